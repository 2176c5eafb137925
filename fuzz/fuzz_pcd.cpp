// libFuzzer target: a PCD file (header, ascii, binary and LZF-compressed
// data), decoded from memory. A file may be refused only with core::Error (a
// core::FileError naming the line or byte).
#include <cstdint>
#include <span>

#include <dcl/core/error.hpp>
#include <dcl/io/pcd.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)dcl::io::decodePcd(std::span(reinterpret_cast<const char*>(data), size), "input.pcd");
  } catch (const dcl::core::Error&) {
  }
  return 0;
}
