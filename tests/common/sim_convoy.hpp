#pragma once
// A small simulated dataset in which two robots meet all the time: robot b
// drives robot a's street of the small-3 campus 4 s (about 5 m) behind it, so
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

/// `sliceRoute`, then the same frames backwards: the robot reverses down the
/// street to where it began, past every place it saw.
inline sim::Route thereAndBack(const sim::Route& route, std::size_t first, std::size_t count,
                               const std::string& name) {
  sim::Route out = sliceRoute(route, first, count, name);
  const double step = out.T_world_sensor.stamp(1) - out.T_world_sensor.stamp(0);
  for (std::size_t i = count - 1; i-- > 0;) {
    out.T_world_sensor.push_back(out.T_world_sensor.stamps().back() + step,
                                 route.T_world_sensor.pose(first + i));
  }
  return out;
}

/// The dataset, written to a temporary folder for the life of the object.
/// `back`: both robots reverse down the street after `frames` frames, back to
/// where they began. `third`: a robot c drives between them, 2 s behind a.
struct Convoy {
  std::filesystem::path folder;
  io::DatasetSpec spec;

  explicit Convoy(const std::string& tag, std::size_t frames = 160, bool back = false,
                  bool third = false) {
    folder = std::filesystem::temp_directory_path() /
             ("dcl_convoy_" + tag + "_" + std::to_string(::getpid()));
    sim::Preset preset = sim::makePreset("small-3");
    const sim::Route street = preset.routes.at(0);
    const auto route = back ? thereAndBack : sliceRoute;
    preset.routes = {route(street, 40, frames, "a"), route(street, 0, frames, "b")};
    if (third) preset.routes.push_back(route(street, 20, frames, "c"));
    spec = sim::writeSimDataset(folder.string(), preset);
  }
  ~Convoy() { std::filesystem::remove_all(folder); }
  Convoy(const Convoy&) = delete;
  Convoy& operator=(const Convoy&) = delete;
};

}  // namespace dcl::test
