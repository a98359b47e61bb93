#include "core/links/links.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include "core/common/sampling.h"
#include "core/links/surfel_locator.h"
#include "core/sh/sh.h"
#include "tests/common/scene_builders.h"

namespace lightlink::links {
namespace {

using scene::MeshInstance;
using scene::Scene;
constexpr float kPi = std::numbers::pi_v<float>;

using lightlink::testing::addBox;
using lightlink::testing::addQuad;

void finish(Scene& s) { lightlink::testing::finishScene(s); }

// Everything link generation needs, built the way precompute builds it.
struct LinkFixture {
  Scene scene;
  rt::Accel accel;
  surfels::Surfels surfels;
  hierarchy::Tree tree;

  static LinkFixture make(Scene s, std::uint32_t surfel_count = 2048) {
    finish(s);
    auto accel = rt::Accel::build(s);
    EXPECT_TRUE(accel) << accel.status().toString();
    auto placed = surfels::placeSurfels(s, {.count = surfel_count});
    EXPECT_TRUE(placed) << placed.status().toString();
    auto tree = hierarchy::buildTree(*placed, {});
    EXPECT_TRUE(tree) << tree.status().toString();
    return LinkFixture{std::move(s), std::move(accel).value(), std::move(placed).value(), std::move(tree).value()};
  }

  Links link(std::vector<glm::vec3> p, std::vector<glm::vec3> n, LinkOptions opt = {}) const {
    auto links = generateLinks(scene, accel, surfels, tree, {p, n}, opt);
    EXPECT_TRUE(links) << links.status().toString();
    return std::move(links).value();
  }
};

// Every array of two link sets the same (the seen surfels included).
void expectSameLinks(const Links& a, const Links& b) {
  EXPECT_EQ(a.seen, b.seen);
  EXPECT_EQ(a.offsets, b.offsets);
  EXPECT_EQ(a.node, b.node);
  EXPECT_EQ(a.coeffs, b.coeffs);
  EXPECT_EQ(a.direction, b.direction);
  EXPECT_EQ(a.solid_angle, b.solid_angle);
  EXPECT_EQ(a.sky, b.sky);
}

float linkSolidAngle(const Links& l, std::size_t cache) {
  float sum = 0.0f;
  for (std::uint32_t k = l.offsets[cache]; k < l.offsets[cache + 1]; ++k) sum += fromHalf(l.solid_angle[k]) * kPi;
  return sum;
}

TEST(Links, OpenSkyMatchesTheAnalyticHemisphere) {
  Scene s;
  addQuad(s, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1});  // floor facing +y
  const LinkFixture fixture = LinkFixture::make(std::move(s));
  // 64 caches on the floor, each with its own jitter.
  constexpr int kCaches = 64;
  std::vector<glm::vec3> p, n;
  for (int c = 0; c < kCaches; ++c) {
    p.push_back({-0.5f + 0.015f * float(c), 0.0f, 0.25f});
    n.push_back({0, 1, 0});
  }
  const Links links = fixture.link(p, n);
  ASSERT_EQ(links.cacheCount(), std::size_t(kCaches));
  EXPECT_EQ(links.linkCount(), 0u);
  EXPECT_EQ(links.stats.escaped, links.stats.rays);
  // Sky visibility / pi of a full hemisphere = a cap of 2 pi sr around the normal.
  float expected[9];
  projectRuntimeLink({0, 1, 0}, 2.0f, 3, expected);
  // One cache's 32 x 32 stratified estimate has an error of ~1e-3 per coefficient (rms over
  // 400 caches: 0.3e-3 to 2.0e-3, the largest for the l = 2 coefficients): each within 1e-2,
  // and the mean over the caches (independent jitter) within 1e-3, which a biased
  // generator would miss.
  double mean[9] = {};
  for (int c = 0; c < kCaches; ++c) {
    for (int i = 0; i < 9; ++i) {
      EXPECT_NEAR(links.sky[9 * c + i], expected[i], 1e-2f) << "cache " << c << " coefficient " << i;
      mean[i] += links.sky[9 * c + i] / double(kCaches);
    }
    // c_00 of V/pi over a hemisphere is 2 pi Y00 / pi = 2 Y00, whatever the directions.
    EXPECT_NEAR(links.sky[9 * c], 2.0f * sh::kY00, 1e-4f);
  }
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(mean[i], expected[i], 1e-3) << "coefficient " << i;
}

TEST(Links, LargeQuadAboveGivesItsAnalyticSolidAngle) {
  // A 2 x 2 m ceiling 1 m above the cache, facing down; nothing else but the floor.
  Scene s;
  addQuad(s, {-1, 1, -1}, {1, 1, -1}, {1, 1, 1}, {-1, 1, 1});
  addQuad(s, {-3, 0, -3}, {-3, 0, 3}, {3, 0, 3}, {3, 0, -3});
  const LinkFixture fixture = LinkFixture::make(std::move(s));
  // Every band count: the links' sums are kept in rows of 8 polynomials (1 row for 2 and 3
  // bands, 2 for 4), and a row or lane out of place breaks the coefficient sums below.
  for (int bands = 1; bands <= 4; ++bands) {
    SCOPED_TRACE("bands " + std::to_string(bands));
    const int coeffs = bands * bands;
    const Links links = fixture.link({{0, 0, 0}}, {{0, 1, 0}}, {.rays = 4096, .bands = bands});
    const float a = 1.0f, b = 1.0f, h = 1.0f;
    const float omega = 4.0f * std::atan(a * b / (h * std::sqrt(h * h + a * a + b * b)));  // 2 pi / 3
    EXPECT_NEAR(linkSolidAngle(links, 0), omega, 0.01f * omega);
    // Links and sky together are the whole visible hemisphere, coefficient by coefficient.
    float hemisphere[16];
    projectRuntimeLink({0, 1, 0}, 2.0f, bands, hemisphere);
    for (int i = 0; i < coeffs; ++i) {
      float sum = links.sky[i];
      for (std::uint32_t k = 0; k < links.linkCount(); ++k) sum += fromHalf(links.coeffs[k * coeffs + i]);
      EXPECT_NEAR(sum, hemisphere[i], 3e-3f) << "coefficient " << i;
    }
    // Sky sees the rest: c00 of the sky is (2 pi - omega) Y00 / pi.
    EXPECT_NEAR(links.sky[0], (2.0f * kPi - omega) * sh::kY00 / kPi, 5e-3f);
  }
}

TEST(Links, ClosedRoomCutCoversTheVisibleSurfelsOnce) {
  Scene s;
  addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true);
  const LinkFixture fixture = LinkFixture::make(std::move(s), 4096);
  const std::vector<glm::vec3> p = {{1, 1, 1}, {0.5f, 1.5f, 1.2f}};
  const std::vector<glm::vec3> n = {{0, 0, 0}, {0, 0, 0}};  // grid caches: full sphere
  const Links links = fixture.link(p, n, {.rays = 1024, .max_links = 64});
  EXPECT_EQ(links.stats.escaped, 0u);
  EXPECT_EQ(links.stats.back_hits, 0u);
  EXPECT_EQ(links.stats.unowned, 0u);
  for (std::size_t c = 0; c < 2; ++c) {
    EXPECT_NEAR(linkSolidAngle(links, c), 4.0f * kPi, 4e-3f * 4.0f * kPi);
    const std::uint32_t count = links.offsets[c + 1] - links.offsets[c];
    EXPECT_LE(count, 64u);
    EXPECT_GT(count, 32u);
    // Disjoint ranges; together they cover the surfels the rays saw. From inside a room all
    // surfels are visible, but a node that no ray hit carries no light and is not linked, so
    // coverage is nearly (not exactly) all at 1024 rays for 4096 surfels.
    std::vector<int> covered(fixture.surfels.size(), 0);
    for (std::uint32_t k = links.offsets[c]; k < links.offsets[c + 1]; ++k) {
      const std::uint32_t node = links.node[k];
      for (std::uint32_t i = fixture.tree.begin[node]; i < fixture.tree.end[node]; ++i) covered[i]++;
    }
    EXPECT_EQ(std::count_if(covered.begin(), covered.end(), [](int v) { return v > 1; }), 0);
    EXPECT_GT(std::count(covered.begin(), covered.end(), 1), static_cast<long>(0.98 * covered.size()));
  }
}

TEST(Links, CacheInsideASolidBlockSeesOnlyBackFaces) {
  Scene s;
  addBox(s, {0, 0, 0}, {1, 1, 1}, /*inward=*/false);
  const LinkFixture fixture = LinkFixture::make(std::move(s));
  const Links links = fixture.link({{0.5f, 0.5f, 0.5f}}, {{0, 0, 0}});
  EXPECT_EQ(links.linkCount(), 0u);
  EXPECT_EQ(links.stats.back_hits, links.stats.rays);
  for (float c : links.sky) EXPECT_EQ(c, 0.0f);
}

TEST(Links, OneLinkIsTheRootWithEverything) {
  Scene s;
  addBox(s, {0, 0, 0}, {2, 2, 2}, true);
  const LinkFixture fixture = LinkFixture::make(std::move(s));
  const Links links = fixture.link({{1, 1, 1}}, {{0, 0, 0}}, {.max_links = 1});
  ASSERT_EQ(links.linkCount(), 1u);
  EXPECT_EQ(links.node[0], 0u);
}

TEST(Links, DeterministicAcrossThreadCounts) {
  Scene s;
  addBox(s, {0, 0, 0}, {2, 2, 2}, true);
  addBox(s, {0.5f, 0, 0.5f}, {1.0f, 0.8f, 1.0f}, false);
  const LinkFixture fixture = LinkFixture::make(std::move(s));
  std::vector<glm::vec3> p, n;
  for (int i = 0; i < 100; ++i) {
    p.push_back({0.1f + 0.018f * i, 1.2f, 1.5f});
    n.push_back(i % 2 ? glm::vec3(0) : glm::vec3(0, 1, 0));
  }
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    return fixture.link(p, n, {.rays = 256, .max_links = 32});
  };
  expectSameLinks(run(1), run(2));
}

TEST(Links, RuntimeFormApproximatesTheProjectedForm) {
  // A small quad far away is nearly a cap: both forms must agree closely.
  Scene s;
  addQuad(s, {-0.2f, 2, -0.2f}, {0.2f, 2, -0.2f}, {0.2f, 2, 0.2f}, {-0.2f, 2, 0.2f});
  addQuad(s, {-3, 0, -3}, {-3, 0, 3}, {3, 0, 3}, {3, 0, -3});
  const LinkFixture fixture = LinkFixture::make(std::move(s));
  const Links links = fixture.link({{0, 0, 0}}, {{0, 1, 0}}, {.rays = 16384, .max_links = 1});
  ASSERT_EQ(links.linkCount(), 1u);
  float runtime[9];
  projectRuntimeLink(decodeOctahedral(links.direction[0]), fromHalf(links.solid_angle[0]), 3, runtime);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(fromHalf(links.coeffs[i]), runtime[i], 2e-3f) << i;
}

TEST(Links, BytesPerLinkMeetTheBudget) {
  Links l;
  l.bands = 3;
  EXPECT_LE(l.bytesPerLinkProjected(), 22u);
  EXPECT_LE(Links::bytesPerLinkRuntime(), 12u);
}

// A surfel is seen when a cache's ray was credited to it: every one faces some cache, a face
// that turns away from the only cache is never seen, and the flags are those of the hits.
TEST(Links, SeenSurfelsAreThoseTheRaysWereCreditedTo) {
  Scene s;
  addBox(s, {0, 0, 0}, {2, 2, 2}, true);
  addBox(s, {0.8f, 0, 0.8f}, {1.2f, 0.4f, 1.2f}, false);  // a block on the floor
  const LinkFixture fixture = LinkFixture::make(std::move(s), 4096);
  const glm::vec3 cache(0.3f, 1.0f, 0.3f);
  const Links links = fixture.link({cache}, {{0, 0, 0}}, {.rays = 4096, .max_links = 4096});
  ASSERT_EQ(links.seen.size(), fixture.surfels.size());
  std::size_t seen = 0, facing_away_seen = 0, hidden_by_block = 0;
  for (std::size_t i = 0; i < links.seen.size(); ++i) {
    ASSERT_LE(links.seen[i], 1);
    seen += links.seen[i];
    const glm::vec3 q = fixture.surfels.position[i];
    if (links.seen[i] && glm::dot(fixture.surfels.normal[i], cache - q) < 0.0f) ++facing_away_seen;
    // The block's far sides (+x, +z faces) turn away from the cache.
    const bool far_side = (q.x > 1.19f && q.y < 0.4f && q.z > 0.8f && q.z < 1.2f) ||
                          (q.z > 1.19f && q.y < 0.4f && q.x > 0.8f && q.x < 1.2f);
    if (far_side) hidden_by_block += 1 - links.seen[i];
  }
  EXPECT_EQ(facing_away_seen, 0u);
  EXPECT_GT(hidden_by_block, 0u);
  // With one link per surfel hit, the seen surfels are the leaves of the cut exactly.
  std::size_t leaves = 0;
  for (std::uint32_t node : links.node) leaves += fixture.tree.isLeaf(node) ? 1 : 0;
  ASSERT_EQ(leaves, links.linkCount()) << "the cut did not reach the leaves; raise max_links";
  EXPECT_EQ(seen, links.linkCount());
  for (std::uint32_t node : links.node) EXPECT_EQ(links.seen[fixture.tree.begin[node]], 1);
}

// The precompute builds the owner lookup once and links the lightmap and the grid caches over
// it: the same links as building one per call, and a lookup over other surfels is refused.
// More chunks than the pipeline keeps in flight (its ring of chunk results wraps many
// times): the caches' links come out in cache order. A cache's rays depend on its index, so
// the reference for the first L caches is a run over just those L: a run of two chunks
// (no wrap), and longer ones on one thread (another ring size, 4 slots instead of 8).
TEST(Links, ManyChunksComeOutInCacheOrder) {
  Scene s;
  addBox(s, {0, 0, 0}, {2, 2, 2}, true);
  addBox(s, {0.5f, 0, 0.5f}, {1.0f, 0.8f, 1.0f}, false);
  const LinkFixture fixture = LinkFixture::make(std::move(s), 512);
  std::vector<glm::vec3> p, n;
  for (int i = 0; i < 1200; ++i) {
    p.push_back({0.1f + 0.0015f * i, 1.2f + 0.0003f * (i % 7), 1.5f});
    n.push_back(i % 3 ? glm::vec3(0, 1, 0) : glm::vec3(0));
  }
  const LinkOptions opt{.rays = 64, .max_links = 16};
  const Links all = [&] {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    return fixture.link(p, n, opt);
  }();
  ASSERT_EQ(all.cacheCount(), p.size());
  const std::size_t q = 9;  // SH coefficients at the default 3 bands
  for (const std::size_t prefix : {std::size_t(33), std::size_t(517), std::size_t(1199)}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, prefix == 33 ? 2 : 1);
    const Links part = fixture.link({p.begin(), p.begin() + prefix}, {n.begin(), n.begin() + prefix}, opt);
    ASSERT_EQ(part.cacheCount(), prefix);
    const std::size_t links = part.linkCount();
    ASSERT_EQ(all.offsets[prefix], links);
    EXPECT_TRUE(std::equal(part.offsets.begin(), part.offsets.end(), all.offsets.begin())) << prefix;
    EXPECT_TRUE(std::equal(part.node.begin(), part.node.end(), all.node.begin())) << prefix;
    EXPECT_TRUE(std::equal(part.direction.begin(), part.direction.end(), all.direction.begin())) << prefix;
    EXPECT_TRUE(std::equal(part.solid_angle.begin(), part.solid_angle.end(), all.solid_angle.begin())) << prefix;
    EXPECT_TRUE(std::equal(part.coeffs.begin(), part.coeffs.end(), all.coeffs.begin())) << prefix;
    EXPECT_TRUE(std::equal(part.sky.begin(), part.sky.end(), all.sky.begin())) << prefix;
    EXPECT_EQ(part.coeffs.size(), links * q);
  }
  // Neighbouring caches differ, so a chunk's links in another chunk's place would show.
  EXPECT_NE(std::vector<std::uint32_t>(all.node.begin() + all.offsets[0], all.node.begin() + all.offsets[1]),
            std::vector<std::uint32_t>(all.node.begin() + all.offsets[600], all.node.begin() + all.offsets[601]));
  // Output arrays sized for 50 links up front grow many times while chunks are copied in on
  // two threads, and hold the same links.
  LinkOptions small = opt;
  small.output_links_up_front = 50;
  const Links grown = [&] {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    return fixture.link(p, n, small);
  }();
  expectSameLinks(grown, all);
}

// In a benchmark build every phase of linking a cache is timed (the report's phase shares
// and the benchmark's "own work per unit of tracing" come from these); elsewhere none is.
TEST(Links, EveryPhaseIsTimed) {
  Scene s;
  addBox(s, {0, 0, 0}, {2, 2, 2}, true);
  addBox(s, {0.5f, 0, 0.5f}, {1.0f, 0.8f, 1.0f}, false);
  const LinkFixture fixture = LinkFixture::make(std::move(s), 512);
  std::vector<glm::vec3> p(64, glm::vec3(1.2f, 1.2f, 1.5f)), n(64, glm::vec3(0));
  const Links links = fixture.link(p, n, {.rays = 256, .max_links = 16});
  if (!kPhaseProbes) {
    EXPECT_EQ(links.stats.totalPhaseTicks(), 0u) << "probes in a build without LIGHTLINK_PROBES";
    return;
  }
  for (int k = 0; k < kLinkPhases; ++k) EXPECT_GT(links.stats.phase_ticks[k], 0u) << kLinkPhaseNames[k];
  // In seconds (precompute_bench sets them against the wall time), the phases of all threads
  // together take no longer than the run on every thread the process may use, and not
  // nothing. (A 10 % margin for the rate's own measurement.)
  const double rate = linkPhaseTicksPerSecond();
  ASSERT_GT(rate, 0.0);
  EXPECT_EQ(rate, linkPhaseTicksPerSecond());  // measured once
  const double phases = double(links.stats.totalPhaseTicks()) / rate;
  EXPECT_GT(phases, 0.0);
  EXPECT_LE(phases, 1.1 * links.stats.seconds * double(tbb::this_task_arena::max_concurrency()));
}

// A caller that cancels (a closed client, a deadline) stops link generation between chunks,
// and gets an error, not partial links.
TEST(Links, CancelledRunReturnsAnError) {
  Scene s;
  addBox(s, {0, 0, 0}, {2, 2, 2}, true);
  const LinkFixture fixture = LinkFixture::make(std::move(s), 512);
  std::vector<glm::vec3> p(2000, glm::vec3(1.0f, 1.0f, 1.0f)), n(2000, glm::vec3(0));
  struct CancelAfterFirstUpdate final : Progress {
    std::atomic<bool> stop{false};
    void begin(std::string_view, std::size_t) override {}
    void update(std::size_t) override { stop = true; }
    void end() override {}
    bool cancelled() const override { return stop; }
  } cancel;
  auto r = generateLinks(fixture.scene, fixture.accel, fixture.surfels, fixture.tree, {p, n},
                         {.rays = 64, .max_links = 16}, &cancel);
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("cancelled"), std::string::npos) << r.status().message();
}

TEST(Links, SharedOwnerLookupGivesTheSameLinks) {
  Scene s;
  addBox(s, {0, 0, 0}, {2, 2, 2}, true);
  addBox(s, {0.5f, 0, 0.5f}, {1.0f, 0.8f, 1.0f}, false);
  const LinkFixture fixture = LinkFixture::make(std::move(s));
  const std::vector<glm::vec3> p = {{1.2f, 1.2f, 1.5f}, {0.3f, 0.001f, 0.3f}}, n = {{0, 0, 0}, {0, 1, 0}};
  const LinkOptions opt{.rays = 256, .max_links = 32};
  const SurfelLocator owners(fixture.surfels, fixture.scene);
  for (int twice = 0; twice < 2; ++twice) {
    auto shared = generateLinks(fixture.scene, fixture.accel, owners, fixture.tree, {p, n}, opt);
    ASSERT_TRUE(shared) << shared.status().toString();
    const Links own = fixture.link(p, n, opt);
    EXPECT_EQ(shared->offsets, own.offsets);
    EXPECT_EQ(shared->node, own.node);
    EXPECT_EQ(shared->coeffs, own.coeffs);
    EXPECT_EQ(shared->direction, own.direction);
    EXPECT_EQ(shared->solid_angle, own.solid_angle);
    EXPECT_EQ(shared->sky, own.sky);
    EXPECT_EQ(shared->stats.front_hits, own.stats.front_hits);
  }
  surfels::Surfels fewer = fixture.surfels;
  fewer.resize(fewer.size() - 1);
  const SurfelLocator other(fewer, fixture.scene);
  auto r = generateLinks(fixture.scene, fixture.accel, other, fixture.tree, {p, n}, opt);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.status().code(), Code::kInvalidInput);
  EXPECT_NE(r.status().message().find("owner lookup"), std::string::npos) << r.status().message();
}

TEST(Links, RejectsAbsurdOptions) {
  Scene s;
  addQuad(s, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1});
  const LinkFixture fixture = LinkFixture::make(std::move(s), 64);
  const std::vector<glm::vec3> p = {{0, 0, 0}}, n = {{0, 1, 0}};
  for (LinkOptions bad : {LinkOptions{.bands = 0}, LinkOptions{.bands = 5}, LinkOptions{.rays = 0},
                          LinkOptions{.max_links = 0}}) {
    auto r = generateLinks(fixture.scene, fixture.accel, fixture.surfels, fixture.tree, {p, n}, bad);
    EXPECT_FALSE(r);
    EXPECT_EQ(r.status().code(), Code::kInvalidInput);
  }
}

// The rays LinkRays makes for one cache (`rays` per cache, link seed `seed`), over a 2 m quad
// (generate() offsets the origin with the accel's epsilon).
std::vector<rt::Ray> cacheRays(int rays, std::uint64_t seed, std::uint32_t cache, glm::vec3 p, glm::vec3 normal) {
  static const rt::Accel accel = [] {
    Scene s;
    addQuad(s, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1});
    finish(s);
    return std::move(rt::Accel::build(s)).value();
  }();
  const LinkRays pattern(LinkOptions{.rays = rays, .seed = seed});
  std::vector<rt::Ray> r(pattern.count());
  pattern.generate(accel, cache, p, normal, r);
  return r;
}

// The reference of the ray pattern, written out again (the reference may not call the
// generator): the base pattern's jitters from Wellons' lowbias32, the cache's polar shift
// and azimuth turn from its 64-bit hash. All in the generator's float operations, in its
// order, so it can be held to the same bits.
struct PatternReference {
  std::uint32_t strata;
  std::uint64_t seed;
  static std::uint32_t mix32(std::uint32_t x) {
    x = (x ^ (x >> 16)) * 0x7feb352dU;
    x = (x ^ (x >> 15)) * 0x846ca68bU;
    return x ^ (x >> 16);
  }
  static float unit(std::uint32_t bits) { return static_cast<float>(bits >> 8) / 16777216.0f; }
  std::uint32_t patternSeed() const { return static_cast<std::uint32_t>(mixBits(seed ^ 0x5851f42d4c957f2dULL) >> 32); }
  std::uint64_t cacheBits(std::uint32_t cache) const { return mixBits(seed ^ (std::uint64_t(cache) * 0xd1b54a32d192ed03ULL)); }
  // Base pattern, ray i: the polar jitter inside its stratum, and the azimuth in [0, 1).
  float baseJitter(std::uint32_t i) const { return unit(mix32(patternSeed() ^ (i * 2654435769U))); }
  float baseAzimuth(std::uint32_t i) const {
    const std::uint32_t bits = mix32(patternSeed() ^ (i * 2654435769U));
    return (static_cast<float>(i / strata) + unit(mix32(bits))) / static_cast<float>(strata);
  }
  float polarShift(std::uint32_t cache) const { return unit(static_cast<std::uint32_t>(cacheBits(cache) >> 32)); }
  double turn(std::uint32_t cache) const {  // radians
    return 2.0 * std::numbers::pi * double(unit(static_cast<std::uint32_t>(cacheBits(cache))));
  }
};

TEST(LinkRays, KeepOneRayPerStratumInEveryCache) {
  // Whatever the cache, ray sy * strata + sx has its polar coordinate u (z = 1 - u on the
  // hemisphere) in stratum sx and its azimuth, less the cache's turn, in stratum sy: the
  // per-cache randomisation moves samples inside their strata, never across.
  for (int rays : {64, 256, 1024}) {
    const glm::vec3 n = glm::normalize(glm::vec3(0.3f, 1.0f, -0.2f));
    glm::vec3 t, b;
    orthonormalBasis(n, t, b);
    const auto strata = static_cast<std::uint32_t>(std::sqrt(double(rays)));
    const PatternReference ref{strata, 77};
    for (std::uint32_t cache : {0u, 5u, 123456u}) {
      const std::vector<rt::Ray> r = cacheRays(rays, 77, cache, {0, 0, 0}, n);
      const double turn = ref.turn(cache);
      for (std::uint32_t i = 0; i < r.size(); ++i) {
        const glm::dvec3 d = glm::normalize(glm::dvec3(r[i].dir));
        const double u = 1.0 - glm::dot(d, glm::dvec3(n));
        double phi = std::atan2(glm::dot(d, glm::dvec3(b)), glm::dot(d, glm::dvec3(t))) - turn;
        phi = phi - 2.0 * std::numbers::pi * std::floor(phi / (2.0 * std::numbers::pi));
        const double su = u * strata, sphi = phi / (2.0 * std::numbers::pi) * strata;
        const std::uint32_t sx = i % strata, sy = i / strata;
        // 1e-4 of a stratum: the float rounding of a sample that lies on a stratum's edge.
        EXPECT_GE(su, sx - 1e-4) << "ray " << i << " of " << rays << ", cache " << cache;
        EXPECT_LE(su, sx + 1 + 1e-4) << "ray " << i << " of " << rays << ", cache " << cache;
        const double dphi = std::remainder(sphi - (sy + 0.5), double(strata));
        EXPECT_LE(std::abs(dphi), 0.5 + 1e-4) << "ray " << i << " of " << rays << ", cache " << cache;
        EXPECT_NEAR(glm::length(r[i].dir), 1.0f, 1e-5f);
        EXPECT_GE(glm::dot(r[i].dir, n), 0.0f);
      }
    }
  }
}

TEST(LinkRays, DirectionsAreFiniteUnitVectorsForAnyRayCount) {
  // The row loop takes sqrt(1 - z^2) without a clamp. That relies on u = (sx + jitter) *
  // (1 / strata) <= 1, i.e. on strata * (1 / strata) <= 1 in floats for every row length.
  for (std::uint32_t strata = 1; strata <= 1024; ++strata) {
    const float inv = 1.0f / static_cast<float>(strata);
    ASSERT_LE(static_cast<float>(strata) * inv, 1.0f) << strata;
  }
  // And on the rays themselves: odd strata (the sphere of grid caches is where z reaches -1),
  // a single ray, many caches.
  for (int rays : {1, 2, 5, 961, 1000}) {
    for (const glm::vec3 normal : {glm::vec3(0.0f), glm::vec3(0.0f, 0.0f, -1.0f)}) {
      for (std::uint32_t cache = 0; cache < 64; ++cache) {
        for (const rt::Ray& r : cacheRays(rays, 5, cache, {0, 0, 0}, normal)) {
          ASSERT_TRUE(std::isfinite(r.dir.x) && std::isfinite(r.dir.y) && std::isfinite(r.dir.z))
              << rays << " rays, cache " << cache;
          ASSERT_NEAR(glm::length(r.dir), 1.0f, 1e-5f) << rays << " rays, cache " << cache;
        }
      }
    }
  }
}

TEST(LinkRays, AreBitIdenticalToTheScalarFormula) {
  // The generator's vectorised row loop must round exactly like per-ray scalar code (no FMA,
  // no reassociation), so rays, and so links, are the same bits on every machine.
  for (int rays : {64, 1024}) {
    for (const glm::vec3 normal : {glm::vec3(0.3f, 1.0f, -0.2f), glm::vec3(0.0f)}) {
      const glm::vec3 p(0.25f, 0.5f, -0.125f);
      const std::uint32_t cache = 12;
      const std::vector<rt::Ray> r = cacheRays(rays, 91, cache, p, normal);
      const bool hemisphere = glm::dot(normal, normal) > 0.0f;
      glm::vec3 t(1, 0, 0), b(0, 1, 0), n(0, 0, 1);
      if (hemisphere) {
        n = glm::normalize(normal);
        orthonormalBasis(n, t, b);
      }
      const auto strata = static_cast<std::uint32_t>(std::sqrt(double(rays)));
      const PatternReference ref{strata, 91};
      const float inv = 1.0f / static_cast<float>(strata), shift = ref.polarShift(cache);
      const float ca = static_cast<float>(std::cos(ref.turn(cache))), sa = static_cast<float>(std::sin(ref.turn(cache)));
      const glm::vec3 tt = ca * t + sa * b, bb = ca * b - sa * t;
      for (std::uint32_t i = 0; i < r.size(); ++i) {
        const std::uint32_t sx = i % strata;
        float jitter = ref.baseJitter(i) + shift;
        if (jitter >= 1.0f) jitter -= 1.0f;
        const float u = (static_cast<float>(sx) + jitter) * inv;
        const double phi = 2.0 * std::numbers::pi * double(ref.baseAzimuth(i));
        const float cos_phi = static_cast<float>(std::cos(phi)), sin_phi = static_cast<float>(std::sin(phi));
        const float z = hemisphere ? 1.0f - u : 1.0f - 2.0f * u;
        const float rad = std::sqrt(std::max(0.0f, 1.0f - z * z));
        const float a = rad * cos_phi, c = rad * sin_phi;
        const glm::vec3 expected(a * tt.x + c * bb.x + z * n.x, a * tt.y + c * bb.y + z * n.y,
                                 a * tt.z + c * bb.z + z * n.z);
        ASSERT_EQ(r[i].dir.x, expected.x) << "ray " << i << " of " << rays;
        ASSERT_EQ(r[i].dir.y, expected.y) << "ray " << i << " of " << rays;
        ASSERT_EQ(r[i].dir.z, expected.z) << "ray " << i << " of " << rays;
      }
    }
  }
}

TEST(LinkRays, CachesErrorsAreSmallUnbiasedAndUncorrelated) {
  // Every cache traces the same base pattern, randomised per cache. Its estimates must still
  // behave like independent stratified samples: small per cache, with no error common to
  // all caches (a shared pattern only turned per cache biased the mean of a plane's sky
  // irradiance by 0.3 %), and no correlation between neighbouring caches. The integrand, the
  // mean over the hemisphere of z^2 (1/3) and of x^2 - y^2 in the cache's frame (0), is what
  // the sky projection's band-2 coefficients estimate. Shifting u itself modulo 1 (a
  // Cranley-Patterson rotation of the pattern) fails the first bound: it splits one polar
  // stratum per row between the normal and the horizon (3 % error per cache at 256 rays).
  const glm::vec3 n = glm::normalize(glm::vec3(-0.4f, 0.2f, 1.0f));
  glm::vec3 t, b;
  orthonormalBasis(n, t, b);
  for (int rays : {256, 1024}) {
    constexpr int kCaches = 4000;
    std::vector<double> err_z(kCaches), err_xy(kCaches);
    for (int c = 0; c < kCaches; ++c) {
      const std::vector<rt::Ray> r = cacheRays(rays, 3, static_cast<std::uint32_t>(c), {0, 0, 0}, n);
      double z2 = 0.0, xy = 0.0;
      for (const rt::Ray& ray : r) {
        const glm::dvec3 d = glm::normalize(glm::dvec3(ray.dir));
        const double z = glm::dot(d, glm::dvec3(n)), x = glm::dot(d, glm::dvec3(t)), y = glm::dot(d, glm::dvec3(b));
        z2 += z * z, xy += x * x - y * y;
      }
      err_z[c] = z2 / double(r.size()) - 1.0 / 3.0;
      err_xy[c] = xy / double(r.size());
    }
    for (const auto* e : {&err_z, &err_xy}) {
      double mean = 0.0, var = 0.0, cov = 0.0, worst = 0.0;
      for (int c = 0; c < kCaches; ++c) mean += (*e)[c] / kCaches;
      for (int c = 0; c < kCaches; ++c) {
        var += ((*e)[c] - mean) * ((*e)[c] - mean) / kCaches;
        if (c + 1 < kCaches) cov += ((*e)[c] - mean) * ((*e)[c + 1] - mean) / (kCaches - 1);
        worst = std::max(worst, std::abs((*e)[c]));
      }
      const double sd = std::sqrt(var);
      const char* what = e == &err_z ? "mean of z^2" : "mean of x^2 - y^2";
      // Stratified: the largest per-cache error over 4000 caches was 0.0035 / 0.0076 (z^2 /
      // x^2 - y^2) at 256 rays and 0.0007 / 0.0043 at 1024; with u shifted modulo 1 it was
      // 0.025 / 0.019 and 0.0065 / 0.0087.
      EXPECT_LT(worst, rays == 256 ? 0.012 : 0.006) << what << ", " << rays << " rays";
      // Unbiased: the mean error within 4 standard errors of 0.
      EXPECT_LT(std::abs(mean), 4.0 * sd / std::sqrt(double(kCaches)) + 1e-7) << what << ", " << rays << " rays";
      // Uncorrelated neighbours: |r| within ~4 standard errors (1 / sqrt(4000) = 0.016).
      EXPECT_LT(std::abs(cov) / var, 0.065) << what << ", " << rays << " rays";
    }
  }
}

TEST(Octahedral, RoundTripIsAccurate) {
  for (int i = 0; i < 1000; ++i) {
    const float z = 1.0f - 2.0f * (i + 0.5f) / 1000.0f, phi = 2.399963f * i;
    const float r = std::sqrt(1 - z * z);
    const glm::vec3 d(r * std::cos(phi), r * std::sin(phi), z);
    const glm::vec3 back = decodeOctahedral(encodeOctahedral(d));
    EXPECT_GT(glm::dot(d, back), std::cos(1e-3f)) << i;
    // Link generation encodes unnormalised sums of hit directions.
    for (float scale : {1e-3f, 37.0f, 900.0f})
      EXPECT_GT(glm::dot(d, decodeOctahedral(encodeOctahedral(scale * d))), std::cos(1e-3f)) << i << " x" << scale;
  }
}

// The batch encoder (eight directions per vector step) against the scalar definition, bit
// for bit: the axes and octant edges, signed zeros, components past the clamp's reach,
// codes at or next to halfway between two integers (lrint rounds ties to even),
// unnormalised lengths, and a tail that is not a whole vector.
TEST(Octahedral, BatchEncodingMatchesTheScalarOneBitForBit) {
  std::vector<glm::vec3> dirs;
  for (float a : {0.0f, -0.0f, 1.0f, -1.0f, 0.5f, -0.5f, 1e-30f, -1e-30f})
    for (float b : {0.0f, -0.0f, 1.0f, -1.0f, 0.25f})
      for (float c : {1.0f, -1.0f, 0.0f, -0.0f, 3.0f}) {
        dirs.emplace_back(a, b, c);
        dirs.emplace_back(b, c, a);
        dirs.emplace_back(c, a, b);
      }
  // x / (|x| + |y| + |z|) * 32767 = k + 0.5 in exact arithmetic for x = 2k + 1, y = 65534 - x, z = 0.
  for (int k : {0, 1, 2, 100, 16383, 32766}) {
    const float xk = 2.0f * static_cast<float>(k) + 1.0f;
    dirs.emplace_back(xk, 65534.0f - xk, 0.0f);
    dirs.emplace_back(-xk, 65534.0f - xk, -0.0f);
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 4000; ++i) {
    const float scale = std::ldexp(1.0f, static_cast<int>(rng() % 40) - 20);
    dirs.emplace_back(scale * u(rng), scale * u(rng), scale * u(rng));
  }
  dirs.emplace_back(0.3f, -0.2f, 0.1f);  // a count that is not a multiple of 8
  std::vector<float> x, y, z;
  for (const glm::vec3& d : dirs) {
    if (std::abs(d.x) + std::abs(d.y) + std::abs(d.z) == 0.0f) continue;  // the encoder's domain: non-zero
    x.push_back(d.x);
    y.push_back(d.y);
    z.push_back(d.z);
  }
  ASSERT_NE(x.size() % 8, 0u);
  std::vector<std::uint32_t> batch(x.size());
  encodeOctahedral(x.data(), y.data(), z.data(), static_cast<std::uint32_t>(x.size()), batch.data());
  for (std::size_t i = 0; i < x.size(); ++i)
    ASSERT_EQ(batch[i], encodeOctahedral(glm::vec3(x[i], y[i], z[i]))) << i << ": " << x[i] << " " << y[i] << " " << z[i];
}

TEST(CapZonal, FullSphereIsConstant) {
  float z[4];
  capZonal(4.0f * kPi, 4, z);
  EXPECT_NEAR(z[0], std::sqrt(4.0f * kPi) / kPi, 1e-5f);
  for (int l = 1; l < 4; ++l) EXPECT_NEAR(z[l], 0.0f, 1e-5f);
}

}  // namespace
}  // namespace lightlink::links
