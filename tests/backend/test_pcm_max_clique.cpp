#include <algorithm>
#include <bit>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/max_clique.hpp>

namespace dcl::backend {
namespace {

/// G(n, p) with a fixed seed.
AdjacencyGraph randomGraph(std::size_t n, double p, unsigned seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution edge(p);
  AdjacencyGraph g(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      if (edge(rng)) g.addEdge(i, j);
    }
  }
  return g;
}

/// `g` with the vertices of `members` joined pairwise.
void plantClique(AdjacencyGraph& g, const std::vector<std::size_t>& members) {
  for (std::size_t a : members) {
    for (std::size_t b : members) g.addEdge(a, b);
  }
}

/// Every subset of a graph of at most 20 vertices; the maximum cliques'
/// lexicographically smallest member list.
std::vector<std::size_t> bruteForceClique(const AdjacencyGraph& g) {
  const std::size_t n = g.size();
  std::vector<std::uint32_t> neighbours(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      if (g.adjacent(i, j)) neighbours[i] |= std::uint32_t{1} << j;
    }
  }
  std::vector<bool> clique(std::size_t{1} << n, false);
  clique[0] = true;
  std::vector<std::size_t> best;
  for (std::uint32_t set = 1; set < (std::uint32_t{1} << n); ++set) {
    const int low = std::countr_zero(set);
    const std::uint32_t rest = set & (set - 1);
    clique[set] = clique[rest] && (rest & ~neighbours[low]) == 0;
    if (!clique[set]) continue;
    std::vector<std::size_t> members;
    for (std::size_t v = 0; v < n; ++v) {
      if ((set >> v) & 1U) members.push_back(v);
    }
    if (members.size() > best.size() || (members.size() == best.size() && members < best)) {
      best = members;
    }
  }
  return best;
}

TEST(MaxClique, ExactIsTheBruteForceCliqueOnRandomGraphs) {
  int graphs = 0;
  for (unsigned seed = 1; seed <= 3; ++seed) {
    for (const double density : {0.1, 0.3, 0.5, 0.7, 0.85, 0.95}) {
      for (const std::size_t n : {1, 2, 5, 9, 14, 18, 20}) {
        const AdjacencyGraph g = randomGraph(n, density, seed * 1000 + n);
        const CliqueResult r = maximumClique(g);
        ASSERT_TRUE(r.exact);
        EXPECT_EQ(r.vertices, bruteForceClique(g))
            << "n " << n << ", density " << density << ", seed " << seed;
        ++graphs;
      }
    }
  }
  EXPECT_EQ(graphs, 126);
}

TEST(MaxClique, ManyTiedCliquesGiveTheLexicographicallySmallest) {
  // Disjoint triangles {3k, 3k+1, 3k+2}: every triangle is a maximum clique.
  AdjacencyGraph g(18);
  for (std::size_t k = 0; k < 6; ++k) plantClique(g, {3 * k, 3 * k + 1, 3 * k + 2});
  g.addEdge(0, 4);  // chords do not make a larger clique
  g.addEdge(1, 7);
  EXPECT_EQ(maximumClique(g).vertices, (std::vector<std::size_t>{0, 1, 2}));
  // The answer follows the vertex numbering, not the order edges were added in.
  AdjacencyGraph h(18);
  for (std::size_t k = 6; k-- > 0;) plantClique(h, {3 * k + 2, 3 * k + 1, 3 * k});
  h.addEdge(7, 1);
  h.addEdge(4, 0);
  EXPECT_EQ(maximumClique(h).vertices, (std::vector<std::size_t>{0, 1, 2}));
}

TEST(MaxClique, RecoversAPlantedCliqueInALargeGraph) {
  for (unsigned seed = 1; seed <= 3; ++seed) {
    AdjacencyGraph g = randomGraph(400, 0.3, seed);
    std::vector<std::size_t> planted;
    std::mt19937 rng(seed);
    std::vector<std::size_t> all(400);
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
    std::shuffle(all.begin(), all.end(), rng);
    planted.assign(all.begin(), all.begin() + 60);
    std::sort(planted.begin(), planted.end());
    plantClique(g, planted);
    const CliqueResult r = maximumClique(g);
    EXPECT_TRUE(r.exact);
    EXPECT_EQ(r.vertices, planted);
  }
}

TEST(MaxClique, DenseGraphsLikeConsistentLoopsAreSolvedExactly) {
  // 600 mutually consistent loops, 100 outliers each consistent with most of
  // them and with each other in groups of ten: the shape of a real PCM graph.
  AdjacencyGraph g(700);
  std::vector<std::size_t> inliers(600);
  for (std::size_t i = 0; i < 600; ++i) inliers[i] = i;
  plantClique(g, inliers);
  std::mt19937 rng(5);
  std::bernoulli_distribution agree(0.85);
  for (std::size_t o = 600; o < 700; ++o) {
    for (std::size_t i = 0; i < 600; ++i) {
      if (agree(rng)) g.addEdge(o, i);
    }
    for (std::size_t p = 600 + (o - 600) / 10 * 10; p < o; ++p) g.addEdge(o, p);
  }
  const CliqueResult r = maximumClique(g);
  EXPECT_TRUE(r.exact);
  EXPECT_EQ(r.vertices, inliers);
}

TEST(MaxClique, HeuristicGivesAValidCliqueCloseToTheMaximum) {
  for (unsigned seed = 1; seed <= 4; ++seed) {
    for (const double density : {0.2, 0.5, 0.8}) {
      const AdjacencyGraph g = randomGraph(100, density, seed);
      const std::vector<std::size_t> h = heuristicClique(g);
      EXPECT_TRUE(isClique(g, h));
      EXPECT_TRUE(std::is_sorted(h.begin(), h.end()));
      const CliqueResult exact = maximumClique(g);
      ASSERT_TRUE(exact.exact);
      EXPECT_LE(h.size(), exact.vertices.size());
      EXPECT_GE(h.size() + 2, exact.vertices.size()) << "density " << density << ", seed " << seed;
    }
  }
}

TEST(MaxClique, FallsBackToTheHeuristicPastItsLimits) {
  const AdjacencyGraph g = randomGraph(120, 0.6, 9);
  const std::vector<std::size_t> h = heuristicClique(g);
  const CliqueResult by_nodes = maximumClique(g, {.max_branch_nodes = 3});
  EXPECT_FALSE(by_nodes.exact);
  EXPECT_EQ(by_nodes.vertices, h);
  const CliqueResult by_size = maximumClique(g, {.max_exact_vertices = 100});
  EXPECT_FALSE(by_size.exact);
  EXPECT_EQ(by_size.vertices, h);
  const CliqueResult exact = maximumClique(g);
  EXPECT_TRUE(exact.exact);
  EXPECT_GT(exact.branch_nodes, 3U);
}

TEST(MaxClique, CoreNumbersMatchRepeatedPeeling) {
  const AdjacencyGraph g = randomGraph(80, 0.15, 4);
  const std::vector<std::size_t> core = coreNumbers(g);
  // The k-core by definition: drop vertices of degree below k until none is left.
  for (std::size_t k = 0; k <= 12; ++k) {
    std::vector<bool> alive(g.size(), true);
    for (bool changed = true; changed;) {
      changed = false;
      for (std::size_t v = 0; v < g.size(); ++v) {
        if (!alive[v]) continue;
        std::size_t degree = 0;
        for (std::size_t u = 0; u < g.size(); ++u) degree += alive[u] && g.adjacent(u, v);
        if (degree < k) alive[v] = false, changed = true;
      }
    }
    for (std::size_t v = 0; v < g.size(); ++v) EXPECT_EQ(alive[v], core[v] >= k) << v;
  }
}

TEST(MaxClique, GrowingAndPermutingKeepTheEdges) {
  AdjacencyGraph g;
  for (std::size_t i = 0; i < 200; ++i) EXPECT_EQ(g.addVertex(), i);
  for (std::size_t i = 0; i + 1 < 200; i += 3) g.addEdge(i, i + 1);
  g.addEdge(5, 5);  // no self-loops
  EXPECT_FALSE(g.adjacent(5, 5));
  const AdjacencyGraph fixed = [] {
    AdjacencyGraph f(200);
    for (std::size_t i = 0; i + 1 < 200; i += 3) f.addEdge(i, i + 1);
    return f;
  }();
  for (std::size_t i = 0; i < 200; ++i) {
    EXPECT_EQ(g.degree(i), fixed.degree(i));
    for (std::size_t j = 0; j < 200; ++j) ASSERT_EQ(g.adjacent(i, j), fixed.adjacent(i, j));
  }
  const std::vector<std::size_t> order = {4, 3, 0, 1};
  const AdjacencyGraph p = g.permuted(order);
  EXPECT_EQ(p.size(), 4U);
  EXPECT_TRUE(p.adjacent(1, 0));   // 3-4
  EXPECT_TRUE(p.adjacent(2, 3));   // 0-1
  EXPECT_FALSE(p.adjacent(0, 2));  // 4-0
}

}  // namespace
}  // namespace dcl::backend
