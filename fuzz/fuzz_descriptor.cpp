// libFuzzer target: the LiDAR-Iris wire codec (a descriptor message's payload).
// A decoder may refuse input only with place::DecodeError; anything else escapes
// and libFuzzer reports it.
#include <cstdint>
#include <span>

#include <dcl/place/descriptor_codec.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)dcl::place::decodeIris(std::span(data, size));
  } catch (const dcl::place::DecodeError&) {
  }
  return 0;
}
