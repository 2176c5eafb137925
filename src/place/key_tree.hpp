#pragma once

/// The k-d tree over the fixed-length keys of a PlaceIndex (row keys, paper
/// Eq. 5, or Scan Context's ring keys), kept incremental as keyframes arrive.
///
/// nanoflann 1.4's dynamic adaptor keeps a logarithmic set of static trees
/// (tree i holds 2^i points; an insertion merges the full ones below the first
/// free slot and rebuilds only that tree), so n insertions cost O(n log^2 n) in
/// all and a query visits at most log2(n) + 1 trees: no full rebuild a query.

#include <cstddef>
#include <limits>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include <nanoflann.hpp>

namespace dcl::place::detail {

/// The keys, row-major, as nanoflann's dataset adaptor.
struct KeyMatrix {
  std::size_t dim = 0;
  std::vector<float> values;  ///< key i is values[i * dim, (i + 1) * dim)

  [[nodiscard]] std::size_t kdtree_get_point_count() const { return dim ? values.size() / dim : 0; }
  [[nodiscard]] float kdtree_get_pt(std::size_t i, std::size_t d) const {
    return values[i * dim + d];
  }
  template <class Box>
  bool kdtree_get_bbox(Box& /*box*/) const {
    return false;
  }
};

/// k nearest results that ignore every key at or past `limit` (the most recent
/// own keyframes of an intra-robot query) while the trees are searched, so that
/// the k results are all eligible.
class LimitedKnn {
 public:
  using DistanceType = float;
  using IndexType = std::size_t;

  LimitedKnn(std::size_t k, std::size_t limit) : inner_(k), limit_(limit) {
    indices_.resize(k);
    dists_.resize(k);
    inner_.init(indices_.data(), dists_.data());
  }
  bool addPoint(float dist, std::size_t index) {
    return index >= limit_ || inner_.addPoint(dist, index);
  }
  [[nodiscard]] float worstDist() const { return inner_.worstDist(); }
  [[nodiscard]] bool full() const { return inner_.full(); }

  /// (key index, squared L2 distance), nearest first.
  [[nodiscard]] std::vector<std::pair<std::size_t, float>> results() const {
    std::vector<std::pair<std::size_t, float>> out;
    for (std::size_t i = 0; i < inner_.size(); ++i) out.emplace_back(indices_[i], dists_[i]);
    return out;
  }

 private:
  nanoflann::KNNResultSet<float, std::size_t> inner_;
  std::vector<std::size_t> indices_;
  std::vector<float> dists_;
  std::size_t limit_;
};

/// Incremental k-d tree over keys of one fixed length.
class KeyTree {
 public:
  /// Appends `key` (its length fixes the tree's on the first call) and indexes it.
  void add(std::span<const float> key) {
    if (!tree_) {
      keys_->dim = key.size();
      keys_->values.assign(key.begin(), key.end());
      tree_ = std::make_unique<Tree>(static_cast<int>(keys_->dim), *keys_,
                                     nanoflann::KDTreeSingleIndexAdaptorParams(10));
      return;
    }
    keys_->values.insert(keys_->values.end(), key.begin(), key.end());
    const std::size_t last = size() - 1;
    tree_->addPoints(last, last);
  }

  /// The `k` keys nearest `query` among keys [0, limit), nearest first.
  [[nodiscard]] std::vector<std::pair<std::size_t, float>> nearest(std::span<const float> query,
                                                                   std::size_t k,
                                                                   std::size_t limit) const {
    if (!tree_ || k == 0 || limit == 0 || query.size() != keys_->dim) return {};
    LimitedKnn result(k, limit);
    tree_->findNeighbors(result, query.data(), nanoflann::SearchParams());
    return result.results();
  }

  [[nodiscard]] std::size_t size() const { return keys_->kdtree_get_point_count(); }
  [[nodiscard]] std::size_t dim() const { return keys_->dim; }

 private:
  using Tree = nanoflann::KDTreeSingleIndexDynamicAdaptor<
      nanoflann::L2_Simple_Adaptor<float, KeyMatrix, float>, KeyMatrix, -1, std::size_t>;
  // On the heap: the tree keeps a reference to the keys, which must not move.
  std::unique_ptr<KeyMatrix> keys_ = std::make_unique<KeyMatrix>();
  std::unique_ptr<Tree> tree_;
};

}  // namespace dcl::place::detail
