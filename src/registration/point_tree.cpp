#include <algorithm>
#include <array>
#include <limits>

#include <nanoflann.hpp>

#include <dcl/registration/point_tree.hpp>

namespace dcl::registration {
namespace {

/// The points as nanoflann's dataset adaptor.
struct PointSet {
  std::vector<Eigen::Vector3d> points;

  [[nodiscard]] std::size_t kdtree_get_point_count() const { return points.size(); }
  [[nodiscard]] double kdtree_get_pt(std::size_t i, std::size_t dim) const {
    return points[i][static_cast<Eigen::Index>(dim)];
  }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox& /*bbox*/) const {
    return false;
  }
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointSet>,
                                                 PointSet, 3, std::uint32_t>;

/// Collects every point within a radius without sorting (nanoflann's
/// RadiusResultSet wants std::pair; FPFH wants our Neighbor).
class WithinResultSet {
 public:
  WithinResultSet(double squared_radius, std::vector<Neighbor>& out)
      : squared_radius_(squared_radius), out_(out) {}

  [[nodiscard]] std::size_t size() const { return out_.size(); }
  [[nodiscard]] bool full() const { return true; }
  bool addPoint(double squared_distance, std::uint32_t index) {
    if (squared_distance < squared_radius_) out_.push_back({index, squared_distance});
    return true;
  }
  [[nodiscard]] double worstDist() const { return squared_radius_; }

 private:
  double squared_radius_;
  std::vector<Neighbor>& out_;
};

}  // namespace

struct PointTree::Index {
  PointSet set;
  Tree tree;

  explicit Index(std::vector<Eigen::Vector3d> points)
      : set{std::move(points)}, tree(3, set, nanoflann::KDTreeSingleIndexAdaptorParams(16)) {}
};

PointTree::PointTree(std::vector<Eigen::Vector3d> points)
    : index_(std::make_unique<Index>(std::move(points))) {}
PointTree::~PointTree() = default;
PointTree::PointTree(PointTree&& other) noexcept = default;
PointTree& PointTree::operator=(PointTree&& other) noexcept = default;

const std::vector<Eigen::Vector3d>& PointTree::points() const {
  static const std::vector<Eigen::Vector3d> kNone;
  return index_ ? index_->set.points : kNone;
}

std::optional<Neighbor> PointTree::nearest(const Eigen::Vector3d& query,
                                           double max_distance) const {
  if (empty()) return std::nullopt;
  std::uint32_t index = 0;
  double squared_distance = 0.0;
  nanoflann::KNNResultSet<double, std::uint32_t> result(1);
  result.init(&index, &squared_distance);
  squared_distance = max_distance * max_distance;  // prunes the search beyond the gate
  index_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
  if (result.size() == 0) return std::nullopt;
  return Neighbor{index, squared_distance};
}

void PointTree::nearest(const Eigen::Vector3d& query, std::size_t k, double max_distance,
                        std::vector<Neighbor>& out) const {
  out.clear();
  k = std::min(k, kMaxNeighbors);
  if (empty() || k == 0) return;
  std::array<std::uint32_t, kMaxNeighbors> indices{};
  std::array<double, kMaxNeighbors> squared_distances{};
  nanoflann::KNNResultSet<double, std::uint32_t> result(k);
  result.init(indices.data(), squared_distances.data());
  squared_distances[k - 1] = max_distance * max_distance;
  index_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
  for (std::size_t i = 0; i < result.size(); ++i) out.push_back({indices[i], squared_distances[i]});
}

void PointTree::within(const Eigen::Vector3d& query, double radius,
                       std::vector<Neighbor>& out) const {
  out.clear();
  if (empty()) return;
  WithinResultSet result(radius * radius, out);
  index_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
}

}  // namespace dcl::registration
