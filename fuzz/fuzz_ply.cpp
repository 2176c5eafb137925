// libFuzzer target: a PLY file (header; ascii, binary little- and big-endian
// data; other elements with lists, skipped), decoded from memory. A file may
// be refused only with core::Error (a core::FileError naming the line or byte).
#include <cstdint>
#include <span>

#include <dcl/core/error.hpp>
#include <dcl/io/ply.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)dcl::io::decodePly(std::span(reinterpret_cast<const char*>(data), size), "input.ply");
  } catch (const dcl::core::Error&) {
  }
  return 0;
}
