#pragma once

/// Maximum cliques of undirected graphs, for PCM (paper §III-C): the largest
/// set of pairwise consistent loop closures is the maximum clique of the
/// consistency graph (Mangelson et al. 2018).
///
/// The exact search is a branch and bound with greedy-colouring bounds
/// (Tomita's MCQ/MCS family, on bit sets as San Segundo's BBMC), seeded by a
/// heuristic clique and restricted to the k-core that can still beat it. Its
/// answer does not depend on how the search went: among the maximum cliques it
/// returns the one whose increasing vertex list is lexicographically smallest.
/// Two robots that build the same graph in the same vertex order therefore
/// accept the same loops, whatever order the loops reached them in. Past a
/// size or search-node limit, a heuristic (greedy by degree, then (1,2)-swap
/// local search) answers instead; it is deterministic too.

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace dcl::backend {

/// An undirected graph without self-loops, stored as one adjacency bit row per
/// vertex (n^2 / 8 bytes: 31 kB for 500 vertices), so that the clique search
/// intersects candidate sets 64 vertices at a time.
class AdjacencyGraph {
 public:
  /// A graph of `vertices` isolated vertices.
  explicit AdjacencyGraph(std::size_t vertices = 0);

  /// Appends an isolated vertex and returns its index (amortised O(n)).
  std::size_t addVertex();

  /// Joins `i` and `j` (no effect when i == j).
  void addEdge(std::size_t i, std::size_t j);

  /// True when `i` and `j` are joined.
  [[nodiscard]] bool adjacent(std::size_t i, std::size_t j) const {
    return ((row(i)[j / 64] >> (j % 64)) & 1U) != 0;
  }

  /// The number of neighbours of `i`.
  [[nodiscard]] std::size_t degree(std::size_t i) const;

  /// The number of vertices.
  [[nodiscard]] std::size_t size() const { return size_; }

  /// The graph with vertices renumbered: vertex k of the result is `order[k]` of
  /// this one (`order` lists distinct vertices; others are left out).
  [[nodiscard]] AdjacencyGraph permuted(std::span<const std::size_t> order) const;

  /// 64-bit words per row (the bits of vertex j are word j / 64, bit j % 64).
  [[nodiscard]] std::size_t words() const { return words_; }

  /// The adjacency bits of vertex `i`, `words()` long.
  [[nodiscard]] const std::uint64_t* row(std::size_t i) const { return bits_.data() + i * words_; }

 private:
  std::size_t size_ = 0;
  std::size_t words_ = 0;
  std::vector<std::uint64_t> bits_;
};

/// How hard the exact search may try.
struct MaxCliqueConfig {
  /// Graphs with more vertices go to the heuristic directly.
  std::size_t max_exact_vertices = 5000;
  /// Branch-and-bound nodes (over both exact phases) before giving up on the
  /// exact answer; a count, not a time, so that the outcome is the same on
  /// every machine.
  std::size_t max_branch_nodes = 2'000'000;
};

/// A clique and how it was found.
struct CliqueResult {
  std::vector<std::size_t> vertices;  ///< in increasing order
  /// The lexicographically smallest maximum clique. False: the heuristic's
  /// clique, or (node budget spent between the two phases) a maximum clique
  /// not shown to be the smallest.
  bool exact = false;
  std::size_t branch_nodes = 0;  ///< search nodes used by the exact phases
};

/// The maximum clique of `graph` (see the file comment for which one). Phase
/// one finds the maximum size (colour-bounded branch and bound from the
/// heuristic clique), phase two the smallest clique of that size (depth first
/// in vertex order, stopping at the first). Past `config`'s limits, the
/// heuristic clique.
CliqueResult maximumClique(const AdjacencyGraph& graph, const MaxCliqueConfig& config = {});

/// A large clique, fast: greedy growth (always the candidate with the most
/// candidate neighbours) from the vertices of highest core number, then
/// (1,2)-swaps while one enlarges it. Increasing order; deterministic.
std::vector<std::size_t> heuristicClique(const AdjacencyGraph& graph);

/// The core number of every vertex: the largest k such that the vertex is in a
/// subgraph whose vertices all have degree k or more. A clique of size s lies
/// in the (s-1)-core.
std::vector<std::size_t> coreNumbers(const AdjacencyGraph& graph);

/// True when the vertices are distinct and pairwise adjacent.
bool isClique(const AdjacencyGraph& graph, std::span<const std::size_t> vertices);

}  // namespace dcl::backend
