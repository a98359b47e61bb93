// Fill plans against their definition, written out the slow way: every layer scans every
// item, and an unreachable target takes the valid item nearest in world space by a scan of
// all of them (lowest index among equals). The plans the baker uses walk frontiers and a
// grid instead; on random atlases with chart islands, holes, isolated all-invalid charts and
// ties in distance, the two must be the same plan, target by target and source by source.
#include <algorithm>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "core/caches/caches.h"

namespace lightlink::caches {
namespace {

FillPlan slowLightmapFill(const LightmapCaches& c) {
  FillPlan plan;
  plan.source_begin.push_back(0);
  std::vector<std::uint8_t> known = c.valid, done(c.size(), 0);
  static constexpr int kOffsets[8][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}, {-1, -1}, {1, -1}, {-1, 1}, {1, 1}};
  for (;;) {
    std::vector<std::uint32_t> layer;
    for (std::uint32_t i = 0; i < c.size(); ++i) {
      if (c.valid[i] || done[i]) continue;
      std::vector<std::uint32_t> sources;
      const int x = int(c.texel[i] % std::uint32_t(c.width)), y = int(c.texel[i] / std::uint32_t(c.width));
      for (const auto& o : kOffsets) {
        const int nx = x + o[0], ny = y + o[1];
        if (nx < 0 || ny < 0 || nx >= c.width || ny >= c.height) continue;
        const std::int32_t j = c.cache_of_texel[std::size_t(ny) * c.width + nx];
        if (j >= 0 && known[std::size_t(j)]) sources.push_back(std::uint32_t(j));
      }
      if (sources.empty()) continue;
      plan.target.push_back(i);
      plan.source.insert(plan.source.end(), sources.begin(), sources.end());
      plan.source_begin.push_back(std::uint32_t(plan.source.size()));
      layer.push_back(i);
    }
    if (layer.empty()) break;
    for (std::uint32_t i : layer) known[i] = done[i] = 1;
  }
  bool any_valid = false;
  for (auto v : c.valid) any_valid |= v != 0;
  for (std::uint32_t i = 0; i < c.size() && any_valid; ++i) {
    if (c.valid[i] || done[i]) continue;
    std::uint32_t best = 0;
    float best_d = std::numeric_limits<float>::infinity();
    bool first = true;
    for (std::uint32_t j = 0; j < c.size(); ++j) {
      if (!c.valid[j]) continue;
      if (first) best = j, first = false;
      const glm::vec3 d = c.position[j] - c.position[i];
      const float d2 = glm::dot(d, d);
      if (d2 < best_d) best_d = d2, best = j;
    }
    plan.target.push_back(i);
    plan.source.push_back(best);
    plan.source_begin.push_back(std::uint32_t(plan.source.size()));
    ++plan.unreachable;
  }
  return plan;
}

// A w x h atlas of rectangular charts at random places; each chart is a patch of world
// space (some far from the others, some on a coarse lattice so distances tie), a few charts
// wholly invalid (unreachable by the flood), the rest with random holes.
LightmapCaches randomAtlas(std::uint32_t seed, int w, int h) {
  std::mt19937 rng(seed);
  LightmapCaches c;
  c.width = w, c.height = h;
  c.cache_of_texel.assign(std::size_t(w) * h, -1);
  std::uniform_int_distribution<int> size(1, 12), px(0, w - 1), py(0, h - 1), coin(0, 9);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int chart = 0; chart < 40; ++chart) {
    const int cw = size(rng), ch = size(rng), x0 = px(rng), y0 = py(rng);
    const bool dead = coin(rng) < 2, lattice = coin(rng) < 3;
    const glm::vec3 origin(10.0f * unit(rng), 10.0f * unit(rng), 10.0f * unit(rng));
    const float hole_rate = unit(rng);
    for (int y = y0; y < std::min(h, y0 + ch); ++y)
      for (int x = x0; x < std::min(w, x0 + cw); ++x) {
        const std::size_t t = std::size_t(y) * w + x;
        if (c.cache_of_texel[t] >= 0) continue;
        c.cache_of_texel[t] = std::int32_t(c.size());
        c.texel.push_back(std::uint32_t(t));
        c.position.push_back(lattice ? glm::vec3(float(x % 4), 0.0f, float(y % 4))
                                     : origin + 0.1f * glm::vec3(float(x - x0), unit(rng), float(y - y0)));
        c.valid.push_back(!dead && unit(rng) >= hole_rate * 0.9f ? 1 : 0);
      }
  }
  c.normal.assign(c.size(), glm::vec3(0, 1, 0));
  c.mesh.assign(c.size(), 0);
  c.triangle.assign(c.size(), 0);
  c.pushed.assign(c.size(), 0);
  return c;
}

TEST(FillPlan, FrontierAndGridGiveTheSlowDefinitionsPlan) {
  std::size_t unreachable = 0, layered = 0;
  for (std::uint32_t seed = 1; seed <= 12; ++seed) {
    const LightmapCaches c = randomAtlas(seed, 64, 48);
    const FillPlan fast = planLightmapFill(c), slow = slowLightmapFill(c);
    ASSERT_EQ(fast.target, slow.target) << "seed " << seed;
    ASSERT_EQ(fast.source_begin, slow.source_begin) << "seed " << seed;
    ASSERT_EQ(fast.source, slow.source) << "seed " << seed;
    ASSERT_EQ(fast.unreachable, slow.unreachable) << "seed " << seed;
    unreachable += slow.unreachable;
    layered += slow.target.size() - slow.unreachable;
  }
  // The atlases exercise both halves: flooded targets and unreachable ones.
  EXPECT_GT(layered, 500u);
  EXPECT_GT(unreachable, 100u);
}

}  // namespace
}  // namespace lightlink::caches
