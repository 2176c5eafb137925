#pragma once

#include <compare>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>

namespace dcl::core {

/// An integer id that does not mix with other ids: a `RobotId` is not a
/// `KeyframeId`, and neither converts silently from a plain integer.
template <class Tag, class Int>
class StrongId {
 public:
  using value_type = Int;

  constexpr StrongId() = default;
  constexpr explicit StrongId(Int value) : value_(value) {}

  [[nodiscard]] constexpr Int value() const { return value_; }
  [[nodiscard]] constexpr bool valid() const { return value_ != kInvalid; }

  constexpr auto operator<=>(const StrongId&) const = default;

  static constexpr Int kInvalid = std::numeric_limits<Int>::max();

 private:
  Int value_ = kInvalid;
};

struct RobotIdTag {};
struct KeyframeIdTag {};

/// A robot of the swarm: 0, 1, 2, ... (printed as 'a', 'b', 'c', ... like GTSAM symbols).
using RobotId = StrongId<RobotIdTag, std::uint8_t>;
/// A keyframe's index within its robot's trajectory, counted from 0.
using KeyframeId = StrongId<KeyframeIdTag, std::uint64_t>;

/// The swarm-wide name of one pose: which robot, which keyframe.
///
/// Packs as a GTSAM-style symbol: the character 'a' + robot in the top 8 bits,
/// the keyframe index in the low 56 bits. Multi-robot g2o files in the
/// field (distributed-mapper, Kimera-Multi) use this encoding for vertex ids.
struct PoseKey {
  RobotId robot;
  KeyframeId keyframe;

  static constexpr int kIndexBits = 56;
  static constexpr std::uint64_t kIndexMask = (std::uint64_t{1} << kIndexBits) - 1;
  static constexpr std::uint8_t kFirstRobotChar = 'a';

  /// Packs into the 64-bit symbol encoding.
  [[nodiscard]] constexpr std::uint64_t pack() const {
    const auto c = static_cast<std::uint64_t>(kFirstRobotChar + robot.value());
    return (c << kIndexBits) | (keyframe.value() & kIndexMask);
  }

  /// Unpacks the 64-bit symbol encoding; the robot is the top byte minus 'a'.
  [[nodiscard]] static constexpr PoseKey unpack(std::uint64_t symbol) {
    const auto c = static_cast<std::uint8_t>(symbol >> kIndexBits);
    return {RobotId(static_cast<std::uint8_t>(c - kFirstRobotChar)),
            KeyframeId(symbol & kIndexMask)};
  }

  /// True when the top byte of `symbol` is a robot character: 'a' and above
  /// (robots 0-25 are 'a'..'z', a 27th robot and on the bytes past 'z', so up to
  /// 159 robots pack), or 'A'..'Z' as other tools write them.
  [[nodiscard]] static constexpr bool isSymbol(std::uint64_t symbol) {
    const auto c = static_cast<std::uint8_t>(symbol >> kIndexBits);
    return c >= 'a' || (c >= 'A' && c <= 'Z');
  }

  constexpr auto operator<=>(const PoseKey&) const = default;
};

/// "a" for robot 0, "b" for robot 1, ...; numbers past 'z'.
std::string robotName(RobotId robot);

/// A pose as messages and errors name it: "b12" for robot 1's keyframe 12.
std::string keyName(const PoseKey& key);

}  // namespace dcl::core

template <class Tag, class Int>
struct std::hash<dcl::core::StrongId<Tag, Int>> {
  std::size_t operator()(const dcl::core::StrongId<Tag, Int>& id) const noexcept {
    return std::hash<Int>{}(id.value());
  }
};

template <>
struct std::hash<dcl::core::PoseKey> {
  std::size_t operator()(const dcl::core::PoseKey& key) const noexcept {
    return std::hash<std::uint64_t>{}(key.pack());
  }
};
