#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <cmath>
#include <set>

#include <dcl/backend/refine_coarse.hpp>

namespace dcl::backend {
namespace {

/// A side shorter than this many cells is flat.
constexpr double kFlatSide = 0.01;
/// Poses a coarse node stands for at least: the coarse level stays a fraction
/// of the block's size (a 5x5x5 grid of poses needs no 9x9x9 grid of nodes).
constexpr std::size_t kPosesPerNode = 4;

/// d[rho; phi] / d[v; omega]: a motion [v; omega] about `centre` as the right
/// perturbation of T (to first order t += v + omega x (t - centre), R = exp(omega) R).
core::Matrix6d motionToRight(const Eigen::Isometry3d& T, const Eigen::Vector3d& centre) {
  const Eigen::Matrix3d Rt = T.linear().transpose();
  core::Matrix6d A = core::Matrix6d::Zero();
  A.topLeftCorner<3, 3>() = Rt;
  A.topRightCorner<3, 3>() = -Rt * core::hat(T.translation() - centre);
  A.bottomRightCorner<3, 3>() = Rt;
  return A;
}

/// The cell of `p` along one axis and the fraction into it.
std::pair<int, double> cellAlong(double p, double origin, double cell, int nodes) {
  if (nodes == 1) return {0, 0.0};
  const double u = std::clamp((p - origin) / cell, 0.0, static_cast<double>(nodes - 1));
  const int k = std::min(static_cast<int>(u), nodes - 2);
  return {k, u - k};
}

/// The grid over the box [lo, hi] with `cells` cells along its longest side.
CoarseGrid boxGrid(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int cells) {
  const Eigen::Vector3d side = hi - lo;
  CoarseGrid grid;
  grid.origin = lo;
  grid.cell = side.maxCoeff() > 0.0 ? side.maxCoeff() / cells : 1.0;
  for (int a = 0; a < 3; ++a) {
    const double span = side(a) / grid.cell;
    grid.nodes(a) =
        span < kFlatSide ? 1 : std::max(1, static_cast<int>(std::ceil(span - 1e-9))) + 1;
  }
  return grid;
}

/// The nodes whose hat functions some position lies in.
std::size_t supportedNodes(const CoarseGrid& grid, const std::vector<Eigen::Vector3d>& positions) {
  std::set<int> nodes;
  for (const Eigen::Vector3d& p : positions) {
    for (const CoarseWeight& w : coarseWeights(grid, p)) nodes.insert(w.node);
  }
  return nodes.size();
}

}  // namespace

CoarseGrid makeCoarseGrid(const std::vector<Eigen::Vector3d>& positions, int cells) {
  if (positions.empty() || cells < 1) return {};
  Eigen::Vector3d lo = positions.front();
  Eigen::Vector3d hi = positions.front();
  for (const Eigen::Vector3d& p : positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  CoarseGrid grid = boxGrid(lo, hi, cells);
  const auto crowded = [&] {
    return supportedNodes(grid, positions) * kPosesPerNode > positions.size();
  };
  while (cells > 1 && crowded()) grid = boxGrid(lo, hi, --cells);
  if (crowded()) {
    // Too few poses for even one cell: one rigid motion about the box's centre.
    grid.origin = 0.5 * (lo + hi);
    grid.nodes = Eigen::Vector3i::Ones();
  }
  return grid;
}

std::vector<CoarseWeight> coarseWeights(const CoarseGrid& grid, const Eigen::Vector3d& p) {
  std::array<std::pair<int, double>, 3> at;
  for (int a = 0; a < 3; ++a) at[a] = cellAlong(p(a), grid.origin(a), grid.cell, grid.nodes(a));
  std::vector<CoarseWeight> weights;
  for (int corner = 0; corner < 8; ++corner) {
    Eigen::Vector3i index;
    double weight = 1.0;
    for (int a = 0; a < 3; ++a) {
      const int up = (corner >> a) & 1;
      if (up == 1 && grid.nodes(a) == 1) weight = 0.0;
      index(a) = at[a].first + up;
      weight *= up == 1 ? at[a].second : 1.0 - at[a].second;
    }
    if (weight <= 0.0) continue;
    const int node = (index.z() * grid.nodes.y() + index.y()) * grid.nodes.x() + index.x();
    weights.push_back({node, weight, grid.origin + grid.cell * index.cast<double>()});
  }
  return weights;
}

Eigen::Isometry3d applyCoarse(const CoarseStep& step, core::RobotId robot, const CoarseGrid& grid,
                              const Eigen::Isometry3d& T_world_node) {
  Eigen::Vector3d dt = Eigen::Vector3d::Zero();
  Eigen::Vector3d dtheta = Eigen::Vector3d::Zero();
  const Eigen::Vector3d t = T_world_node.translation();
  for (const CoarseWeight& w : coarseWeights(grid, t)) {
    const auto it = step.motion.find({robot, w.node});
    if (it == step.motion.end()) continue;
    const Eigen::Vector3d omega = it->second.tail<3>();
    dt += w.weight * (it->second.head<3>() + omega.cross(t - w.centre));
    dtheta += w.weight * omega;
  }
  Eigen::Isometry3d moved = T_world_node;
  moved.linear() = core::expSO3(dtheta) * T_world_node.linear();
  moved.translation() = t + dt;
  return moved;
}

void appendCoarseColumns(std::vector<CoarseColumn>& columns, const core::Matrix6d& J,
                         core::RobotId robot, const CoarseGrid& grid,
                         const Eigen::Isometry3d& T_world_node) {
  for (const CoarseWeight& w : coarseWeights(grid, T_world_node.translation())) {
    const core::Matrix6d C = w.weight * J * motionToRight(T_world_node, w.centre);
    const CoarseNode node{robot, w.node};
    const auto same = std::find_if(columns.begin(), columns.end(),
                                   [&](const CoarseColumn& c) { return c.node == node; });
    if (same != columns.end()) {
      same->J += C;
    } else {
      columns.push_back({node, C});
    }
  }
}

void addToShare(CoarseShare& share, const core::Vector6d& r,
                const std::vector<CoarseColumn>& columns, bool hessian) {
  for (const CoarseColumn& c : columns) {
    auto [g, added] = share.gradient.try_emplace(c.node, core::Vector6d::Zero());
    g->second += c.J.transpose() * r;
  }
  if (!hessian) return;
  for (const CoarseColumn& a : columns) {
    for (const CoarseColumn& b : columns) {
      if (b.node < a.node) continue;
      auto [h, added] = share.hessian.try_emplace({a.node, b.node}, core::Matrix6d::Zero());
      h->second += a.J.transpose() * b.J;
    }
  }
}

double relativeChange(const CoarseBlocks& now, const CoarseBlocks& before) {
  double change = 0.0;
  double norm = 0.0;
  for (const auto& [ab, block] : before) {
    norm += block.squaredNorm();
    const auto it = now.find(ab);
    change +=
        (it == now.end() ? block : Eigen::Matrix<double, 6, 6>(it->second - block)).squaredNorm();
  }
  for (const auto& [ab, block] : now) {
    if (!before.contains(ab)) change += block.squaredNorm();
  }
  return norm > 0.0 ? std::sqrt(change / norm) : (change > 0.0 ? 1.0 : 0.0);
}

CoarseStep scaled(const CoarseStep& step, double scale) {
  CoarseStep out = step;
  for (auto& [node, motion] : out.motion) motion *= scale;
  out.slope *= scale;
  return out;
}

CoarseChoice coarseScale(const CoarseStep& step, double cost,
                         const std::array<double, kCoarseScales.size()>& costs, double trust) {
  CoarseChoice choice;
  double best = cost;
  for (std::size_t k = 0; k < costs.size(); ++k) {
    if (costs[k] >= best) continue;
    best = costs[k];
    choice.scale = kCoarseScales[k];
  }
  const double predicted = -0.5 * step.slope;
  choice.refresh = predicted > 0.0 && cost - best < trust * predicted;
  return choice;
}

struct CoarseSolver::Impl {
  double damping;
  std::map<core::RobotId, CoarseBlocks> blocks;  // each robot's last sent
  std::map<CoarseNode, int> index;               // first unknown of each node
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  bool factorised = false;

  void factorise() {
    index.clear();
    for (const auto& [robot, robot_blocks] : blocks) {
      for (const auto& [ab, block] : robot_blocks) {
        index.try_emplace(ab.first, 0);
        index.try_emplace(ab.second, 0);
      }
    }
    int n = 0;
    for (auto& [node, first] : index) {
      first = n;
      n += 6;
    }
    std::vector<Eigen::Triplet<double>> entries;
    for (const auto& [robot, robot_blocks] : blocks) {
      for (const auto& [ab, block] : robot_blocks) addBlock(entries, ab, block);
    }
    Eigen::SparseMatrix<double> H(n, n);
    H.setFromTriplets(entries.begin(), entries.end());
    damp(H);
    ldlt.compute(H);
    factorised = n > 0 && ldlt.info() == Eigen::Success;
  }

  void addBlock(std::vector<Eigen::Triplet<double>>& entries,
                const std::pair<CoarseNode, CoarseNode>& ab, const core::Matrix6d& block) const {
    const int a = index.at(ab.first);
    const int b = index.at(ab.second);
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) {
        entries.emplace_back(a + r, b + c, block(r, c));
        if (a != b) entries.emplace_back(b + c, a + r, block(r, c));
      }
    }
  }

  /// H + damping D: D the diagonal, raised to a millionth of its largest
  /// entry so that a node no factor moves in some direction stays put.
  void damp(Eigen::SparseMatrix<double>& H) const {
    const Eigen::VectorXd d = H.diagonal();
    const double floor = 1e-6 * (d.size() > 0 ? d.maxCoeff() : 0.0);
    for (int i = 0; i < H.rows(); ++i)
      H.coeffRef(i, i) += damping * std::max(d(i), floor) + floor * 1e-6;
  }

  CoarseStep step(const std::vector<CoarseShare>& shares) const {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(6 * static_cast<Eigen::Index>(index.size()));
    for (const CoarseShare& s : shares) {
      for (const auto& [node, gradient] : s.gradient) {
        const auto it = index.find(node);
        if (it != index.end()) g.segment<6>(it->second) += gradient;
      }
    }
    const Eigen::VectorXd x = ldlt.solve(-g);
    CoarseStep step;
    for (const auto& [node, first] : index) step.motion.emplace(node, x.segment<6>(first));
    step.slope = 2.0 * g.dot(x);  // the chi-square is twice the least-squares cost
    return step;
  }
};

CoarseSolver::CoarseSolver(double damping) : impl_(std::make_unique<Impl>()) {
  impl_->damping = damping;
}
CoarseSolver::~CoarseSolver() = default;
CoarseSolver::CoarseSolver(CoarseSolver&&) noexcept = default;
CoarseSolver& CoarseSolver::operator=(CoarseSolver&&) noexcept = default;

CoarseStep CoarseSolver::solve(const std::vector<CoarseShare>& shares) {
  bool fresh = false;
  for (const CoarseShare& s : shares) {
    if (s.hessian.empty()) continue;
    impl_->blocks[s.robot] = s.hessian;
    fresh = true;
  }
  if (fresh) impl_->factorise();
  if (!impl_->factorised) return {};
  return impl_->step(shares);
}

}  // namespace dcl::backend
