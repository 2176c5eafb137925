#pragma once

/// The simulated world: one triangle mesh with a surface class per triangle.
/// Generators (world_gen.hpp) fill it from primitives; the ray caster
/// (raycaster.hpp) intersects LiDAR beams with it. World frame: x east-ish,
/// y north-ish, z up, metres.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace dcl::sim {

/// What a triangle is made of: decides its reflectivity and its colour in previews.
enum class Surface : std::uint8_t {
  ground,      ///< terrain off the road (grass, dirt)
  road,        ///< asphalt
  kerb,        ///< kerb stones and pavement edges
  building,    ///< facades and roofs
  vegetation,  ///< tree crowns, hedges
  trunk,       ///< tree trunks
  pole,        ///< lamp posts, sign poles
  vehicle,     ///< parked cars
  wall,        ///< walls of corridors and courtyards
  person,      ///< pedestrians and cyclists (moving actors, sim/traffic.hpp)
};

/// Number of Surface values.
inline constexpr std::size_t kSurfaceCount = 10;

/// Diffuse reflectivity in [0, 1] of a surface class (what the LiDAR's intensity sees).
float reflectivity(Surface surface);

/// A triangle mesh with a Surface per triangle. Vertices are shared within a
/// primitive, not across primitives.
struct World {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< counter-clockwise seen from outside
  std::vector<Surface> surfaces;                        ///< one per triangle

  [[nodiscard]] std::size_t triangleCount() const { return triangles.size(); }

  /// Appends a vertex and returns its index.
  std::uint32_t addVertex(const Eigen::Vector3f& v);

  /// Appends a triangle of existing vertices.
  void addTriangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, Surface surface);

  /// Two triangles for the quad a-b-c-d (in order around its edge).
  void addQuad(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d, Surface surface);

  /// A box of `size` (x, y, z extents) placed by `T_world_box`, whose origin is
  /// the centre of the box's bottom face.
  void addBox(const Eigen::Isometry3d& T_world_box, const Eigen::Vector3d& size, Surface surface);

  /// A vertical prism: the counter-clockwise footprint polygon (x, y) extruded
  /// from z_bottom to z_top, with a flat top and no bottom face.
  void addPrism(std::span<const Eigen::Vector2d> footprint, double z_bottom, double z_top,
                Surface surface);

  /// A vertical cylinder standing on `base` with `segments` sides and a flat top.
  void addCylinder(const Eigen::Vector3d& base, double radius, double height, int segments,
                   Surface surface);

  /// An axis-aligned ellipsoid around `center` (a tree crown), as a UV sphere
  /// with `rings` latitude bands and 2 * rings longitude segments.
  void addEllipsoid(const Eigen::Vector3d& center, const Eigen::Vector3d& radii, int rings,
                    Surface surface);

  /// Appends another world's triangles.
  void append(const World& other);

  /// The axis-aligned bounding box of all vertices (empty box for an empty world).
  [[nodiscard]] Eigen::AlignedBox3f bounds() const;

  /// The number of triangles of each surface class, indexed by the enum value.
  [[nodiscard]] std::array<std::size_t, kSurfaceCount> surfaceHistogram() const;
};

}  // namespace dcl::sim
