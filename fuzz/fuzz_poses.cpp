// libFuzzer target: the trajectory file readers (TUM, KITTI poses, KITTI
// times, KITTI calib.txt), each given the same bytes. A file may be refused
// only with core::Error (a core::FileError naming the line).
#include <cstdint>

#include <dcl/core/error.hpp>
#include <dcl/io/pose_file.hpp>

#include "fuzz_input_file.hpp"

namespace {

template <class F>
void refusedOnlyWithOurErrors(F&& read) {
  try {
    read();
  } catch (const dcl::core::Error&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const dcl::fuzz::InputFile file("poses");
  const std::string& path = file.write(data, size);
  refusedOnlyWithOurErrors([&] { (void)dcl::io::readTumPoses(path); });
  refusedOnlyWithOurErrors([&] { (void)dcl::io::readKittiPoses(path); });
  refusedOnlyWithOurErrors([&] { (void)dcl::io::readKittiTimes(path); });
  refusedOnlyWithOurErrors([&] { (void)dcl::io::readKittiCalib(path); });
  return 0;
}
