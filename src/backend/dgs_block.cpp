#include "dgs_block.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <queue>
#include <string>

#include <dcl/core/error.hpp>

namespace dcl::backend::dgs {
namespace {

using Triplets = std::vector<Eigen::Triplet<double>>;

/// Union-find over node indices, for the components a layout holds.
class Components {
 public:
  explicit Components(int n) : parent_(static_cast<std::size_t>(n)) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  int find(int i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  /// Joins the components of a and b under the lower root, so a root is its component's lowest
  /// node.
  void join(int a, int b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<int> parent_;
};

bool bothWeights(const Edge& e) {
  return e.w.rotation > 0.0 && e.w.translation > 0.0;
}

void addDiagonal(Triplets& triplets, int row, int size, double value) {
  for (int k = 0; k < size; ++k) triplets.emplace_back(row + k, row + k, value);
}

void addBlock(Triplets& triplets, int row, int col, const Eigen::Matrix3d& m) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) triplets.emplace_back(row + r, col + c, m(r, c));
  }
}

/// Factors the symmetric matrix of `triplets` (duplicates summed).
bool factor(Eigen::SimplicialLLT<Eigen::SparseMatrix<double>>& llt, int size,
            const Triplets& triplets) {
  Eigen::SparseMatrix<double> matrix(size, size);
  matrix.setFromTriplets(triplets.begin(), triplets.end());
  llt.compute(matrix);
  return llt.info() == Eigen::Success;
}

/// Edge weights as a scalar graph Laplacian: w on both diagonals, -w between free ends.
void addLaplacianEdge(Triplets& triplets, int a, int b, double w) {
  if (a >= 0) triplets.emplace_back(a, a, w);
  if (b >= 0) triplets.emplace_back(b, b, w);
  if (a >= 0 && b >= 0) {
    triplets.emplace_back(a, b, -w);
    triplets.emplace_back(b, a, -w);
  }
}

}  // namespace

Weights isotropicWeights(const core::Matrix6d& information, const std::string& what) {
  if (!information.allFinite()) throw core::Error(what + ": information is not finite");
  const Weights w{information.bottomRightCorner<3, 3>().trace() / 3.0,
                  information.topLeftCorner<3, 3>().trace() / 3.0};
  if (w.rotation < 0.0 || w.translation < 0.0) {
    throw core::Error(what + ": information has a negative trace in its " +
                      (w.rotation < 0.0 ? "rotation" : "translation") + " block");
  }
  return w;
}

Block::Block(std::vector<core::PoseKey> keys, const std::vector<Factor>& factors,
             const std::string& what)
    : keys_(std::move(keys)) {
  for (std::size_t i = 0; i < keys_.size(); ++i) index_.emplace(keys_[i], static_cast<int>(i));
  for (const Factor& f : factors) {
    if (f.from == f.to) continue;
    Edge e;
    e.from = indexOf(f.from);
    e.to = indexOf(f.to);
    if (e.from < 0 && e.to < 0) continue;
    e.R = f.T_from_to.linear();
    e.t = f.T_from_to.translation();
    e.w = isotropicWeights(
        f.information, what + ": factor " + core::keyName(f.from) + " -> " + core::keyName(f.to));
    if (e.from >= 0 && e.to >= 0) {
      internal_.push_back(e);
    } else {
      e.other = e.from < 0 ? f.from : f.to;
      separators_.push_back(e);
    }
  }
}

int Block::indexOf(const core::PoseKey& key) const {
  const auto it = index_.find(key);
  return it == index_.end() ? -1 : it->second;
}

Layout makeLayout(const Block& block, const std::vector<bool>& fixed,
                  const std::vector<bool>& active) {
  const int n = block.size();
  Components components(n);
  for (const Edge& e : block.internal()) {
    if (bothWeights(e)) components.join(e.from, e.to);
  }
  std::vector<bool> held(static_cast<std::size_t>(n), false);
  Layout layout;
  for (int i = 0; i < n; ++i) {
    if (fixed[i]) held[components.find(i)] = layout.grounded = true;
  }
  for (std::size_t s = 0; s < block.separators().size(); ++s) {
    const Edge& e = block.separators()[s];
    if (active[s] && bothWeights(e)) held[components.find(e.own())] = layout.grounded = true;
  }
  layout.unknown.assign(static_cast<std::size_t>(n), -1);
  for (int i = 0; i < n; ++i) {
    const int root = components.find(i);
    const bool anchor = !held[root] && root == i;  // an unheld component's lowest node
    if (!fixed[i] && !anchor) layout.unknown[i] = layout.unknowns++;
  }
  return layout;
}

// Stage 1. Unknown per free node: x_i = R_i^T (its columns are R_i's rows).
// Edge residual R_j - R_i R_ij, transposed x_j - R_ij^T x_i: normal equations
// H_ii += w I, H_jj += w I, H_ij -= w R_ij, H_ji -= w R_ij^T; a held or
// neighbour's end moves its term to the right-hand side.

bool RotationProblem::configure(const Block& block, const Layout& layout,
                                const std::vector<bool>& active,
                                const std::vector<Eigen::Matrix3d>& values) {
  layout_ = layout;
  const int n = layout.unknowns;
  b_held_ = Eigen::MatrixXd::Zero(3 * n, 3);
  Triplets triplets;
  triplets.reserve(block.internal().size() * 24 + block.separators().size() * 3);
  for (const Edge& e : block.internal()) {
    const double w = e.w.rotation;
    const int a = layout.unknown[e.from];
    const int b = layout.unknown[e.to];
    if (w <= 0.0 || (a < 0 && b < 0)) continue;
    if (a >= 0) addDiagonal(triplets, 3 * a, 3, w);
    if (b >= 0) addDiagonal(triplets, 3 * b, 3, w);
    if (a >= 0 && b >= 0) {
      addBlock(triplets, 3 * a, 3 * b, -w * e.R);
      addBlock(triplets, 3 * b, 3 * a, -w * e.R.transpose());
    } else if (a >= 0) {
      b_held_.middleRows<3>(3 * a) += w * e.R * values[e.to].transpose();
    } else {
      b_held_.middleRows<3>(3 * b) += w * e.R.transpose() * values[e.from].transpose();
    }
  }
  for (std::size_t s = 0; s < block.separators().size(); ++s) {
    const Edge& e = block.separators()[s];
    const int u = layout.unknown[e.own()];
    if (active[s] && u >= 0 && e.w.rotation > 0.0) addDiagonal(triplets, 3 * u, 3, e.w.rotation);
  }
  return n == 0 || factor(llt_, 3 * n, triplets);
}

std::vector<Eigen::Matrix3d> RotationProblem::solve(
    const Block& block, const std::vector<bool>& active,
    const std::map<core::PoseKey, Eigen::Matrix3d>& neighbours,
    const std::vector<Eigen::Matrix3d>& values) const {
  std::vector<Eigen::Matrix3d> out = values;
  if (layout_.unknowns == 0) return out;
  Eigen::MatrixXd b = b_held_;
  for (std::size_t s = 0; s < block.separators().size(); ++s) {
    const Edge& e = block.separators()[s];
    const int u = layout_.unknown[e.own()];
    if (!active[s] || u < 0 || e.w.rotation <= 0.0) continue;
    const Eigen::Matrix3d x_other = neighbours.at(e.other).transpose();
    b.middleRows<3>(3 * u) +=
        e.w.rotation * (e.ownIsFrom() ? Eigen::Matrix3d(e.R * x_other) : e.R.transpose() * x_other);
  }
  const Eigen::MatrixXd x = llt_.solve(b);
  for (int i = 0; i < block.size(); ++i) {
    const int u = layout_.unknown[i];
    if (u >= 0) out[i] = x.middleRows<3>(3 * u).transpose();
  }
  return out;
}

Eigen::Matrix3d PoseValues::rotation(int i) const {
  return core::expSO3(delta[i]) * R_hat[i];
}

Eigen::Isometry3d PoseValues::pose(int i) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotation(i);
  T.translation() = t[i];
  return T;
}

// Stage 2, corrections: residual d_j - d_i - log(R^_i R_ij R^_j^T), a scalar
// Laplacian (times the 3x3 identity) with three right-hand sides. A held end's
// d is its current value, a neighbour's the one its pose and R^ give.

bool PoseProblem::configure(const Block& block, const Layout& layout,
                            const std::vector<bool>& active, const PoseValues& values) {
  layout_ = layout;
  const int n = layout.unknowns;
  b_rotation_held_ = Eigen::MatrixXd::Zero(n, 3);
  Triplets rotation;
  Triplets translation;
  for (const Edge& e : block.internal()) {
    const int a = layout.unknown[e.from];
    const int b = layout.unknown[e.to];
    if (a < 0 && b < 0) continue;
    addLaplacianEdge(rotation, a, b, e.w.rotation);
    addLaplacianEdge(translation, a, b, e.w.translation);
    const Eigen::Vector3d c =
        core::logSO3(values.R_hat[e.from] * e.R * values.R_hat[e.to].transpose());
    if (b >= 0) {
      b_rotation_held_.row(b) +=
          e.w.rotation * (a >= 0 ? c : Eigen::Vector3d(c + values.delta[e.from])).transpose();
    }
    if (a >= 0) {
      b_rotation_held_.row(a) +=
          e.w.rotation * (b >= 0 ? Eigen::Vector3d(-c) : values.delta[e.to] - c).transpose();
    }
  }
  for (std::size_t s = 0; s < block.separators().size(); ++s) {
    const Edge& e = block.separators()[s];
    const int u = layout.unknown[e.own()];
    if (!active[s] || u < 0) continue;
    rotation.emplace_back(u, u, e.w.rotation);
    translation.emplace_back(u, u, e.w.translation);
  }
  return n == 0 || (factor(rotation_llt_, n, rotation) && factor(translation_llt_, n, translation));
}

void PoseProblem::step(const Block& block, const std::vector<bool>& active,
                       const std::map<core::PoseKey, Eigen::Isometry3d>& neighbours,
                       const std::map<core::PoseKey, Eigen::Matrix3d>& linearisation, double gamma,
                       bool first, PoseValues& values) const {
  if (layout_.unknowns == 0) return;
  const Eigen::MatrixXd delta =
      rotation_llt_.solve(correctionRhs(block, active, neighbours, linearisation, values));
  for (int i = 0; i < block.size(); ++i) {
    const int u = layout_.unknown[i];
    if (u < 0) continue;
    values.delta[i] =
        relax<Eigen::Vector3d>(values.delta[i], delta.row(u).transpose(), gamma, first);
  }
  const Eigen::MatrixXd t =
      translation_llt_.solve(translationRhs(block, active, neighbours, values));
  for (int i = 0; i < block.size(); ++i) {
    const int u = layout_.unknown[i];
    if (u >= 0)
      values.t[i] = relax<Eigen::Vector3d>(values.t[i], t.row(u).transpose(), gamma, first);
  }
}

Eigen::MatrixXd PoseProblem::correctionRhs(
    const Block& block, const std::vector<bool>& active,
    const std::map<core::PoseKey, Eigen::Isometry3d>& neighbours,
    const std::map<core::PoseKey, Eigen::Matrix3d>& linearisation, const PoseValues& values) const {
  Eigen::MatrixXd b = b_rotation_held_;
  for (std::size_t s = 0; s < block.separators().size(); ++s) {
    const Edge& e = block.separators()[s];
    const int u = layout_.unknown[e.own()];
    if (!active[s] || u < 0) continue;
    // The neighbour's node at its linearisation point R^ and correction d when
    // it sent R^, else linearised at its full rotation (d = 0 there).
    const Eigen::Matrix3d& R_other = neighbours.at(e.other).linear();
    const auto linearised = linearisation.find(e.other);
    const bool known = linearised != linearisation.end();
    const Eigen::Matrix3d R_hat_other = known ? linearised->second : R_other;
    const Eigen::Vector3d d_other =
        known ? core::logSO3(R_other * R_hat_other.transpose()) : Eigen::Vector3d::Zero();
    const Eigen::Matrix3d& R_hat = values.R_hat[e.own()];
    const Eigen::Vector3d c =
        e.ownIsFrom()
            ? Eigen::Vector3d(d_other - core::logSO3(R_hat * e.R * R_hat_other.transpose()))
            : Eigen::Vector3d(d_other + core::logSO3(R_hat_other * e.R * R_hat.transpose()));
    b.row(u) += e.w.rotation * c.transpose();
  }
  return b;
}

// Stage 2, translations: residual t_j - t_i - R_i t_ij with the corrected R_i,
// the same Laplacian structure; a neighbour's end at its full pose.
Eigen::MatrixXd PoseProblem::translationRhs(
    const Block& block, const std::vector<bool>& active,
    const std::map<core::PoseKey, Eigen::Isometry3d>& neighbours, const PoseValues& values) const {
  std::vector<Eigen::Matrix3d> R(static_cast<std::size_t>(block.size()));
  for (int i = 0; i < block.size(); ++i) R[i] = values.rotation(i);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(layout_.unknowns, 3);
  for (const Edge& e : block.internal()) {
    const int a = layout_.unknown[e.from];
    const int c = layout_.unknown[e.to];
    if (a < 0 && c < 0) continue;
    const Eigen::Vector3d u = R[e.from] * e.t;
    if (c >= 0) {
      b.row(c) +=
          e.w.translation * (a >= 0 ? u : Eigen::Vector3d(u + values.t[e.from])).transpose();
    }
    if (a >= 0) {
      b.row(a) += e.w.translation * (c >= 0 ? Eigen::Vector3d(-u) : values.t[e.to] - u).transpose();
    }
  }
  for (std::size_t s = 0; s < block.separators().size(); ++s) {
    const Edge& e = block.separators()[s];
    const int u = layout_.unknown[e.own()];
    if (!active[s] || u < 0) continue;
    const Eigen::Isometry3d& T_other = neighbours.at(e.other);
    const Eigen::Vector3d r = e.ownIsFrom()
                                  ? Eigen::Vector3d(T_other.translation() - R[e.own()] * e.t)
                                  : T_other.translation() + T_other.linear() * e.t;
    b.row(u) += e.w.translation * r.transpose();
  }
  return b;
}

std::vector<Eigen::Isometry3d> initialEstimates(const std::vector<core::PoseKey>& keys,
                                                const PoseGraph& graph) {
  std::map<core::PoseKey, int> index;
  for (std::size_t i = 0; i < keys.size(); ++i) index.emplace(keys[i], static_cast<int>(i));
  std::vector<Eigen::Isometry3d> T(keys.size(), Eigen::Isometry3d::Identity());
  std::vector<bool> known(keys.size(), false);
  // Adjacency of the unknown-estimate nodes: (neighbour, T_this_neighbour).
  std::vector<std::vector<std::pair<int, Eigen::Isometry3d>>> adjacent(keys.size());
  for (const Factor& f : graph.factors()) {
    const auto a = index.find(f.from);
    const auto b = index.find(f.to);
    if (a == index.end() || b == index.end() || a == b) continue;
    adjacent[a->second].emplace_back(b->second, f.T_from_to);
    adjacent[b->second].emplace_back(a->second, f.T_from_to.inverse());
  }
  std::queue<int> queue;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    if (graph.hasNode(keys[i])) {
      T[i] = graph.estimate(keys[i]);
      known[i] = true;
      queue.push(static_cast<int>(i));
    }
  }
  while (!queue.empty()) {
    const int i = queue.front();
    queue.pop();
    for (const auto& [j, T_i_j] : adjacent[i]) {
      if (known[j]) continue;
      T[j] = T[i] * T_i_j;
      known[j] = true;
      queue.push(j);
    }
  }
  return T;
}

}  // namespace dcl::backend::dgs
