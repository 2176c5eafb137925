#pragma once

/// The linear algebra of one DGS block (dgs.hpp): the nodes one solver owns,
/// the factors among them, the factors to other blocks' nodes (separators),
/// and the two stages' least-squares problems over them. A DgsAgent is one
/// block whose separators lead to its neighbours; chordalInitialise is one
/// block holding the whole graph and no separator.

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <map>
#include <string>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::backend::dgs {

/// The isotropic weights a factor gets in both stages.
struct Weights {
  double rotation = 0.0;     ///< trace of the information's rotation block / 3
  double translation = 0.0;  ///< trace of its translation block / 3
};

/// Weights of `information`; throws core::Error when an entry is not finite
/// or a block's trace is negative (the message names `what`).
Weights isotropicWeights(const core::Matrix6d& information, const std::string& what);

/// A factor as a block sees it: each end an own node (its index) or, for a
/// separator, the neighbour's node `other`.
struct Edge {
  int from = -1;                                    ///< own index; -1: the neighbour's end
  int to = -1;                                      ///< own index; -1: the neighbour's end
  core::PoseKey other;                              ///< the neighbour's node of a separator
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  ///< R_from_to
  Eigen::Vector3d t = Eigen::Vector3d::Zero();      ///< t_from_to
  Weights w;

  [[nodiscard]] int own() const { return from >= 0 ? from : to; }
  /// True when the own end is the from end.
  [[nodiscard]] bool ownIsFrom() const { return from >= 0; }
};

/// Own nodes (sorted keys), the edges among them and the separators.
class Block {
 public:
  Block() = default;
  /// `keys` sorted and unique; factors with no own end, or from a node to
  /// itself, are left out; `what` names the owner in error messages.
  Block(std::vector<core::PoseKey> keys, const std::vector<Factor>& factors,
        const std::string& what);

  [[nodiscard]] int size() const { return static_cast<int>(keys_.size()); }
  [[nodiscard]] const std::vector<core::PoseKey>& keys() const { return keys_; }
  /// Index of `key`, -1 when it is not an own node.
  [[nodiscard]] int indexOf(const core::PoseKey& key) const;
  [[nodiscard]] const std::vector<Edge>& internal() const { return internal_; }
  [[nodiscard]] const std::vector<Edge>& separators() const { return separators_; }

 private:
  std::vector<core::PoseKey> keys_;
  std::map<core::PoseKey, int> index_;
  std::vector<Edge> internal_;
  std::vector<Edge> separators_;
};

/// Which own nodes are unknowns of a solve.
struct Layout {
  std::vector<int> unknown;  ///< per node: its unknown index, -1 when held fixed
  int unknowns = 0;
  /// Some component is held by a given fixed node or a separator in use; when
  /// false the block cannot place itself and waits.
  bool grounded = false;

  bool operator==(const Layout&) const = default;
};

/// The layout for `fixed` nodes and the separators in use (`active`, per
/// separator). Every connected component of own nodes (through edges with both
/// weights positive) that holds no fixed node and no separator in use is held
/// by its lowest node.
Layout makeLayout(const Block& block, const std::vector<bool>& fixed,
                  const std::vector<bool>& active);

/// Stage 1: the chordal relaxation. Values are the unconstrained 3x3 estimates of R_world_node.
class RotationProblem {
 public:
  /// Assembles and factors the block matrix; `values` gives the held nodes' estimates.
  /// Returns false when the factorisation failed (the matrix is not positive definite).
  bool configure(const Block& block, const Layout& layout, const std::vector<bool>& active,
                 const std::vector<Eigen::Matrix3d>& values);
  /// The least-squares estimates of the unknowns with the neighbours' values
  /// (`neighbours`, holding every active separator's node) fixed; held nodes keep `values`.
  [[nodiscard]] std::vector<Eigen::Matrix3d> solve(
      const Block& block, const std::vector<bool>& active,
      const std::map<core::PoseKey, Eigen::Matrix3d>& neighbours,
      const std::vector<Eigen::Matrix3d>& values) const;

 private:
  Layout layout_;
  Eigen::MatrixXd b_held_;  ///< right-hand side from held own nodes, 3 unknowns x 3
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> llt_;
};

/// Stage-2 values of the own nodes: T = (exp(delta) R_hat, t).
struct PoseValues {
  std::vector<Eigen::Matrix3d> R_hat;  ///< stage-1 rotations, projected
  std::vector<Eigen::Vector3d> delta;  ///< rotation corrections (world frame)
  std::vector<Eigen::Vector3d> t;      ///< translations

  [[nodiscard]] Eigen::Matrix3d rotation(int i) const;
  [[nodiscard]] Eigen::Isometry3d pose(int i) const;
};

/// Stage 2: rotation corrections, then translations, linearised at R_hat.
class PoseProblem {
 public:
  /// Assembles and factors the two Laplacians; `values` gives the held nodes'.
  bool configure(const Block& block, const Layout& layout, const std::vector<bool>& active,
                 const PoseValues& values);
  /// One step: solves the corrections, relaxes them into `values` (gamma;
  /// `first`: take the solution), then the translations with the corrected
  /// rotations, relaxed likewise. `neighbours` holds every active separator's
  /// node; `linearisation` the neighbours' stage-1 rotations R^ where known
  /// (else a separator is linearised at the neighbour's full rotation).
  void step(const Block& block, const std::vector<bool>& active,
            const std::map<core::PoseKey, Eigen::Isometry3d>& neighbours,
            const std::map<core::PoseKey, Eigen::Matrix3d>& linearisation, double gamma, bool first,
            PoseValues& values) const;

 private:
  [[nodiscard]] Eigen::MatrixXd correctionRhs(
      const Block& block, const std::vector<bool>& active,
      const std::map<core::PoseKey, Eigen::Isometry3d>& neighbours,
      const std::map<core::PoseKey, Eigen::Matrix3d>& linearisation,
      const PoseValues& values) const;
  [[nodiscard]] Eigen::MatrixXd translationRhs(
      const Block& block, const std::vector<bool>& active,
      const std::map<core::PoseKey, Eigen::Isometry3d>& neighbours, const PoseValues& values) const;

  Layout layout_;
  Eigen::MatrixXd b_rotation_held_;  ///< constant part of the corrections' right-hand side
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> rotation_llt_;
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> translation_llt_;
};

/// x + gamma (solved - x), or `solved` on a block's first solve.
template <class T>
T relax(const T& x, const T& solved, double gamma, bool first) {
  if (first) return solved;
  return x + gamma * (solved - x);
}

/// Initial estimates of `keys` from `graph`: its estimate where the graph holds
/// the node, else composed from a known own node through the factors among
/// `keys` (breadth first), else the identity.
std::vector<Eigen::Isometry3d> initialEstimates(const std::vector<core::PoseKey>& keys,
                                                const PoseGraph& graph);

}  // namespace dcl::backend::dgs
