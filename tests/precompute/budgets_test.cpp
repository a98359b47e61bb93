// Budgets and cancellation of the precompute (docs/cli.md "Limits"): every stage stops with
// Code::kCancelled when its Progress asks, and a run over a budget is refused before the
// stage it bounds, with Code::kResourceExhausted naming the limit.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/caches/caches.h"
#include "core/charts/unwrap.h"
#include "core/hierarchy/tree.h"
#include "core/precompute/precompute.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"
#include "core/surfels/surfels.h"
#include "tests/common/testing.h"

namespace lightlink::precompute {
namespace {

const std::string kDemo = (testing::sourceDir() / "clients/demo/cornell_box.gltf").string();

// Cancelled from the start, or from the beginning of one named stage; records the stages begun.
class CancelAt final : public Progress {
 public:
  explicit CancelAt(std::string stage = "") : stage_(std::move(stage)), stop_(stage_.empty()) {}
  void begin(std::string_view stage, std::size_t) override {
    begun.emplace_back(stage);
    if (stage == stage_) stop_ = true;
  }
  void update(std::size_t) override {}
  void end() override {}
  bool cancelled() const override { return stop_; }
  std::vector<std::string> begun;

 private:
  std::string stage_;
  std::atomic<bool> stop_;
};

PrecomputeOptions small() {
  PrecomputeOptions o;
  o.surfels = 2048;
  o.links = 16;
  o.rays = 64;
  o.target_resolution = 32;
  o.grid_resolution = 4;
  o.validity_rays = 16;
  return o;
}

TEST(PrecomputeBudgets, EachStagePollsCancellation) {
  auto scene = scene::loadGltf(kDemo);
  ASSERT_TRUE(scene) << scene.status().toString();
  CancelAt always;
  charts::UnwrapOptions u;
  u.target_resolution = 32;
  u.progress = &always;
  auto cancelled_unwrap = charts::unwrap(*scene, u);
  ASSERT_FALSE(cancelled_unwrap);
  EXPECT_EQ(cancelled_unwrap.status().code(), Code::kCancelled) << cancelled_unwrap.status().toString();

  u.progress = nullptr;
  ASSERT_TRUE(charts::unwrap(*scene, u));
  auto cancelled_surfels = surfels::placeSurfels(*scene, {.count = 4096, .progress = &always});
  ASSERT_FALSE(cancelled_surfels);
  EXPECT_EQ(cancelled_surfels.status().code(), Code::kCancelled);

  auto placed = surfels::placeSurfels(*scene, {.count = 4096});
  ASSERT_TRUE(placed);
  auto tree = hierarchy::buildTree(*placed, {.builder = hierarchy::Builder::kAgglomerative, .progress = &always});
  ASSERT_FALSE(tree);
  EXPECT_EQ(tree.status().code(), Code::kCancelled);

  auto accel = rt::Accel::build(*scene);
  ASSERT_TRUE(accel);
  auto lm = caches::placeLightmapCaches(*scene, *accel, {.resolution = 32, .validity = {.rays = 16, .progress = &always}});
  ASSERT_FALSE(lm);
  EXPECT_EQ(lm.status().code(), Code::kCancelled);
  auto grid = caches::placeGridCaches(*scene, *accel, {.resolution = 4, .validity = {.rays = 16, .progress = &always}});
  ASSERT_FALSE(grid);
  EXPECT_EQ(grid.status().code(), Code::kCancelled);
}

TEST(PrecomputeBudgets, CancelledRunStopsAtTheStage) {
  for (const char* stage : {"unwrap", "surfels", "hierarchy", "caches"}) {
    auto scene = scene::loadGltf(kDemo);
    ASSERT_TRUE(scene);
    CancelAt at(stage);
    auto p = run(*scene, small(), &at);
    ASSERT_FALSE(p) << stage;
    EXPECT_EQ(p.status().code(), Code::kCancelled) << stage << ": " << p.status().toString();
    ASSERT_FALSE(at.begun.empty());
    EXPECT_EQ(at.begun.back(), stage) << "a later stage began after the cancellation";
  }
}

TEST(PrecomputeBudgets, TexelAndLinkBudgetsAreCheckedBeforeTheWork) {
  auto scene = scene::loadGltf(kDemo);
  ASSERT_TRUE(scene);
  PrecomputeOptions o = small();
  o.limits.max_texels = 32 * 32 - 1;
  CancelAt never("none");
  auto texels = run(*scene, o, &never);
  ASSERT_FALSE(texels);
  EXPECT_EQ(texels.status().code(), Code::kResourceExhausted);
  EXPECT_NE(texels.status().message().find("32x32 = 1024 texels"), std::string::npos) << texels.status().message();
  EXPECT_NE(texels.status().message().find("max_texels"), std::string::npos);
  ASSERT_EQ(never.begun.size(), 1u);  // refused inside the unwrap, before packing

  scene = scene::loadGltf(kDemo);
  o = small();
  o.limits.max_link_bytes = 10000;  // a few caches' worth
  CancelAt record("none");
  auto links = run(*scene, o, &record);
  ASSERT_FALSE(links);
  EXPECT_EQ(links.status().code(), Code::kResourceExhausted);
  EXPECT_NE(links.status().message().find("max_link_bytes"), std::string::npos) << links.status().message();
  for (const auto& stage : record.begun) EXPECT_EQ(stage.find("links"), std::string::npos) << "links began";
  // The estimate is caches x links x (10 + 2 bands^2) bytes.
  EXPECT_EQ(linkBytesEstimate(1000, 128, 3), 1000u * 128u * 28u);
}

}  // namespace
}  // namespace lightlink::precompute
