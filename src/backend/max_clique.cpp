#include <algorithm>
#include <bit>
#include <numeric>

#include <dcl/backend/max_clique.hpp>

namespace dcl::backend {
namespace {

using Word = std::uint64_t;
using Bits = std::vector<Word>;

constexpr std::size_t kBitsPerWord = 64;
/// Start vertices the heuristic grows a clique from (those of highest core number).
constexpr std::size_t kHeuristicStarts = 32;

std::size_t wordsFor(std::size_t n) {
  return (n + kBitsPerWord - 1) / kBitsPerWord;
}

void setBit(Bits& b, std::size_t i) {
  b[i / kBitsPerWord] |= Word{1} << (i % kBitsPerWord);
}

void resetBit(Bits& b, std::size_t i) {
  b[i / kBitsPerWord] &= ~(Word{1} << (i % kBitsPerWord));
}

bool testBit(const Bits& b, std::size_t i) {
  return ((b[i / kBitsPerWord] >> (i % kBitsPerWord)) & 1U) != 0;
}

std::size_t countBits(const Bits& b) {
  std::size_t n = 0;
  for (Word w : b) n += static_cast<std::size_t>(std::popcount(w));
  return n;
}

bool anyBit(const Bits& b) {
  return std::any_of(b.begin(), b.end(), [](Word w) { return w != 0; });
}

/// |a & row|, the members of `a` adjacent to the row's vertex.
std::size_t countAnd(const Bits& a, const Word* row) {
  std::size_t n = 0;
  for (std::size_t k = 0; k < a.size(); ++k)
    n += static_cast<std::size_t>(std::popcount(a[k] & row[k]));
  return n;
}

void andRow(Bits& a, const Word* row) {
  for (std::size_t k = 0; k < a.size(); ++k) a[k] &= row[k];
}

void andNotRow(Bits& a, const Word* row) {
  for (std::size_t k = 0; k < a.size(); ++k) a[k] &= ~row[k];
}

/// Calls f(i) for every set bit, in increasing order.
template <class F>
void forEachBit(const Bits& b, F&& f) {
  for (std::size_t k = 0; k < b.size(); ++k) {
    for (Word w = b[k]; w != 0; w &= w - 1) {
      f(k * kBitsPerWord + static_cast<std::size_t>(std::countr_zero(w)));
    }
  }
}

/// The lowest set bit (the caller knows there is one).
std::size_t lowestBit(const Bits& b) {
  std::size_t k = 0;
  while (b[k] == 0) ++k;
  return k * kBitsPerWord + static_cast<std::size_t>(std::countr_zero(b[k]));
}

/// The highest set bit (the caller knows there is one).
std::size_t highestBit(const Bits& b) {
  std::size_t k = b.size() - 1;
  while (b[k] == 0) --k;
  return k * kBitsPerWord + (kBitsPerWord - 1 - static_cast<std::size_t>(std::countl_zero(b[k])));
}

Bits rowBits(const AdjacencyGraph& g, std::size_t i) {
  return Bits(g.row(i), g.row(i) + g.words());
}

/// Vertices by decreasing core number, then decreasing degree, then index.
std::vector<std::size_t> coreOrder(const AdjacencyGraph& g, const std::vector<std::size_t>& core) {
  std::vector<std::size_t> order(g.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::vector<std::size_t> degree(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) degree[i] = g.degree(i);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (core[a] != core[b]) return core[a] > core[b];
    if (degree[a] != degree[b]) return degree[a] > degree[b];
    return a < b;
  });
  return order;
}

/// Greedy growth from `start`: always the candidate adjacent to most other
/// candidates (lowest index on ties); candidate counts kept up to date as
/// candidates drop out, so one growth costs O(n^2 / 64 + edges).
std::vector<std::size_t> growClique(const AdjacencyGraph& g, std::size_t start,
                                    std::vector<std::size_t>& count) {
  std::vector<std::size_t> clique{start};
  Bits candidates = rowBits(g, start);
  forEachBit(candidates, [&](std::size_t u) { count[u] = countAnd(candidates, g.row(u)); });
  Bits next(candidates.size());
  while (anyBit(candidates)) {
    std::size_t pick = 0, most = 0;
    bool first = true;
    forEachBit(candidates, [&](std::size_t u) {
      if (first || count[u] > most) pick = u, most = count[u], first = false;
    });
    clique.push_back(pick);
    next = candidates;
    andRow(next, g.row(pick));
    Bits dropped = candidates;
    andNotRow(dropped, g.row(pick));  // includes `pick` itself
    forEachBit(dropped, [&](std::size_t r) {
      const Word* row = g.row(r);
      for (std::size_t k = 0; k < next.size(); ++k) {
        for (Word w = next[k] & row[k]; w != 0; w &= w - 1) {
          --count[k * kBitsPerWord + static_cast<std::size_t>(std::countr_zero(w))];
        }
      }
    });
    candidates.swap(next);
  }
  return clique;
}

/// One improvement of `clique`: a vertex adjacent to all of it, else a (1,2)-swap
/// (one member out, two adjacent vertices that miss only that member in).
bool improveOnce(const AdjacencyGraph& g, std::vector<std::size_t>& clique) {
  Bits members(g.words());
  for (std::size_t v : clique) setBit(members, v);
  std::vector<std::vector<std::size_t>> missing_only(g.size());
  for (std::size_t u = 0; u < g.size(); ++u) {
    if (testBit(members, u)) continue;
    const std::size_t missed = clique.size() - countAnd(members, g.row(u));
    if (missed == 0) {
      clique.push_back(u);
      return true;
    }
    if (missed != 1) continue;
    Bits outside = members;
    andNotRow(outside, g.row(u));
    missing_only[lowestBit(outside)].push_back(u);
  }
  for (std::size_t x = 0; x < g.size(); ++x) {
    const auto& tight = missing_only[x];
    for (std::size_t a = 0; a < tight.size(); ++a) {
      for (std::size_t b = a + 1; b < tight.size(); ++b) {
        if (!g.adjacent(tight[a], tight[b])) continue;
        std::erase(clique, x);
        clique.push_back(tight[a]);
        clique.push_back(tight[b]);
        return true;
      }
    }
  }
  return false;
}

/// The exact search state shared by both phases: the node budget.
struct Budget {
  std::size_t used = 0;
  std::size_t limit = 0;
  bool exhausted = false;

  bool spend() {
    if (++used > limit) exhausted = true;
    return !exhausted;
  }
};

/// Phase 1: MCQ/BBMC branch and bound for any clique larger than `best`
/// (which starts as the heuristic clique). Vertices are coloured greedily,
/// classes built lowest index first; vertices whose colour cannot lift the
/// current clique past `best` are never branched on.
class LargestCliqueSearch {
 public:
  /// Looks for cliques of more than `floor` vertices.
  LargestCliqueSearch(const AdjacencyGraph& g, Budget& budget, std::size_t floor)
      : g_(g), budget_(budget), bound_(floor) {}

  /// The largest clique found, empty when none beats the floor.
  std::vector<std::size_t> run() {
    Bits all(g_.words());
    for (std::size_t v = 0; v < g_.size(); ++v) setBit(all, v);
    if (g_.size() > bound_) expand(all);
    return best_;
  }

 private:
  void expand(Bits& candidates) {
    if (!budget_.spend()) return;
    std::vector<std::size_t> order, colour;
    colourCandidates(candidates, order, colour);
    for (std::size_t i = order.size(); i-- > 0;) {
      if (current_.size() + colour[i] <= bound_) return;
      const std::size_t v = order[i];
      current_.push_back(v);
      Bits next = candidates;
      andRow(next, g_.row(v));
      if (!anyBit(next)) {
        if (current_.size() > bound_) best_ = current_, bound_ = current_.size();
      } else {
        expand(next);
        if (budget_.exhausted) return;
      }
      current_.pop_back();
      resetBit(candidates, v);
    }
  }

  /// The candidates worth branching on, by non-decreasing colour, with their colours.
  void colourCandidates(const Bits& candidates, std::vector<std::size_t>& order,
                        std::vector<std::size_t>& colour) const {
    const std::size_t useless = bound_ >= current_.size() ? bound_ - current_.size() : 0;
    Bits uncoloured = candidates;
    Bits available(candidates.size());
    for (std::size_t k = 1; anyBit(uncoloured); ++k) {
      available = uncoloured;
      while (anyBit(available)) {
        const std::size_t v = lowestBit(available);
        resetBit(available, v);
        resetBit(uncoloured, v);
        andNotRow(available, g_.row(v));
        if (k > useless) order.push_back(v), colour.push_back(k);
      }
    }
  }

  const AdjacencyGraph& g_;
  Budget& budget_;
  std::size_t bound_;  ///< size of the largest clique known (the floor at first)
  std::vector<std::size_t> best_;
  std::vector<std::size_t> current_;
};

/// Phase 2: the lexicographically smallest clique of the known maximum size
/// `target`. Depth-first in increasing vertex order, so cliques are met in
/// lexicographic order; a branch is cut only when it cannot reach `target`,
/// so the first clique of that size found is the smallest. The bound colours
/// the candidates highest index first: first-fit colours of a suffix of the
/// candidates then depend on that suffix alone, and their maximum bounds it.
class SmallestCliqueSearch {
 public:
  SmallestCliqueSearch(const AdjacencyGraph& g, Budget& budget, std::size_t target)
      : g_(g), budget_(budget), target_(target) {}

  std::vector<std::size_t> run(Bits candidates) {
    if (target_ == 0 || !search(candidates)) return {};
    return current_;
  }

 private:
  bool search(Bits& candidates) {
    if (current_.size() == target_) return true;
    if (!budget_.spend()) return false;
    std::vector<std::size_t> order, suffix_colours;
    suffixColours(candidates, order, suffix_colours);
    for (std::size_t i = 0; i < order.size(); ++i) {
      if (current_.size() + suffix_colours[i] < target_) return false;
      const std::size_t v = order[i];
      resetBit(candidates, v);
      Bits next = candidates;
      andRow(next, g_.row(v));
      current_.push_back(v);
      if (current_.size() + countBits(next) >= target_ && search(next)) return true;
      if (budget_.exhausted) return false;
      current_.pop_back();
    }
    return false;
  }

  /// The candidates in increasing order and, for each, the colours needed by it
  /// and the candidates after it.
  void suffixColours(const Bits& candidates, std::vector<std::size_t>& order,
                     std::vector<std::size_t>& suffix) const {
    Bits uncoloured = candidates;
    Bits available(candidates.size());
    std::vector<std::pair<std::size_t, std::size_t>> coloured;  // (vertex, colour)
    for (std::size_t k = 1; anyBit(uncoloured); ++k) {
      available = uncoloured;
      while (anyBit(available)) {
        const std::size_t v = highestBit(available);
        resetBit(available, v);
        resetBit(uncoloured, v);
        andNotRow(available, g_.row(v));
        coloured.emplace_back(v, k);
      }
    }
    std::sort(coloured.begin(), coloured.end());
    order.resize(coloured.size());
    suffix.resize(coloured.size());
    std::size_t most = 0;
    for (std::size_t i = coloured.size(); i-- > 0;) {
      most = std::max(most, coloured[i].second);
      order[i] = coloured[i].first;
      suffix[i] = most;
    }
  }

  const AdjacencyGraph& g_;
  Budget& budget_;
  std::size_t target_;
  std::vector<std::size_t> current_;
};

/// Phase 1 on the vertices that can beat `seed` (core number at least its
/// size), renumbered by decreasing core number so that colouring goes well.
std::vector<std::size_t> largestClique(const AdjacencyGraph& g,
                                       const std::vector<std::size_t>& core,
                                       const std::vector<std::size_t>& seed, Budget& budget) {
  std::vector<std::size_t> order;
  for (std::size_t v : coreOrder(g, core)) {
    if (core[v] >= seed.size()) order.push_back(v);
  }
  if (order.size() <= seed.size()) return seed;
  const AdjacencyGraph sub = g.permuted(order);
  std::vector<std::size_t> best = LargestCliqueSearch(sub, budget, seed.size()).run();
  if (best.empty()) return seed;
  for (std::size_t& v : best) v = order[v];
  std::sort(best.begin(), best.end());
  return best;
}

}  // namespace

AdjacencyGraph::AdjacencyGraph(std::size_t vertices)
    : size_(vertices), words_(wordsFor(vertices)), bits_(vertices * words_, 0) {}

std::size_t AdjacencyGraph::addVertex() {
  if (size_ == words_ * kBitsPerWord) {
    const std::size_t words = std::max<std::size_t>(1, 2 * words_);
    std::vector<Word> bits(size_ * words, 0);
    for (std::size_t i = 0; i < size_; ++i) {
      std::copy(row(i), row(i) + words_, bits.begin() + static_cast<std::ptrdiff_t>(i * words));
    }
    bits_.swap(bits);
    words_ = words;
  }
  bits_.resize(bits_.size() + words_, 0);
  return size_++;
}

void AdjacencyGraph::addEdge(std::size_t i, std::size_t j) {
  if (i == j) return;
  bits_[i * words_ + j / kBitsPerWord] |= Word{1} << (j % kBitsPerWord);
  bits_[j * words_ + i / kBitsPerWord] |= Word{1} << (i % kBitsPerWord);
}

std::size_t AdjacencyGraph::degree(std::size_t i) const {
  std::size_t n = 0;
  for (std::size_t k = 0; k < words_; ++k) n += static_cast<std::size_t>(std::popcount(row(i)[k]));
  return n;
}

AdjacencyGraph AdjacencyGraph::permuted(std::span<const std::size_t> order) const {
  AdjacencyGraph g(order.size());
  for (std::size_t a = 0; a < order.size(); ++a) {
    for (std::size_t b = a + 1; b < order.size(); ++b) {
      if (adjacent(order[a], order[b])) g.addEdge(a, b);
    }
  }
  return g;
}

std::vector<std::size_t> coreNumbers(const AdjacencyGraph& graph) {
  // Batagelj and Zaversnik's O(edges) peeling: vertices bucketed by current degree.
  const std::size_t n = graph.size();
  std::vector<std::vector<std::size_t>> neighbours(n);
  std::vector<std::size_t> degree(n);
  for (std::size_t v = 0; v < n; ++v) {
    forEachBit(rowBits(graph, v), [&](std::size_t u) { neighbours[v].push_back(u); });
    degree[v] = neighbours[v].size();
  }
  const std::size_t max_degree = n == 0 ? 0 : *std::max_element(degree.begin(), degree.end());
  std::vector<std::size_t> bin_start(max_degree + 2, 0);
  for (std::size_t d : degree) ++bin_start[d + 1];
  std::partial_sum(bin_start.begin(), bin_start.end(), bin_start.begin());
  std::vector<std::size_t> position(n), sorted(n);
  std::vector<std::size_t> next_slot(bin_start.begin(), bin_start.end() - 1);
  for (std::size_t v = 0; v < n; ++v) {
    position[v] = next_slot[degree[v]]++;
    sorted[position[v]] = v;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t v = sorted[i];
    for (std::size_t u : neighbours[v]) {
      if (degree[u] <= degree[v]) continue;
      // Move u to the front of its bin, then shrink its degree by one.
      const std::size_t du = degree[u];
      const std::size_t front = bin_start[du];
      const std::size_t w = sorted[front];
      if (w != u) {
        std::swap(sorted[position[u]], sorted[front]);
        std::swap(position[u], position[w]);
      }
      ++bin_start[du];
      --degree[u];
    }
  }
  return degree;
}

std::vector<std::size_t> heuristicClique(const AdjacencyGraph& graph) {
  if (graph.size() == 0) return {};
  const std::vector<std::size_t> core = coreNumbers(graph);
  const std::vector<std::size_t> order = coreOrder(graph, core);
  std::vector<std::size_t> best;
  std::vector<std::size_t> count(graph.size(), 0);
  const std::size_t starts = std::min(graph.size(), kHeuristicStarts);
  for (std::size_t s = 0; s < starts; ++s) {
    if (core[order[s]] + 1 <= best.size()) continue;  // no clique through it can be larger
    std::vector<std::size_t> clique = growClique(graph, order[s], count);
    if (clique.size() > best.size()) best = std::move(clique);
  }
  while (improveOnce(graph, best)) {
  }
  std::sort(best.begin(), best.end());
  return best;
}

CliqueResult maximumClique(const AdjacencyGraph& graph, const MaxCliqueConfig& config) {
  CliqueResult result;
  if (graph.size() == 0) {
    result.exact = true;
    return result;
  }
  const std::vector<std::size_t> heuristic = heuristicClique(graph);
  result.vertices = heuristic;
  if (graph.size() > config.max_exact_vertices) return result;
  Budget budget{.limit = config.max_branch_nodes};
  const std::vector<std::size_t> core = coreNumbers(graph);
  const std::vector<std::size_t> largest = largestClique(graph, core, heuristic, budget);
  result.branch_nodes = budget.used;
  if (budget.exhausted) return result;
  // Phase 2 among the vertices that can be in a clique of that size.
  Bits candidates(graph.words());
  for (std::size_t v = 0; v < graph.size(); ++v) {
    if (core[v] + 1 >= largest.size()) setBit(candidates, v);
  }
  std::vector<std::size_t> smallest =
      SmallestCliqueSearch(graph, budget, largest.size()).run(candidates);
  result.branch_nodes = budget.used;
  if (budget.exhausted || smallest.empty()) {
    result.vertices = largest;  // maximum, but not shown to be the canonical one
    return result;
  }
  result.vertices = std::move(smallest);
  result.exact = true;
  return result;
}

bool isClique(const AdjacencyGraph& graph, std::span<const std::size_t> vertices) {
  for (std::size_t a = 0; a < vertices.size(); ++a) {
    if (vertices[a] >= graph.size()) return false;
    for (std::size_t b = a + 1; b < vertices.size(); ++b) {
      if (!graph.adjacent(vertices[a], vertices[b])) return false;
    }
  }
  return true;
}

}  // namespace dcl::backend
