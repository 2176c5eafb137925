#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

#include <dcl/core/error.hpp>
#include <dcl/eval/scan_statistics.hpp>
#include <dcl/registration/point_tree.hpp>

namespace dcl::eval {
namespace {

/// Nearest neighbours of a local surface fit (the point itself included).
constexpr std::size_t kPatch = 12;
/// Fewest neighbours a fit is made of.
constexpr std::size_t kMinPatch = 8;
/// Patches farther than this from their point are not local.
constexpr double kPatchReach = 1.0;
/// RMS distance to its plane above which a patch fits no surface, m.
constexpr double kScatterRms = 0.05;

/// The local surface at one return.
struct Patch {
  bool valid = false;
  double incidence_deg = 0.0;  ///< between the beam and the surface normal
  double residual = 0.0;       ///< the return's distance to the plane, m
  double rms = 0.0;            ///< RMS distance of the patch to its plane, m
  bool spread = false;         ///< the patch spans two directions (its plane is defined)
};

/// 1.4826 times the median of |v|: a Gaussian's sigma, robust to outliers. NaN when empty.
double robustSigma(std::vector<double>& v) {
  if (v.empty()) return std::nan("");
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return 1.4826 * *mid;
}

/// The element of rank floor(q * size) of `v` (the upper middle for q = 0.5).
/// NaN when empty.
double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  const auto rank =
      std::min(static_cast<std::size_t>(static_cast<double>(v.size()) * q), v.size() - 1);
  const auto at = v.begin() + static_cast<std::ptrdiff_t>(rank);
  std::nth_element(v.begin(), at, v.end());
  return *at;
}

double median(std::vector<double> v) {
  return quantile(std::move(v), 0.5);
}

template <std::size_t N>
std::size_t binOf(const std::array<double, N>& edges, double v) {
  const auto it = std::upper_bound(edges.begin(), edges.end(), v);
  if (it == edges.begin()) return N;  // below the first edge
  const auto bin = static_cast<std::size_t>(it - edges.begin()) - 1;
  if (bin >= N - 1) return v <= edges.back() ? N - 2 : N;  // the last edge is inclusive
  return bin;
}

/// The returns of each ring in azimuth order: from `ring` when the scan has
/// it, otherwise runs of the points' own order broken where the azimuth wraps.
std::vector<std::vector<std::uint32_t>> ringSequences(const core::PointCloud& scan,
                                                      std::span<const double> azimuth) {
  std::vector<std::vector<std::uint32_t>> rings;
  if (scan.hasRing()) {
    for (std::size_t i = 0; i < scan.size(); ++i) {
      if (scan.ring[i] >= rings.size()) rings.resize(scan.ring[i] + 1u);
      rings[scan.ring[i]].push_back(static_cast<std::uint32_t>(i));
    }
    for (auto& ring : rings)
      std::sort(ring.begin(), ring.end(),
                [&](std::uint32_t a, std::uint32_t b) { return azimuth[a] < azimuth[b]; });
    return rings;
  }
  rings.emplace_back();
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (i > 0 && azimuth[i] - azimuth[i - 1] < -M_PI) rings.emplace_back();
    rings.back().push_back(static_cast<std::uint32_t>(i));
  }
  return rings;
}

std::vector<Patch> localPatches(const core::PointCloud& scan, std::span<const double> range) {
  std::vector<Eigen::Vector3d> points(scan.size());
  for (std::size_t i = 0; i < scan.size(); ++i) points[i] = scan.points[i].cast<double>();
  const registration::PointTree tree(points);
  std::vector<Patch> patches(scan.size());
  std::vector<registration::Neighbor> found;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (range[i] < kNoiseRangeEdges.front() || range[i] > kNoiseRangeEdges.back()) continue;
    const Eigen::Vector3d& p = tree.points()[i];
    tree.nearest(p, kPatch, kPatchReach, found);
    if (found.size() < kMinPatch) continue;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& n : found) centroid += tree.points()[n.index];
    centroid /= static_cast<double>(found.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& n : found) {
      const Eigen::Vector3d d = tree.points()[n.index] - centroid;
      cov += d * d.transpose();
    }
    cov /= static_cast<double>(found.size());
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(cov);
    const Eigen::Vector3d lambda = eig.eigenvalues().cwiseMax(0.0);  // ascending
    const Eigen::Vector3d normal = eig.eigenvectors().col(0);
    Patch& patch = patches[i];
    patch.valid = true;
    patch.incidence_deg =
        std::acos(std::min(1.0, std::abs(normal.dot(p) / range[i]))) * 180.0 / M_PI;
    // A return's distance to a plane fitted to it and its neighbours is
    // shorter than to the true surface by sqrt((k - 3) / k).
    const double k = static_cast<double>(found.size());
    patch.residual = std::abs(normal.dot(p - centroid)) * std::sqrt(k / (k - 3.0));
    patch.rms = std::sqrt(lambda[0]);
    patch.spread = lambda[1] > 0.05 * lambda[2];
  }
  return patches;
}

}  // namespace

ScanStatistics measureScanStatistics(const core::PointCloud& scan) {
  for (std::size_t i = 0; i < scan.size(); ++i)
    if (!scan.points[i].allFinite())
      throw core::Error("scan statistics: point " + std::to_string(i) +
                        " is not finite (read organised clouds with their no-returns dropped)");
  if (scan.size() < 1000)
    throw core::Error("scan statistics need a sweep of at least 1000 returns, not " +
                      std::to_string(scan.size()));
  const std::size_t n = scan.size();
  std::vector<double> range(n), azimuth(n);
  for (std::size_t i = 0; i < n; ++i) {
    range[i] = scan.points[i].cast<double>().norm();
    azimuth[i] = std::atan2(scan.points[i].y(), scan.points[i].x());
  }
  ScanStatistics s;
  s.returns = n;
  const auto rings = ringSequences(scan, azimuth);
  const auto patches = localPatches(scan, range);

  // Plane noise by range, and scattered returns.
  std::array<std::vector<double>, kNoiseRangeEdges.size() - 1> residuals;
  std::size_t near = 0;
  std::vector<double> scattered;
  for (std::size_t i = 0; i < n; ++i) {
    const Patch& patch = patches[i];
    if (!patch.valid) continue;
    if (range[i] <= 30.0) {
      ++near;
      if (patch.rms > kScatterRms) scattered.push_back(patch.rms);
    }
    if (patch.spread && patch.rms <= kScatterRms && patch.incidence_deg < 45.0) {
      const std::size_t band = binOf(kNoiseRangeEdges, range[i]);
      if (band < residuals.size())
        residuals[band].push_back(patch.residual / std::cos(patch.incidence_deg * M_PI / 180.0));
    }
  }
  for (std::size_t b = 0; b < residuals.size(); ++b) s.plane_noise[b] = robustSigma(residuals[b]);
  s.scattered_share =
      near > 0 ? static_cast<double>(scattered.size()) / static_cast<double>(near) : 0.0;
  s.scattered_depth = quantile(std::move(scattered), 0.9);

  // The firing pattern along the rings.
  std::vector<double> steps;
  for (const auto& ring : rings)
    for (std::size_t j = 1; j < ring.size(); ++j) {
      const double step = azimuth[ring[j]] - azimuth[ring[j - 1]];
      if (step > 0.0 && step < M_PI / 180.0) steps.push_back(step);
    }
  if (steps.empty()) throw core::Error("scan statistics: no ring of the scan has two returns");
  const double nominal = median(steps);
  s.nominal_step_deg = nominal * 180.0 / M_PI;
  std::vector<double> jitter;
  std::size_t halves = 0;
  for (const double step : steps) {
    const double ratio = step / nominal;
    halves += ratio < 0.7;
    if (ratio > 0.8 && ratio < 1.2) jitter.push_back(ratio - 1.0);
  }
  s.half_step_share = static_cast<double>(halves) / static_cast<double>(steps.size());
  for (double& j : jitter) j = std::abs(j);
  s.step_jitter = robustSigma(jitter);

  // Return rate: between two returns of one surface (ranges within 10 %), a
  // step of m nominal steps holds m - 1 firings that returned nothing.
  std::array<double, kIncidenceEdges.size() - 1> fired_i{}, returned_i{};
  std::array<double, kIntensityEdges.size() - 1> fired_v{}, returned_v{};
  // Mixed pixels: a0 a b c c0 along a ring, flat on both sides of a step edge.
  std::size_t edges = 0, mixed = 0;
  for (const auto& ring : rings) {
    for (std::size_t j = 1; j < ring.size(); ++j) {
      const std::uint32_t a = ring[j - 1], c = ring[j];
      const double ratio = (azimuth[c] - azimuth[a]) / nominal;
      if (ratio < 0.8 || ratio > 4.5 || range[a] > 40.0) continue;
      if (std::abs(range[c] - range[a]) > 0.1 * range[a]) continue;
      const double firings = std::max(1.0, std::round(ratio));
      const Patch& patch = patches[a];
      if (patch.valid) {
        const std::size_t bin = binOf(kIncidenceEdges, patch.incidence_deg);
        if (bin < fired_i.size()) {
          fired_i[bin] += firings;
          returned_i[bin] += 1.0;
        }
      }
      if (scan.hasIntensity()) {
        const std::size_t bin = binOf(kIntensityEdges, scan.intensity[a]);
        if (bin < fired_v.size()) {
          fired_v[bin] += firings;
          returned_v[bin] += 1.0;
        }
      }
    }
    for (std::size_t j = 2; j + 2 < ring.size(); ++j) {
      bool regular = true;
      for (std::size_t k = j - 2; k < j + 2 && regular; ++k) {
        const double ratio = (azimuth[ring[k + 1]] - azimuth[ring[k]]) / nominal;
        regular = ratio > 0.3 && ratio < 1.3;
      }
      if (!regular) continue;
      const double a0 = range[ring[j - 2]], a = range[ring[j - 1]], b = range[ring[j]];
      const double c = range[ring[j + 1]], c0 = range[ring[j + 2]];
      const double jump = std::abs(c - a);
      if (jump < std::max(1.0, 0.2 * std::min(a, c))) continue;
      if (std::abs(a0 - a) > 0.05 * a || std::abs(c0 - c) > 0.05 * c) continue;
      ++edges;
      const double margin = 0.1 * jump;
      mixed += b > std::min(a, c) + margin && b < std::max(a, c) - margin;
    }
  }
  for (std::size_t b = 0; b < fired_i.size(); ++b)
    s.return_rate_by_incidence[b] = fired_i[b] > 0 ? returned_i[b] / fired_i[b] : std::nan("");
  if (scan.hasIntensity()) {
    s.mean_intensity =
        std::accumulate(scan.intensity.begin(), scan.intensity.end(), 0.0) / static_cast<double>(n);
    std::size_t within = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (range[i] > 40.0) continue;
      ++within;
      const std::size_t bin = binOf(kIntensityEdges, scan.intensity[i]);
      if (bin < s.intensity_share.size()) s.intensity_share[bin] += 1.0;
    }
    for (double& share : s.intensity_share)
      share /= static_cast<double>(std::max<std::size_t>(within, 1));
  }
  for (std::size_t b = 0; b < fired_v.size(); ++b)
    s.return_rate_by_intensity[b] = fired_v[b] > 0 ? returned_v[b] / fired_v[b] : std::nan("");
  s.mixed_pixel_share = edges > 0 ? static_cast<double>(mixed) / static_cast<double>(edges) : 0.0;
  return s;
}

AttitudeStatistics measureAttitude(const core::Trajectory& T_world_sensor) {
  const std::size_t n = T_world_sensor.size();
  if (n < 50)
    throw core::Error("attitude statistics need at least 50 poses, not " + std::to_string(n));
  std::vector<double> pitch(n), roll(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Matrix3d R = T_world_sensor.pose(i).linear();
    pitch[i] = std::asin(std::clamp(R(2, 0), -1.0, 1.0)) * 180.0 / M_PI;  // nose up: positive
    roll[i] = std::atan2(R(2, 1), R(2, 2)) * 180.0 / M_PI;
  }
  const auto fast = [&](const std::vector<double>& angle) {
    std::vector<double> out;
    std::size_t lo = 0, hi = 0;
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double t = T_world_sensor.stamp(i);
      while (hi < n && T_world_sensor.stamp(hi) <= t + 1.0) sum += angle[hi++];
      while (T_world_sensor.stamp(lo) < t - 1.0) sum -= angle[lo++];
      out.push_back(std::abs(angle[i] - sum / static_cast<double>(hi - lo)));
    }
    return out;
  };
  const auto p99 = [](std::vector<double> v) {
    const auto at =
        v.begin() + static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), at, v.end());
    return *at;
  };
  std::vector<double> fast_pitch = fast(pitch), fast_roll = fast(roll);
  AttitudeStatistics a;
  a.pitch_p99_deg = p99(fast_pitch);
  a.roll_p99_deg = p99(fast_roll);
  a.pitch_sigma_deg = robustSigma(fast_pitch);
  a.roll_sigma_deg = robustSigma(fast_roll);
  return a;
}

std::span<const StatisticRow> statisticRows() {
  // Tolerances: 3 mm of noise, half a percent of firings, three percent of
  // the returns' intensities, a percent of the edges and scattered returns.
  static const std::vector<StatisticRow> rows = {
      {"plane noise 2-10 m (m)", [](const ScanStatistics& s) { return s.plane_noise[0]; }, 0.003},
      {"plane noise 10-20 m (m)", [](const ScanStatistics& s) { return s.plane_noise[1]; }, 0.003},
      {"plane noise 20-40 m (m)", [](const ScanStatistics& s) { return s.plane_noise[2]; }, 0.003},
      {"mixed pixels at depth edges", [](const ScanStatistics& s) { return s.mixed_pixel_share; },
       0.01},
      {"return rate, incidence 0-30 deg",
       [](const ScanStatistics& s) { return s.return_rate_by_incidence[0]; }, 0.005},
      {"return rate, incidence 30-60 deg",
       [](const ScanStatistics& s) { return s.return_rate_by_incidence[1]; }, 0.005},
      {"return rate, incidence 60-75 deg",
       [](const ScanStatistics& s) { return s.return_rate_by_incidence[2]; }, 0.005},
      {"return rate, incidence 75-90 deg",
       [](const ScanStatistics& s) { return s.return_rate_by_incidence[3]; }, 0.005},
      {"return rate, intensity < 0.1",
       [](const ScanStatistics& s) { return s.return_rate_by_intensity[0]; }, 0.005},
      {"return rate, intensity 0.1-0.3",
       [](const ScanStatistics& s) { return s.return_rate_by_intensity[1]; }, 0.005},
      {"return rate, intensity > 0.3",
       [](const ScanStatistics& s) { return s.return_rate_by_intensity[2]; }, 0.005},
      {"returns of intensity < 0.1", [](const ScanStatistics& s) { return s.intensity_share[0]; },
       0.03},
      {"returns of intensity 0.1-0.3", [](const ScanStatistics& s) { return s.intensity_share[1]; },
       0.03},
      {"returns of intensity > 0.3", [](const ScanStatistics& s) { return s.intensity_share[2]; },
       0.03},
      {"mean intensity", [](const ScanStatistics& s) { return s.mean_intensity; }, 0.03},
      {"scattered returns, 2-30 m", [](const ScanStatistics& s) { return s.scattered_share; },
       0.01},
      {"scattered returns' depth, 90th percentile (m)",
       [](const ScanStatistics& s) { return s.scattered_depth; }, 0.01},
      {"half steps along a ring", [](const ScanStatistics& s) { return s.half_step_share; }, 0.01},
      {"step jitter (of the step)", [](const ScanStatistics& s) { return s.step_jitter; }, 0.005},
  };
  return rows;
}

StatisticBand bandOf(const StatisticRow& row, std::span<const ScanStatistics> scans) {
  if (scans.empty()) throw core::Error("a statistic's band needs at least one scan");
  StatisticBand band{1e300, -1e300};
  for (const ScanStatistics& s : scans) {
    const double v = row.value(s);
    if (std::isnan(v)) continue;
    band.lo = std::min(band.lo, v);
    band.hi = std::max(band.hi, v);
  }
  return band;
}

}  // namespace dcl::eval
