// RelightPipeline, the one relight driver, against a scripted backend: the pass order of a
// full relight, the bounce loop's stop rule with sums that arrive before or after the next
// lighting pass, the unchanged shortcut, a failing pass, and a backend without incremental.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/relight/passes.h"
#include "core/relight/pipeline.h"
#include "core/relight/scene_tables.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using testing::addBox;
using testing::addMaterial;
using testing::Baked;
using testing::smallOptions;

// Records every call; bounce k's sums are sums[k - 1] (the last one repeats).
class ScriptedPasses final : public RelightPasses {
 public:
  ScriptedPasses(bool lag, std::vector<BounceSums> sums) : lag_(lag), sums_(std::move(sums)) {}
  std::vector<std::string> calls;
  int fail_at_gather = 0;  // bounce whose gather fails (0: none)

  std::string_view backend() const override { return "scripted"; }
  std::string kernelName(const RelightOptions&) const override { return "none"; }
  Status begin(const RelightFrame&) override { return log("begin"); }
  Status setEmission(std::span<const glm::vec3>, std::uint64_t) override { return log("setEmission"); }
  Status surfelDirect(const RelightFrame&, std::span<const glm::vec3>, RelightResult&) override {
    return log("surfelDirect");
  }
  Status pullAndLight(const RelightFrame&, const std::string& prefix, bool grid, RelightResult& res) override {
    res.passes.cache_lighting++;
    return log("pullAndLight(" + prefix + (grid ? ",grid)" : ")"));
  }
  Status gather(const RelightFrame&, int bounce, bool, RelightResult&) override {
    gathered_ = bounce;
    if (bounce == fail_at_gather) return internalError("scripted: gather {} failed", bounce);
    return log("gather" + std::to_string(bounce));
  }
  Expected<BounceSums> bounceSums() override {
    (void)log("bounceSums");
    return sums_[std::min<std::size_t>(std::size_t(gathered_ - 1), sums_.size() - 1)];
  }
  bool sumsLag() const override { return lag_; }
  Status cacheDirect(const RelightFrame&, const EmitterTexels&, RelightResult&) override {
    return log("cacheDirect");
  }
  Status texels(const RelightFrame&, RelightResult& res) override {
    res.passes.fill = 1;
    return log("texels");
  }

 private:
  Status log(std::string call) {
    calls.push_back(std::move(call));
    return {};
  }
  bool lag_;
  std::vector<BounceSums> sums_;
  int gathered_ = 0;
};

// A closed, emissive box: every relight has light and so bounces.
const Baked& glowingBox() {
  static const std::unique_ptr<Baked> b = [] {
    scene::Scene s;
    const int m = addMaterial(s, glm::vec3(0.5f), glm::vec3(1.0f));
    addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true, m);
    return Baked::make(std::move(s), smallOptions());
  }();
  return *b;
}

struct Driven {
  std::unique_ptr<SceneTables> tables;
  ScriptedPasses* passes = nullptr;
  std::unique_ptr<RelightPipeline> pipeline;
};

Driven drive(bool lag, std::vector<BounceSums> sums) {
  const Baked& b = glowingBox();
  Driven d;
  auto t = SceneTables::build(b.scene, *b.accel, b.p, b.p.lightmap_links.view(), b.p.grid_links.view());
  EXPECT_TRUE(t) << t.status().toString();
  d.tables = std::make_unique<SceneTables>(std::move(*t));
  auto passes = std::make_unique<ScriptedPasses>(lag, std::move(sums));
  d.passes = passes.get();
  d.pipeline = std::make_unique<RelightPipeline>(*d.tables, std::move(passes));
  return d;
}

TEST(RelightPipeline, FullRelightRunsThePassesInOrderAndStopsAtTheThreshold) {
  Driven d = drive(false, {{0.5, 1.0}, {1e-6, 1.0}});
  RelightResult res;
  ASSERT_TRUE(d.pipeline->relightInto(LightSet{}, {.max_bounces = 10, .bounce_threshold = 1e-3f}, res));
  const std::vector<std::string> want = {"begin",       "setEmission", "surfelDirect", "pullAndLight()",
                                         "gather1",     "bounceSums",  "pullAndLight(bounce1_)",
                                         "gather2",     "bounceSums",  "pullAndLight(bounce2_)",
                                         "cacheDirect", "texels"};
  EXPECT_EQ(d.passes->calls, want);
  EXPECT_EQ(res.backend, "scripted");
  EXPECT_EQ(res.bounce_stop, "threshold");
  ASSERT_EQ(res.bounce_log.size(), 2u);
  EXPECT_EQ(res.bounce_log[0].added_flux, 0.5);
  EXPECT_EQ(res.passes.bounces, 2);
}

TEST(RelightPipeline, LateSumsAreReadAfterTheNextLightingPassAndTheCapHolds) {
  Driven d = drive(true, {{0.5, 1.0}});
  RelightResult res;
  ASSERT_TRUE(d.pipeline->relightInto(LightSet{}, {.max_bounces = 2, .bounce_threshold = 1e-3f}, res));
  const std::vector<std::string> want = {"begin",      "setEmission", "surfelDirect", "pullAndLight()",
                                         "gather1",    "pullAndLight(bounce1_)", "bounceSums",
                                         "gather2",    "pullAndLight(bounce2_)", "bounceSums",
                                         "cacheDirect", "texels"};
  EXPECT_EQ(d.passes->calls, want);
  EXPECT_EQ(res.bounce_stop, "cap");
}

TEST(RelightPipeline, UnchangedLightSetRunsOnlyTheTexels) {
  Driven d = drive(false, {{1e-6, 1.0}});
  RelightResult first, again;
  const RelightOptions o{.max_bounces = 4};
  ASSERT_TRUE(d.pipeline->relightInto(LightSet{}, o, first));
  d.passes->calls.clear();
  ASSERT_TRUE(d.pipeline->relightInto(LightSet{}, o, again));
  EXPECT_EQ(d.passes->calls, (std::vector<std::string>{"begin", "texels"}));
  EXPECT_EQ(again.passes.unchanged, 1);
  EXPECT_EQ(again.bounce_stop, first.bounce_stop);
  EXPECT_EQ(again.bounce_log.size(), first.bounce_log.size());
  // Another option value is another result: a full relight.
  d.passes->calls.clear();
  ASSERT_TRUE(d.pipeline->relightInto(LightSet{}, {.max_bounces = 5}, again));
  EXPECT_EQ(again.passes.unchanged, 0);
  EXPECT_EQ(d.passes->calls.back(), "texels");
  EXPECT_GT(d.passes->calls.size(), 2u);
}

TEST(RelightPipeline, AFailingPassFailsTheRelightAndTheNextOneIsFull) {
  Driven d = drive(false, {{0.5, 1.0}});
  RelightResult res;
  const RelightOptions o{.max_bounces = 4};
  ASSERT_TRUE(d.pipeline->relightInto(LightSet{}, o, res));
  d.passes->fail_at_gather = 2;
  d.pipeline->invalidate(false);
  Status s = d.pipeline->relightInto(LightSet{}, o, res);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("gather 2 failed"), std::string::npos) << s.message();
  d.passes->fail_at_gather = 0;
  d.passes->calls.clear();
  ASSERT_TRUE(d.pipeline->relightInto(LightSet{}, o, res));
  EXPECT_EQ(res.passes.unchanged, 0);
  EXPECT_EQ(d.passes->calls.front(), "begin");
  EXPECT_EQ(d.passes->calls[2], "surfelDirect");
}

TEST(RelightPipeline, BadRequestsAreRejectedBeforeAnyPass) {
  Driven d = drive(false, {{0.5, 1.0}});
  RelightResult res;
  Status s = d.pipeline->relightInto(LightSet{}, {.max_bounces = -1}, res);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("max_bounces"), std::string::npos) << s.message();
  EXPECT_TRUE(d.passes->calls.empty());
}

}  // namespace
}  // namespace lightlink::relight
