// libFuzzer target: the compact verification cloud (a loop candidate's payload,
// and a map summary's). A decoder may refuse input only with CloudDecodeError.
#include <cstdint>
#include <span>

#include <dcl/registration/cloud_codec.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)dcl::registration::decodeVerificationCloud(std::span(data, size));
  } catch (const dcl::registration::CloudDecodeError&) {
  }
  return 0;
}
