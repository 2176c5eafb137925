// libFuzzer target: a KITTI Velodyne .bin scan, decoded from memory. A file
// may be refused only with core::Error (a core::FileError naming the byte).
#include <cstdint>
#include <span>

#include <dcl/core/error.hpp>
#include <dcl/io/kitti_scan.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)dcl::io::decodeKittiScan(std::span(reinterpret_cast<const char*>(data), size),
                                   "input.bin");
  } catch (const dcl::core::Error&) {
  }
  return 0;
}
