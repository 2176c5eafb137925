#pragma once

/// Private to dcl::sim: an Embree 3 scene of a World and batched ray casts into it.

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <memory>
#include <span>

#include <dcl/sim/world.hpp>

namespace dcl::sim {

/// One beam in the world frame.
struct Ray {
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();      ///< m, world frame
  Eigen::Vector3f direction = Eigen::Vector3f::UnitX();  ///< unit length, world frame
};

/// What one beam met first.
struct RayHit {
  float range = std::numeric_limits<float>::infinity();  ///< m to the hit; infinite when none
  float cos_incidence = 0.0f;         ///< |cos| of the angle between beam and the triangle's normal
  Surface surface = Surface::ground;  ///< the class of the triangle hit (meaningless without a hit)

  /// True when the beam met a triangle within its range.
  [[nodiscard]] bool hit() const { return std::isfinite(range); }
};

/// An Embree scene of one World: one triangle geometry, built once, then
/// intersected from any number of threads at once.
class RayCaster {
 public:
  /// Builds the scene from a copy of the world's mesh (the world need not
  /// outlive the caster). Throws core::Error on an inconsistent world or on
  /// any Embree device error, with Embree's own message.
  explicit RayCaster(const World& world);
  ~RayCaster();
  RayCaster(RayCaster&&) noexcept;
  RayCaster& operator=(RayCaster&&) noexcept;

  /// Casts every ray from range 0 to `max_range`; `hits` must be as long as
  /// `rays`. Rays are traced in packets of 16, so keep neighbours coherent
  /// (same origin, nearby directions) for speed.
  void cast(std::span<const Ray> rays, float max_range, std::span<RayHit> hits) const;

  /// One ray, traced alone.
  [[nodiscard]] RayHit cast(const Ray& ray, float max_range) const;

  /// Triangles in the scene.
  [[nodiscard]] std::size_t triangleCount() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::sim
