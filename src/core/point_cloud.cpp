#include <dcl/core/error.hpp>
#include <dcl/core/point_cloud.hpp>

namespace dcl::core {

namespace {
template <class T>
bool channelFits(const std::vector<T>& channel, std::size_t n) {
  return channel.empty() || channel.size() == n;
}

template <class T>
void appendChannel(std::vector<T>& to, const std::vector<T>& from, std::size_t old_size,
                   const char* name) {
  if (to.empty() && from.empty()) return;
  if (to.size() != old_size || from.empty()) {
    throw Error(std::string("PointCloud::append: channel '") + name +
                "' present in one cloud only");
  }
  to.insert(to.end(), from.begin(), from.end());
}
}  // namespace

bool PointCloud::consistent() const {
  const std::size_t n = points.size();
  return channelFits(intensity, n) && channelFits(time, n) && channelFits(ring, n);
}

void PointCloud::reserve(std::size_t n) {
  points.reserve(n);
  intensity.reserve(n);
  time.reserve(n);
  ring.reserve(n);
}

void PointCloud::clear() {
  points.clear();
  intensity.clear();
  time.clear();
  ring.clear();
}

void PointCloud::append(const PointCloud& other) {
  if (empty()) {
    *this = other;
    return;
  }
  const std::size_t old_size = size();
  points.insert(points.end(), other.points.begin(), other.points.end());
  appendChannel(intensity, other.intensity, old_size, "intensity");
  appendChannel(time, other.time, old_size, "time");
  appendChannel(ring, other.ring, old_size, "ring");
}

void PointCloud::transform(const Eigen::Isometry3d& T_target_source) {
  const Eigen::Isometry3f T = T_target_source.cast<float>();
  for (auto& p : points) p = T * p;
}

PointCloud transformed(const PointCloud& cloud, const Eigen::Isometry3d& T_target_source) {
  PointCloud out = cloud;
  out.transform(T_target_source);
  return out;
}

}  // namespace dcl::core
