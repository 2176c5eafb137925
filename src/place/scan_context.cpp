#include <algorithm>
#include <cmath>
#include <string>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/place/scan_context.hpp>

namespace dcl::place {

namespace {

constexpr double kPi = 3.14159265358979323846;

void checkScanContext(bool ok, const std::string& what) {
  if (!ok) throw core::Error("Scan Context: " + what);
}

std::size_t toSize(int i) {
  return static_cast<std::size_t>(i);
}

void validate(const ScanContextConfig& c) {
  core::checkConfig(c, "Scan Context config");
}

/// Bin of a point, or -1 when it is beyond max_range or not finite.
int binOf(const ScanContextConfig& c, const Eigen::Vector3f& p) {
  if (!p.allFinite()) return -1;
  const double range = std::hypot(p.x(), p.y());
  if (range >= c.max_range) return -1;
  double angle = std::atan2(p.y(), p.x());
  if (angle < 0.0) angle += 2.0 * kPi;
  const int ring = std::min(static_cast<int>(range / c.max_range * c.rings), c.rings - 1);
  const int sector = std::min(static_cast<int>(angle / (2.0 * kPi) * c.sectors), c.sectors - 1);
  return ring * c.sectors + sector;
}

/// The Euclidean norm of every sector (column).
std::vector<double> columnNorms(const ScanContextDescriptor& d) {
  std::vector<double> norms(toSize(d.sectors), 0.0);
  for (int r = 0; r < d.rings; ++r)
    for (int s = 0; s < d.sectors; ++s)
      norms[toSize(s)] += static_cast<double>(d.at(r, s)) * d.at(r, s);
  for (double& n : norms) n = std::sqrt(n);
  return norms;
}

void checkComparable(const ScanContextDescriptor& a, const ScanContextDescriptor& b) {
  checkScanContext(a.rings == b.rings && a.sectors == b.sectors && a.sectors > 0,
                   "cannot compare descriptors of different dimensions");
}

double distanceWithNorms(const ScanContextDescriptor& q, const ScanContextDescriptor& c,
                         const std::vector<double>& qn, const std::vector<double>& cn, int shift) {
  double similarity = 0.0;
  int columns = 0;
  for (int j = 0; j < q.sectors; ++j) {
    const int k = (j + shift) % q.sectors;
    if (qn[toSize(j)] <= 0.0 || cn[toSize(k)] <= 0.0) continue;
    double dot = 0.0;
    for (int r = 0; r < q.rings; ++r) dot += static_cast<double>(q.at(r, j)) * c.at(r, k);
    similarity += dot / (qn[toSize(j)] * cn[toSize(k)]);
    ++columns;
  }
  return columns == 0 ? 1.0 : 1.0 - similarity / columns;
}

}  // namespace

ScanContextDescriptor describeScanContext(const core::PointCloud& scan,
                                          const ScanContextConfig& config) {
  validate(config);
  ScanContextDescriptor d;
  d.rings = config.rings;
  d.sectors = config.sectors;
  d.cells.assign(toSize(config.rings * config.sectors), 0.0F);
  for (const Eigen::Vector3f& p : scan.points) {
    const int bin = binOf(config, p);
    if (bin < 0) continue;
    // Heights lifted by the mount height so that 0 can mean "empty" (Kim & Kim).
    const auto h = static_cast<float>(p.z() + config.sensor_height);
    d.cells[toSize(bin)] = std::max(d.cells[toSize(bin)], h);
  }
  d.ring_key.assign(toSize(config.rings), 0.0F);
  for (int r = 0; r < d.rings; ++r) {
    double sum = 0.0;
    for (int s = 0; s < d.sectors; ++s) sum += d.at(r, s);
    d.ring_key[toSize(r)] = static_cast<float>(sum / d.sectors);
  }
  return d;
}

double scanContextDistance(const ScanContextDescriptor& query,
                           const ScanContextDescriptor& candidate, int shift) {
  checkComparable(query, candidate);
  const int s = ((shift % query.sectors) + query.sectors) % query.sectors;
  return distanceWithNorms(query, candidate, columnNorms(query), columnNorms(candidate), s);
}

Match matchScanContext(const ScanContextDescriptor& query, const ScanContextDescriptor& candidate) {
  checkComparable(query, candidate);
  const std::vector<double> qn = columnNorms(query);
  const std::vector<double> cn = columnNorms(candidate);
  Match best;
  best.distance = 2.0;
  // Every shift: 60 shifts of 60 x 20 products is cheaper than Scan Context's
  // sector-key pre-alignment is worth.
  for (int shift = 0; shift < query.sectors; ++shift) {
    const double d = distanceWithNorms(query, candidate, qn, cn, shift);
    if (d < best.distance) {
      best.distance = d;
      best.shift = shift;
    }
  }
  const int n = query.sectors;
  const int signed_shift = best.shift > n / 2 ? best.shift - n : best.shift;
  best.yaw_rad = -2.0 * kPi * signed_shift / n;
  best.reversed = std::abs(signed_shift) * 4 > n;
  return best;
}

ScanContext::ScanContext(const ScanContextConfig& config) : config_(config) {
  validate(config_);
}

std::size_t ScanContext::keySize() const {
  return toSize(config_.rings);
}

std::shared_ptr<const PlaceDescriptor> ScanContext::describe(const core::PointCloud& scan) const {
  return std::make_shared<const ScanContextDescriptor>(describeScanContext(scan, config_));
}

Match ScanContext::match(const PlaceDescriptor& query, const PlaceDescriptor& candidate) const {
  const auto* q = dynamic_cast<const ScanContextDescriptor*>(&query);
  const auto* c = dynamic_cast<const ScanContextDescriptor*>(&candidate);
  checkScanContext(q != nullptr && c != nullptr,
                   "match: both descriptors must be Scan Context descriptors");
  return matchScanContext(*q, *c);
}

}  // namespace dcl::place
