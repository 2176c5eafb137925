// Geometric richness of VLP-16 scans in the campus world, along the routes of
// the `small-3` and `campus-3` presets: enough structure off the ground, spread
// around the sensor and facing several directions, that scan-to-map ICP is
// constrained in every horizontal direction and place recognition has
// something to describe.
//
// What real scans would show (expected from the geometry, not measured here:
// the shared data holds no real VLP-16 campus scans): a VLP-16 1 m up on a
// robot has half its 16 beams pointing upwards, at 0-15 degrees. On a
// university campus (the paper's SYSU sequences) buildings, trees, hedges,
// parked cars and poles line most streets, so those beams return from
// something on most azimuths: well over a third of the returns are not
// ground, there is structure all round within 40 m, and walls face both
// directions of the street grid (street facades and the side walls, facades
// down the cross streets). On a lawn with a few trees the upper beams return
// almost nothing, and walls along one street only leave KISS-ICP-like
// odometry free to slide along the road.
//
// Measured here, lowest over the checked scans (seed 1; seeds 2-8 alike):
//            non-ground share  sectors  wall ratio
//   before   small-3 0.306     6        0.000 (median 0.025)   two buildings in its world
//            campus-3 0.356    6        0.047
//   after    small-3 0.470     8        0.137
//            campus-3 0.471    8        0.105   (seeds 1-8 of both: >= 0.454, >= 7, >= 0.070)
// The thresholds sit below the lows after by a margin for other seeds and
// layouts (0.38, 6, 0.05), and the share and wall ratio above the sparse
// world's lows. Street trees alone already filled six sectors, so the sector
// count guards against structure on one side only, not against sparseness.

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/sim/presets.hpp>
#include <dcl/sim/scan_simulator.hpp>
#include <dcl/sim/world_gen.hpp>

namespace dcl::sim {
namespace {

constexpr std::size_t kScanStride = 40;  ///< check every 40th scan of each robot
constexpr double kAboveGround = 0.3;     ///< m above the ground surface: a non-ground return
constexpr double kSectorRange = 40.0;    ///< m, horizontal range of the sector count
constexpr std::size_t kSectors = 8;
constexpr std::size_t kSectorMinReturns = 20;  ///< a sector with fewer counts as empty
constexpr double kMinNonGroundShare = 0.38;    ///< see the thresholds above
constexpr std::size_t kMinSectors = 6;
constexpr double kMinWallRatio = 0.05;

/// The world's own surfaces around a point, from its triangles in a 2 m bucket
/// grid: the height of the ground (ground, road and kerb, the highest under a
/// point) and the facade (an upright building or wall triangle) a point lies on.
class SurfaceLookup {
 public:
  explicit SurfaceLookup(const World& world) : world_(world) {
    for (std::size_t t = 0; t < world.triangleCount(); ++t) {
      const Surface s = world.surfaces[t];
      if (s == Surface::ground || s == Surface::road || s == Surface::kerb) add(ground_, t);
      if ((s == Surface::building || s == Surface::wall) && std::abs(normal(t).z()) < 0.1)
        add(facades_, t);
    }
  }

  /// Height of the highest ground-class surface under `xy`, -inf when there is none.
  [[nodiscard]] double groundHeight(const Eigen::Vector2d& xy) const {
    double best = -INFINITY;
    for (const std::uint32_t t : bucket(ground_, xy))
      if (insideXy(t, xy)) best = std::max(best, planeHeight(t, xy));
    return best;
  }

  /// The horizontal unit normal of the facade within kOnFacade of `p`, if any.
  [[nodiscard]] std::optional<Eigen::Vector2d> facadeNormal(const Eigen::Vector3d& p) const {
    for (const std::uint32_t t : bucket(facades_, p.head<2>())) {
      const Eigen::Vector3d n = normal(t);
      const Eigen::Vector3d v0 = vertex(t, 0);
      const double off = n.dot(p - v0);
      if (std::abs(off) < kOnFacade && insideUpright(t, p - off * n))
        return n.head<2>().normalized();
    }
    return std::nullopt;
  }

 private:
  using Buckets = std::unordered_map<std::int64_t, std::vector<std::uint32_t>>;
  static constexpr double kOnFacade = 0.15;  ///< m, six sigma of the VLP-16's range noise

  static int cell(double v) { return static_cast<int>(std::floor(v / 2.0)); }
  static std::int64_t key(int x, int y) {
    return (static_cast<std::int64_t>(x) << 32) ^ static_cast<std::uint32_t>(y);
  }
  void add(Buckets& buckets, std::size_t t) const {
    Eigen::AlignedBox2d box;
    for (int k = 0; k < 3; ++k) box.extend(vertex(t, k).head<2>());
    box.min().array() -= kOnFacade;
    box.max().array() += kOnFacade;
    for (int x = cell(box.min().x()); x <= cell(box.max().x()); ++x)
      for (int y = cell(box.min().y()); y <= cell(box.max().y()); ++y)
        buckets[key(x, y)].push_back(static_cast<std::uint32_t>(t));
  }
  [[nodiscard]] const std::vector<std::uint32_t>& bucket(const Buckets& buckets,
                                                         const Eigen::Vector2d& xy) const {
    static const std::vector<std::uint32_t> kNone;
    const auto it = buckets.find(key(cell(xy.x()), cell(xy.y())));
    return it == buckets.end() ? kNone : it->second;
  }
  [[nodiscard]] Eigen::Vector3d vertex(std::size_t t, int k) const {
    return world_.vertices[world_.triangles[t][k]].cast<double>();
  }
  [[nodiscard]] Eigen::Vector3d normal(std::size_t t) const {
    return (vertex(t, 1) - vertex(t, 0)).cross(vertex(t, 2) - vertex(t, 0)).normalized();
  }
  /// True when xy lies inside the triangle's projection on the ground.
  [[nodiscard]] bool insideXy(std::size_t t, const Eigen::Vector2d& xy) const {
    std::array<double, 3> side{};
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2d a = vertex(t, k).head<2>(), e = vertex(t, (k + 1) % 3).head<2>() - a;
      side[k] = e.x() * (xy.y() - a.y()) - e.y() * (xy.x() - a.x());
    }
    return (side[0] >= 0 && side[1] >= 0 && side[2] >= 0) ||
           (side[0] <= 0 && side[1] <= 0 && side[2] <= 0);
  }
  /// True when q, a point in the triangle's plane, lies inside it (barycentric, some slack).
  [[nodiscard]] bool insideUpright(std::size_t t, const Eigen::Vector3d& q) const {
    const Eigen::Vector3d a = vertex(t, 0), e1 = vertex(t, 1) - a, e2 = vertex(t, 2) - a;
    Eigen::Matrix2d gram;
    gram << e1.dot(e1), e1.dot(e2), e1.dot(e2), e2.dot(e2);
    const Eigen::Vector2d uv = gram.inverse() * Eigen::Vector2d(e1.dot(q - a), e2.dot(q - a));
    constexpr double kSlack = -0.02;
    return uv.x() >= kSlack && uv.y() >= kSlack && uv.sum() <= 1.0 - kSlack;
  }
  [[nodiscard]] double planeHeight(std::size_t t, const Eigen::Vector2d& xy) const {
    const Eigen::Vector3d n = normal(t), v0 = vertex(t, 0);
    if (std::abs(n.z()) < 1e-6) return -INFINITY;  // upright: a ray down grazes it
    return v0.z() - (n.x() * (xy.x() - v0.x()) + n.y() * (xy.y() - v0.y())) / n.z();
  }

  const World& world_;
  Buckets ground_;
  Buckets facades_;
};

/// The richness of one scan.
struct Richness {
  double non_ground_share = 0.0;  ///< returns more than kAboveGround above the ground
  std::size_t sectors = 0;        ///< 45-degree sectors with non-ground returns within 40 m
  double wall_ratio = 0.0;        ///< smallest / largest eigenvalue of sum n n^T (horizontal)
};

/// A scan's returns in the world frame, each taken there from the pose at its
/// own firing time (the sweep is motion-distorted).
std::vector<Eigen::Vector3d> inWorld(const core::PointCloud& scan, const core::Trajectory& route,
                                     double stamp) {
  std::vector<Eigen::Vector3d> out(scan.size(), Eigen::Vector3d::Constant(NAN));
  for (std::size_t i = 0; i < scan.size(); ++i)
    if (const auto T_world_sensor = route.at(stamp + scan.time[i]))
      out[i] = *T_world_sensor * scan.points[i].cast<double>();
  return out;
}

std::size_t occupiedSectors(const core::PointCloud& scan, const std::vector<bool>& above) {
  std::array<std::size_t, kSectors> counts{};
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const Eigen::Vector3f& p = scan.points[i];
    if (!above[i] || p.head<2>().norm() > kSectorRange) continue;
    const double turn = std::atan2(p.y(), p.x()) / (2 * M_PI) + 0.5;  // [0, 1]
    ++counts[std::min(kSectors - 1, static_cast<std::size_t>(turn * kSectors))];
  }
  return static_cast<std::size_t>(std::count_if(
      counts.begin(), counts.end(), [](std::size_t c) { return c >= kSectorMinReturns; }));
}

/// Smallest over largest eigenvalue of a 2x2 information matrix (0 when empty).
double eigenRatio(const Eigen::Matrix2d& info) {
  const Eigen::Vector2d eig = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(info).eigenvalues();
  return eig(1) > 0 ? eig(0) / eig(1) : 0.0;
}

Richness measureRichness(const core::PointCloud& scan, const core::Trajectory& route, double stamp,
                         const SurfaceLookup& world) {
  const std::vector<Eigen::Vector3d> points = inWorld(scan, route, stamp);
  std::vector<bool> above(scan.size(), false);
  Eigen::Matrix2d info = Eigen::Matrix2d::Zero();  // sum n n^T over facade returns
  for (std::size_t i = 0; i < points.size(); ++i) {
    above[i] = points[i].z() > world.groundHeight(points[i].head<2>()) + kAboveGround;
    if (!above[i]) continue;
    if (const auto n = world.facadeNormal(points[i])) info += *n * n->transpose();
  }
  Richness r;
  const auto lifted = std::count(above.begin(), above.end(), true);
  r.non_ground_share = scan.empty() ? 0.0 : double(lifted) / double(scan.size());
  r.sectors = occupiedSectors(scan, above);
  r.wall_ratio = eigenRatio(info);
  return r;
}

/// Richness of every kScanStride-th scan of every robot of a campus preset.
std::vector<Richness> presetRichness(const std::string& name, std::uint64_t seed = 1) {
  PresetOptions options;
  options.seed = seed;
  const Preset preset = makePreset(name, options);
  std::vector<core::Trajectory> routes;
  for (const Route& r : preset.routes) routes.push_back(r.T_world_sensor);
  const World world = generateCampusWorld({routes, preset.mount_height, preset.seed});
  const SurfaceLookup lookup(world);
  const ScanSimulator simulator(world, LidarModel::vlp16());
  std::vector<Richness> out;
  for (std::size_t r = 0; r < routes.size(); ++r) {
    for (std::size_t i = kScanStride / 2; i + 2 < routes[r].size(); i += kScanStride) {
      const double stamp = routes[r].stamp(i);
      const core::PointCloud scan = simulator.scan(routes[r], stamp, 1000 * r + i);
      out.push_back(measureRichness(scan, routes[r], stamp, lookup));
    }
  }
  return out;
}

class CampusRichness : public ::testing::TestWithParam<std::string> {};

TEST_P(CampusRichness, Vlp16ScansSeeStructureAllRoundFacingSeveralWays) {
  const std::vector<Richness> scans = presetRichness(GetParam());
  ASSERT_GE(scans.size(), 30u);
  Richness low{1.0, kSectors, 1.0};
  for (std::size_t k = 0; k < scans.size(); ++k) {
    const Richness& s = scans[k];
    SCOPED_TRACE(::testing::Message() << "checked scan " << k);
    EXPECT_GE(s.non_ground_share, kMinNonGroundShare);
    EXPECT_GE(s.sectors, kMinSectors);
    EXPECT_GE(s.wall_ratio, kMinWallRatio);
    low = {std::min(low.non_ground_share, s.non_ground_share), std::min(low.sectors, s.sectors),
           std::min(low.wall_ratio, s.wall_ratio)};
  }
  std::printf("%s: %zu scans, lowest non-ground share %.3f, sectors %zu, wall ratio %.3f\n",
              GetParam().c_str(), scans.size(), low.non_ground_share, low.sectors, low.wall_ratio);
}

INSTANTIATE_TEST_SUITE_P(Presets, CampusRichness, ::testing::Values("small-3", "campus-3"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return info.param == "small-3" ? std::string("small_3") : "campus_3";
                         });

}  // namespace
}  // namespace dcl::sim
