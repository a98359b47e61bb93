// The cut against its definition taken literally: one refinement per step, the open node
// with the most samples first (ties: the lower node index), children counted by a scan,
// straight from the tree's arrays. chooseCut takes shortcuts (the leaves directly when there
// are no more surfels than the budget, one integer key per open node, a heap, split
// positions by binary search, the final order through a table); the nodes, counts and
// sample ranges must be these all the same.
#include "core/links/cut.h"

#include <algorithm>
#include <random>
#include <tuple>

#include <gtest/gtest.h>

#include "core/surfels/surfels.h"
#include "tests/common/scene_builders.h"

namespace lightlink::links {
namespace {

std::vector<CutEntry> literalCut(const hierarchy::Tree& t, const std::vector<Sample>& samples, std::size_t max_links) {
  struct Open {
    std::uint32_t count, node, first;
  };
  std::vector<Open> open{{static_cast<std::uint32_t>(samples.size()), 0, 0}};
  std::vector<CutEntry> cut;
  auto samplesIn = [&](std::uint32_t node, std::uint32_t first, std::uint32_t count) {
    std::uint32_t n = 0;
    for (std::uint32_t k = first; k < first + count; ++k) {
      const std::uint32_t s = surfelOf(samples[k]);
      n += (s >= t.begin[node] && s < t.end[node]) ? 1 : 0;
    }
    return n;
  };
  while (!open.empty()) {
    const auto best = std::max_element(open.begin(), open.end(), [](const Open& a, const Open& b) {
      return std::make_tuple(a.count, -std::int64_t(a.node)) < std::make_tuple(b.count, -std::int64_t(b.node));
    });
    const Open o = *best;
    if (t.isLeaf(o.node)) {
      cut.push_back({o.count, o.node, o.first});
      open.erase(best);
      continue;
    }
    const auto l = static_cast<std::uint32_t>(t.left[o.node]), r = static_cast<std::uint32_t>(t.right[o.node]);
    const std::uint32_t cl = samplesIn(l, o.first, o.count), cr = o.count - cl;
    EXPECT_EQ(cr, samplesIn(r, o.first + cl, cr));
    if (cl > 0 && cr > 0) {
      if (open.size() + cut.size() + 1 > max_links) break;
      *best = {cl, l, o.first};
      open.push_back({cr, r, o.first + cl});
    } else {
      *best = cl > 0 ? Open{cl, l, o.first} : Open{cr, r, o.first};
    }
  }
  for (const Open& o : open) cut.push_back({o.count, o.node, o.first});
  std::sort(cut.begin(), cut.end(), [](const CutEntry& a, const CutEntry& b) { return a.first < b.first; });
  return cut;
}

// Samples as a cache's hits give them: a few clusters of nearby surfels (tree neighbours, so
// many one-sided nodes on the way down) plus scattered ones, several hits per surfel.
std::vector<Sample> hitSamples(std::uint32_t surfels, std::uint32_t clusters, std::uint32_t scattered,
                               std::mt19937& rng) {
  std::vector<Sample> out;
  std::uint32_t ray = 0;
  for (std::uint32_t c = 0; c < clusters; ++c) {
    const std::uint32_t centre = rng() % surfels, width = 1 + rng() % 40, hits = 1 + rng() % 200;
    for (std::uint32_t h = 0; h < hits; ++h)
      out.push_back(makeSample(std::min(surfels - 1, centre + std::uint32_t(rng() % width)), ray++));
  }
  for (std::uint32_t h = 0; h < scattered; ++h) out.push_back(makeSample(rng() % surfels, ray++));
  std::sort(out.begin(), out.end());
  return out;
}

void expectLiteralCut(hierarchy::Builder builder) {
  scene::Scene s;
  lightlink::testing::addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true);
  lightlink::testing::finishScene(s);
  auto placed = surfels::placeSurfels(s, {.count = 4096});
  ASSERT_TRUE(placed) << placed.status().toString();
  auto tree = hierarchy::buildTree(*placed, {.builder = builder});
  ASSERT_TRUE(tree) << tree.status().toString();
  const CutTree cut_tree = cutTree(*tree);
  const auto n = static_cast<std::uint32_t>(placed->size());
  std::mt19937 rng(7);
  // One scratch per kernel, reused across the cases as link generation reuses it across
  // caches (the next search starts from the last one's stopping count).
  CutScratch scratch[2];
  std::vector<CutEntry> cut;
  std::size_t cases = 0, shortened = 0, within = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const std::vector<Sample> samples = hitSamples(n, 1 + rng() % 12, rng() % 300, rng);
    for (int max_links : {1, 2, 3, 8, 64, 128, 4096}) {
      const std::vector<CutEntry> want = literalCut(*tree, samples, std::size_t(max_links));
      for (const CutKernel kernel : {CutKernel::kBest, CutKernel::kScalar}) {
        const char* name = kernel == CutKernel::kBest ? "best" : "scalar";
        chooseCut(cut_tree, samples, max_links, scratch[kernel == CutKernel::kBest ? 0 : 1], cut, kernel);
        ASSERT_EQ(cut.size(), want.size()) << "trial " << trial << ", nL " << max_links << ", " << name;
        for (std::size_t k = 0; k < want.size(); ++k) {
          EXPECT_EQ(cut[k].node, want[k].node) << "trial " << trial << ", nL " << max_links << ", link " << k << ", " << name;
          EXPECT_EQ(cut[k].count, want[k].count) << "trial " << trial << ", nL " << max_links << ", link " << k << ", " << name;
          EXPECT_EQ(cut[k].first, want[k].first) << "trial " << trial << ", nL " << max_links << ", link " << k << ", " << name;
        }
      }
      ++cases;
      shortened += want.size() == std::size_t(max_links) ? 1 : 0;
      std::size_t distinct = 0;
      for (std::size_t k = 0; k < samples.size(); ++k)
        distinct += (k == 0 || surfelOf(samples[k]) != surfelOf(samples[k - 1])) ? 1 : 0;
      within += distinct <= std::size_t(max_links) ? 1 : 0;
    }
  }
  // Most cases must end at the link budget, where the order of refinements decides the
  // cut, or the test would not see what the ordering has to get right; and enough must
  // have no more surfels than the budget (the cut of one leaf per surfel, taken directly).
  EXPECT_GT(shortened, cases / 2);
  EXPECT_GT(within, cases / 10);
}

TEST(Cut, IsTheLiteralLargestFirstRefinementOnAnAgglomerativeTree) { expectLiteralCut(hierarchy::Builder::kAgglomerative); }
TEST(Cut, IsTheLiteralLargestFirstRefinementOnAKdTree) { expectLiteralCut(hierarchy::Builder::kKdMedian); }

// The search starts from the last cut's stopping count; wherever it starts (far above the
// answer: several lowering rounds; at 0: every node split), the cut is the same.
TEST(Cut, DoesNotDependOnWhereTheSearchStarts) {
  scene::Scene s;
  lightlink::testing::addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true);
  lightlink::testing::finishScene(s);
  auto placed = surfels::placeSurfels(s, {.count = 4096});
  ASSERT_TRUE(placed) << placed.status().toString();
  auto tree = hierarchy::buildTree(*placed, {.builder = hierarchy::Builder::kAgglomerative});
  ASSERT_TRUE(tree) << tree.status().toString();
  const CutTree cut_tree = cutTree(*tree);
  std::mt19937 rng(11);
  std::vector<CutEntry> fresh, warm;
  std::size_t compared = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const std::vector<Sample> samples = hitSamples(static_cast<std::uint32_t>(placed->size()), 1 + rng() % 12, 100 + rng() % 300, rng);
    for (const CutKernel kernel : {CutKernel::kBest, CutKernel::kScalar}) {
      CutScratch first_use;
      chooseCut(cut_tree, samples, 32, first_use, fresh, kernel);
      for (const std::uint32_t start : {0u, 1u, 2u, 5u, 40u, 100000u, 0xffffffffu}) {
        CutScratch scratch;
        scratch.stop_count = start;
        chooseCut(cut_tree, samples, 32, scratch, warm, kernel);
        ASSERT_EQ(warm.size(), fresh.size()) << "trial " << trial << ", start " << start;
        for (std::size_t k = 0; k < fresh.size(); ++k) {
          EXPECT_EQ(warm[k].node, fresh[k].node) << "trial " << trial << ", start " << start << ", link " << k;
          EXPECT_EQ(warm[k].first, fresh[k].first) << "trial " << trial << ", start " << start << ", link " << k;
        }
        compared += fresh.size() == 32 ? 1 : 0;
      }
    }
  }
  EXPECT_GT(compared, 200u);  // cuts that stopped at the budget, where the stopping count matters
}

TEST(Cut, NoSamplesNoLinks) {
  static constexpr std::uint32_t kLeafOfSurfel[] = {0};
  const CutTree one{{{kLeaf, 0}}, kLeafOfSurfel};
  CutScratch scratch;
  std::vector<CutEntry> cut{{1, 2, 3}};
  chooseCut(one, {}, 8, scratch, cut);
  EXPECT_TRUE(cut.empty());
}

}  // namespace
}  // namespace lightlink::links
