#include <cmath>

#include <dcl/sim/world.hpp>

namespace dcl::sim {

float reflectivity(Surface surface) {
  // Typical 905 nm diffuse reflectances: asphalt dark, vegetation bright.
  switch (surface) {
    case Surface::ground:
      return 0.30f;
    case Surface::road:
      return 0.12f;
    case Surface::kerb:
      return 0.35f;
    case Surface::building:
      return 0.45f;
    case Surface::vegetation:
      return 0.60f;
    case Surface::trunk:
      return 0.25f;
    case Surface::pole:
      return 0.50f;
    case Surface::vehicle:
      return 0.20f;
    case Surface::wall:
      return 0.40f;
    case Surface::person:
      return 0.30f;  // clothing
  }
  return 0.3f;
}

std::uint32_t World::addVertex(const Eigen::Vector3f& v) {
  vertices.push_back(v);
  return static_cast<std::uint32_t>(vertices.size() - 1);
}

void World::addTriangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, Surface surface) {
  triangles.push_back({a, b, c});
  surfaces.push_back(surface);
}

void World::addQuad(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d,
                    Surface surface) {
  addTriangle(a, b, c, surface);
  addTriangle(a, c, d, surface);
}

void World::addBox(const Eigen::Isometry3d& T_world_box, const Eigen::Vector3d& size,
                   Surface surface) {
  const Eigen::Vector3d h(size.x() / 2, size.y() / 2, size.z());
  std::uint32_t v[8];
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d local((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(),
                                (i & 4) ? h.z() : 0.0);
    v[i] = addVertex((T_world_box * local).cast<float>());
  }
  addQuad(v[0], v[2], v[3], v[1], surface);  // bottom
  addQuad(v[4], v[5], v[7], v[6], surface);  // top
  addQuad(v[0], v[1], v[5], v[4], surface);  // -y
  addQuad(v[2], v[6], v[7], v[3], surface);  // +y
  addQuad(v[0], v[4], v[6], v[2], surface);  // -x
  addQuad(v[1], v[3], v[7], v[5], surface);  // +x
}

void World::addPrism(std::span<const Eigen::Vector2d> footprint, double z_bottom, double z_top,
                     Surface surface) {
  const auto n = static_cast<std::uint32_t>(footprint.size());
  if (n < 3) return;
  const std::uint32_t first = static_cast<std::uint32_t>(vertices.size());
  for (const auto& p : footprint) {
    addVertex(Eigen::Vector3f(float(p.x()), float(p.y()), float(z_bottom)));
    addVertex(Eigen::Vector3f(float(p.x()), float(p.y()), float(z_top)));
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t j = (i + 1) % n;
    addQuad(first + 2 * i, first + 2 * j, first + 2 * j + 1, first + 2 * i + 1, surface);
  }
  // The roof as a fan: footprints are convex or star-shaped from their first vertex.
  for (std::uint32_t i = 1; i + 1 < n; ++i) {
    addTriangle(first + 1, first + 2 * i + 1, first + 2 * (i + 1) + 1, surface);
  }
}

void World::addCylinder(const Eigen::Vector3d& base, double radius, double height, int segments,
                        Surface surface) {
  std::vector<Eigen::Vector2d> ring(static_cast<std::size_t>(segments));
  for (int i = 0; i < segments; ++i) {
    const double a = 2.0 * M_PI * i / segments;
    ring[static_cast<std::size_t>(i)] =
        base.head<2>() + radius * Eigen::Vector2d(std::cos(a), std::sin(a));
  }
  addPrism(ring, base.z(), base.z() + height, surface);
}

void World::addEllipsoid(const Eigen::Vector3d& center, const Eigen::Vector3d& radii, int rings,
                         Surface surface) {
  const int segments = 2 * rings;
  const std::uint32_t first = static_cast<std::uint32_t>(vertices.size());
  for (int r = 0; r <= rings; ++r) {
    const double polar = M_PI * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double azimuth = 2.0 * M_PI * s / segments;
      const Eigen::Vector3d unit(std::sin(polar) * std::cos(azimuth),
                                 std::sin(polar) * std::sin(azimuth), std::cos(polar));
      addVertex((center + radii.cwiseProduct(unit)).cast<float>());
    }
  }
  const auto at = [&](int r, int s) {
    return first + static_cast<std::uint32_t>(r * segments + (s % segments));
  };
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      addQuad(at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s + 1), surface);
    }
  }
}

void World::append(const World& other) {
  const auto offset = static_cast<std::uint32_t>(vertices.size());
  vertices.insert(vertices.end(), other.vertices.begin(), other.vertices.end());
  for (const auto& t : other.triangles)
    triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  surfaces.insert(surfaces.end(), other.surfaces.begin(), other.surfaces.end());
}

Eigen::AlignedBox3f World::bounds() const {
  Eigen::AlignedBox3f box;
  for (const auto& v : vertices) box.extend(v);
  return box;
}

std::array<std::size_t, kSurfaceCount> World::surfaceHistogram() const {
  std::array<std::size_t, kSurfaceCount> counts{};
  for (Surface s : surfaces) ++counts[static_cast<std::size_t>(s)];
  return counts;
}

}  // namespace dcl::sim
