// libFuzzer target: a pose graph file (g2o or TORO) read as `pcm` and `pgo`
// read one: the reader, the chaining of missing vertices, the checks of the
// whole graph and the conversion to a pose graph. A file may be refused only
// with core::Error (a core::FileError naming the line).
#include <cstdint>

#include <dcl/core/error.hpp>
#include <dcl/io/multi_robot_graph.hpp>

#include "fuzz_input_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const dcl::fuzz::InputFile file("g2o");
  const std::string& path = file.write(data, size);
  try {
    (void)dcl::io::readMultiRobotGraph(path, /*skip_unknown_lines=*/true);
  } catch (const dcl::core::Error&) {
  }
  return 0;
}
