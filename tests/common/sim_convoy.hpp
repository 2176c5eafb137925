#pragma once
// A small simulated dataset in which two robots meet all the time: robot b
// drives robot a's street of the demo campus 4 s (about 5 m) behind it, so
// every place one sees the other sees too. 160 frames each (16 s, VLP-16).
#include <filesystem>
#include <string>

#include <unistd.h>

#include <dcl/io/dataset.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/sim_source.hpp>

namespace dcl::test {

/// Frames [first, first + count) of `route`, stamps from 0, named `name`.
inline sim::Route sliceRoute(const sim::Route& route, std::size_t first, std::size_t count,
                             const std::string& name) {
  sim::Route out;
  out.name = name;
  const double t0 = route.T_world_sensor.stamp(first);
  for (std::size_t i = first; i < first + count; ++i)
    out.T_world_sensor.push_back(route.T_world_sensor.stamp(i) - t0, route.T_world_sensor.pose(i));
  return out;
}

/// The dataset, written to a temporary folder for the life of the object.
struct Convoy {
  std::filesystem::path folder;
  io::DatasetSpec spec;

  explicit Convoy(const std::string& tag) {
    folder = std::filesystem::temp_directory_path() /
             ("dcl_convoy_" + tag + "_" + std::to_string(::getpid()));
    sim::Preset preset = sim::makePreset("demo");
    const sim::Route street = preset.routes.at(0);
    preset.routes = {sliceRoute(street, 40, 160, "a"), sliceRoute(street, 0, 160, "b")};
    spec = sim::writeSimDataset(folder.string(), preset);
  }
  ~Convoy() { std::filesystem::remove_all(folder); }
  Convoy(const Convoy&) = delete;
  Convoy& operator=(const Convoy&) = delete;
};

}  // namespace dcl::test
