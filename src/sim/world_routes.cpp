// Route samples and the grid behind the world generators' distance queries.

#include <algorithm>
#include <cmath>
#include <limits>

#include "world_detail.hpp"

namespace dcl::sim::detail {

namespace {

constexpr double kCell = 8.0;               // m, segment grid cell
constexpr double kCoarseSampleCell = 20.0;  // m, coarse sample grid cell
constexpr double kCoarseSpacing = 10.0;     // m between coarse samples
constexpr double kMinStep = 0.5;            // m, closer poses are merged
constexpr double kMaxStep = 2.0;            // m, longer gaps are subdivided
constexpr double kFreshRadius = 8.0;        // m, an earlier pass this close owns the street
constexpr double kPaveRadius = 4.0;         // m, an earlier pass this close carries the road
constexpr double kRecentArc = 40.0;         // m, the route's own recent samples do not count
constexpr double kLaneSpan = 4.5;           // m, parallel lanes this near share one street

struct SegmentPoint {
  double distance;
  double t;  // 0 at a, 1 at b
};

SegmentPoint pointToSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                            const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return {(a + t * ab - p).norm(), t};
}

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

bool segmentsIntersect(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                       const Eigen::Vector2d& d) {
  const double d1 = cross(b - a, c - a), d2 = cross(b - a, d - a);
  const double d3 = cross(d - c, a - c), d4 = cross(d - c, b - c);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
}

double segmentDistance(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                       const Eigen::Vector2d& d) {
  if (segmentsIntersect(a, b, c, d)) return 0.0;
  return std::min({pointToSegment(a, c, d).distance, pointToSegment(b, c, d).distance,
                   pointToSegment(c, a, b).distance, pointToSegment(d, a, b).distance});
}

bool insideConvex(std::span<const Eigen::Vector2d> polygon, const Eigen::Vector2d& p) {
  bool positive = false, negative = false;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const double c = cross(polygon[(i + 1) % polygon.size()] - polygon[i], p - polygon[i]);
    positive |= c > 0;
    negative |= c < 0;
  }
  return !(positive && negative);
}

double segmentPolygonDistance(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                              std::span<const Eigen::Vector2d> polygon) {
  if (insideConvex(polygon, a)) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    best = std::min(best, segmentDistance(a, b, polygon[i], polygon[(i + 1) % polygon.size()]));
  }
  return best;
}

/// Road samples of one trajectory: poses closer than kMinStep merged, gaps over kMaxStep split.
std::vector<RouteSample> resample(const core::Trajectory& route, double mount_height,
                                  std::uint32_t index) {
  std::vector<RouteSample> out;
  for (const auto& T : route.poses()) {
    const Eigen::Vector2d xy = T.translation().head<2>();
    const double z = T.translation().z() - mount_height;
    if (out.empty()) {
      out.push_back({xy, z, 0.0, true, true, index, xy});
      continue;
    }
    const RouteSample last = out.back();
    const double d = (xy - last.xy).norm();
    if (d < kMinStep) continue;
    const int pieces = static_cast<int>(std::ceil(d / kMaxStep));
    for (int k = 1; k <= pieces; ++k) {
      const double f = static_cast<double>(k) / pieces;
      const Eigen::Vector2d p = last.xy + f * (xy - last.xy);
      out.push_back({p, last.z_road + f * (z - last.z_road), last.s + f * d, true, true, index, p});
    }
  }
  return out;
}

}  // namespace

double polygonDistance(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b) {
  if (insideConvex(a, b[0]) || insideConvex(b, a[0])) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < a.size(); ++i)
    best = std::min(best, segmentPolygonDistance(a[i], a[(i + 1) % a.size()], b));
  return best;
}

std::uint64_t mix(std::uint64_t h, std::uint64_t value) {
  std::uint64_t z = h ^ (value + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2));
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

std::uint64_t Rng::next() {
  std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

int Rng::integer(int lo, int hi) {
  const auto span = static_cast<std::uint64_t>(hi - lo + 1);
  return lo + static_cast<int>(next() % span);
}

RouteIndex::RouteIndex(std::span<const core::Trajectory> routes, double mount_height) {
  for (const auto& route : routes)
    routes_.push_back(resample(route, mount_height, static_cast<std::uint32_t>(routes_.size())));
  markFresh();
  buildGrids();
  findStreets();
}

void RouteIndex::findStreets() {
  for (auto& samples : routes_) {
    for (std::size_t i = 0; i < samples.size(); ++i) {
      RouteSample& sample = samples[i];
      const std::size_t a = i > 0 ? i - 1 : 0, b = std::min(i + 1, samples.size() - 1);
      if ((samples[b].xy - samples[a].xy).norm() < 1e-9) continue;
      const Eigen::Vector2d along = (samples[b].xy - samples[a].xy).normalized();
      const Eigen::Vector2d left(-along.y(), along.x());
      double lo = 0.0, hi = 0.0;
      const Eigen::Vector2d reach = Eigen::Vector2d::Constant(kLaneSpan);
      forSegmentsNear(sample.xy - reach, sample.xy + reach,
                      [&](const RouteSample& p, const RouteSample& q) {
                        const Eigen::Vector2d d = q.xy - p.xy;
                        if (p.route == sample.route && std::abs(p.s - sample.s) < kRecentArc)
                          return;
                        if (d.norm() < 1e-9 || std::abs(d.normalized().dot(along)) < 0.9) return;
                        const SegmentPoint sp = pointToSegment(sample.xy, p.xy, q.xy);
                        const Eigen::Vector2d offset = p.xy + sp.t * d - sample.xy;
                        if (std::abs(offset.dot(along)) > 1.0) return;
                        const double lateral = offset.dot(left);
                        if (std::abs(lateral) > kLaneSpan) return;
                        lo = std::min(lo, lateral);
                        hi = std::max(hi, lateral);
                      });
      sample.street = sample.xy + (lo + hi) / 2 * left;
    }
  }
}

double RouteIndex::length(std::size_t route) const {
  return routes_[route].empty() ? 0.0 : routes_[route].back().s;
}

RouteIndex::Key RouteIndex::key(int cx, int cy) const {
  return (static_cast<Key>(cx) << 32) ^ static_cast<Key>(static_cast<std::uint32_t>(cy));
}

Eigen::Vector2i RouteIndex::cellOf(const Eigen::Vector2d& p, double cell) const {
  return {static_cast<int>(std::floor(p.x() / cell)), static_cast<int>(std::floor(p.y() / cell))};
}

void RouteIndex::markFresh() {
  std::unordered_map<Key, std::vector<std::pair<std::uint32_t, std::uint32_t>>> claimed;
  for (std::uint32_t r = 0; r < routes_.size(); ++r) {
    for (std::uint32_t j = 0; j < routes_[r].size(); ++j) {
      RouteSample& sample = routes_[r][j];
      const Eigen::Vector2i c = cellOf(sample.xy, kCell);
      double nearest_earlier = kFreshRadius;
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          const auto it = claimed.find(key(c.x() + dx, c.y() + dy));
          if (it == claimed.end()) continue;
          for (const auto& [qr, qj] : it->second) {
            const RouteSample& q = routes_[qr][qj];
            if (qr == r && q.s >= sample.s - kRecentArc) continue;
            nearest_earlier = std::min(nearest_earlier, (q.xy - sample.xy).norm());
          }
        }
      }
      sample.fresh = nearest_earlier >= kFreshRadius;
      sample.paved = nearest_earlier >= kPaveRadius;
      claimed[key(c.x(), c.y())].emplace_back(r, j);
    }
  }
}

void RouteIndex::buildGrids() {
  for (std::uint32_t r = 0; r < routes_.size(); ++r) {
    const auto& samples = routes_[r];
    double next_coarse = 0.0;
    for (std::uint32_t i = 0; i < samples.size(); ++i) {
      const std::uint32_t j = std::min<std::uint32_t>(i + 1, samples.size() - 1);
      if (j == i && i > 0) break;
      const Eigen::Vector2i lo = cellOf(samples[i].xy.cwiseMin(samples[j].xy), kCell);
      const Eigen::Vector2i hi = cellOf(samples[i].xy.cwiseMax(samples[j].xy), kCell);
      for (int x = lo.x(); x <= hi.x(); ++x)
        for (int y = lo.y(); y <= hi.y(); ++y) grid_[key(x, y)].push_back({r, i});
      if (samples[i].s >= next_coarse) {
        const Eigen::Vector2i c = cellOf(samples[i].xy, kCoarseSampleCell);
        coarse_[key(c.x(), c.y())].push_back(static_cast<std::uint32_t>(coarse_samples_.size()));
        coarse_samples_.emplace_back(samples[i].xy.x(), samples[i].xy.y(), samples[i].z_road);
        next_coarse = samples[i].s + kCoarseSpacing;
      }
    }
  }
}

template <class F>
void RouteIndex::forSegmentsNear(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, F&& f,
                                 bool paved_only) const {
  const Eigen::Vector2i clo = cellOf(lo, kCell), chi = cellOf(hi, kCell);
  for (int x = clo.x(); x <= chi.x(); ++x) {
    for (int y = clo.y(); y <= chi.y(); ++y) {
      const auto it = grid_.find(key(x, y));
      if (it == grid_.end()) continue;
      for (const SegmentRef& ref : it->second) {
        const auto& samples = routes_[ref.route];
        const std::size_t j = std::min<std::size_t>(ref.index + 1, samples.size() - 1);
        if (paved_only && !(samples[ref.index].paved && samples[j].paved)) continue;
        f(samples[ref.index], samples[j]);
      }
    }
  }
}

std::optional<RouteNearest> RouteIndex::nearest(const Eigen::Vector2d& p, double radius,
                                                bool paved_only) const {
  std::optional<RouteNearest> best;
  const Eigen::Vector2i c = cellOf(p, kCell);
  const int rings = static_cast<int>(std::ceil(radius / kCell)) + 1;
  for (int ring = 0; ring <= rings; ++ring) {
    for (int x = c.x() - ring; x <= c.x() + ring; ++x) {
      const int step = (x == c.x() - ring || x == c.x() + ring) ? 1 : 2 * ring;
      for (int y = c.y() - ring; y <= c.y() + ring; y += std::max(step, 1)) {
        const Eigen::Vector2d centre((x + 0.5) * kCell, (y + 0.5) * kCell);
        forSegmentsNear(
            centre, centre,
            [&](const RouteSample& a, const RouteSample& b) {
              const SegmentPoint sp = pointToSegment(p, a.xy, b.xy);
              if (best && sp.distance >= best->distance) return;
              const Eigen::Vector2d d = b.xy - a.xy;
              const Eigen::Vector2d along =
                  d.norm() > 1e-9 ? d.normalized() : Eigen::Vector2d::UnitX();
              best = RouteNearest{sp.distance, a.z_road + sp.t * (b.z_road - a.z_road),
                                  a.xy + sp.t * d, along};
            },
            paved_only);
      }
    }
    if (best && best->distance <= ring * kCell) break;
  }
  if (best && best->distance > radius) return std::nullopt;
  return best;
}

bool RouteIndex::clear(std::span<const Eigen::Vector2d> polygon, double clearance) const {
  Eigen::Vector2d lo = polygon[0], hi = polygon[0];
  for (const auto& v : polygon) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  const Eigen::Vector2d margin = Eigen::Vector2d::Constant(clearance);
  bool ok = true;
  forSegmentsNear(lo - margin, hi + margin, [&](const RouteSample& a, const RouteSample& b) {
    if (ok && segmentPolygonDistance(a.xy, b.xy, polygon) < clearance) ok = false;
  });
  return ok;
}

RouteFrame RouteIndex::frameAt(std::size_t route, double s) const {
  const auto& samples = routes_[route];
  RouteFrame frame;
  if (samples.empty()) return frame;
  const auto at = [&](double q) {
    const auto it = std::lower_bound(samples.begin(), samples.end(), q,
                                     [](const RouteSample& a, double v) { return a.s < v; });
    if (it == samples.begin()) return std::pair{samples.front(), samples.front()};
    if (it == samples.end()) return std::pair{samples.back(), samples.back()};
    return std::pair{*(it - 1), *it};
  };
  const auto [a, b] = at(s);
  const double f = b.s > a.s ? std::clamp((s - a.s) / (b.s - a.s), 0.0, 1.0) : 0.0;
  frame.xy = a.street + f * (b.street - a.street);
  frame.z_road = a.z_road + f * (b.z_road - a.z_road);
  frame.fresh = (f < 0.5 ? a : b).fresh;
  const Eigen::Vector2d ahead = at(s + 2.0).second.street, behind = at(s - 2.0).first.street;
  if ((ahead - behind).norm() > 1e-6) frame.along = (ahead - behind).normalized();
  frame.left = Eigen::Vector2d(-frame.along.y(), frame.along.x());
  return frame;
}

double RouteIndex::smoothRoadHeight(const Eigen::Vector2d& p, double radius) const {
  const Eigen::Vector2i lo = cellOf(p.array() - radius, kCoarseSampleCell);
  const Eigen::Vector2i hi = cellOf(p.array() + radius, kCoarseSampleCell);
  double sum = 0.0, weights = 0.0;
  for (int x = lo.x(); x <= hi.x(); ++x) {
    for (int y = lo.y(); y <= hi.y(); ++y) {
      const auto it = coarse_.find(key(x, y));
      if (it == coarse_.end()) continue;
      for (std::uint32_t i : it->second) {
        const double d = (coarse_samples_[i].head<2>() - p).norm();
        if (d >= radius) continue;
        const double w = (1.0 - d / radius) * (1.0 - d / radius) / (d * d + 25.0);
        sum += w * coarse_samples_[i].z();
        weights += w;
      }
    }
  }
  if (weights > 0.0) return sum / weights;
  return coarse_samples_.empty() ? 0.0 : coarse_samples_.front().z();
}

}  // namespace dcl::sim::detail
