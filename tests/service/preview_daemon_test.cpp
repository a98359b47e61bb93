// The instant preview through a real lightlinkd (docs/service.md "Preview while the precompute
// runs"): the first version of a newly opened scene is the preview grid (ResultKind says so),
// a light change during the precompute re-lights the preview, and the linked result replaces
// it under a later version with every update in it.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>

#include <gtest/gtest.h>

#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

using Clock = std::chrono::steady_clock;

std::vector<std::string> previewFlags() {
  return {"--backend", "cpu", "--bounces", "2", "--log-level", "debug", "--preview", "on"};
}

v1::SceneRef refOf(const v1::SceneOpened& o) {
  v1::SceneRef r;
  r.set_scene_id(o.scene_id());
  r.set_token(o.scene_token());
  return r;
}

// The Cornell request with a precompute slow enough (a few seconds on 2 cores) that calls
// made after the preview land while the links are still being computed.
v1::OpenSceneRequest slowCornell() {
  v1::OpenSceneRequest r = cornellRequest();
  r.set_surfels(8192);
  r.set_rays(2048);
  r.set_links(64);
  return r;
}

// The newest result of a scene (GetTextures with nothing seen), full precision.
Result newest(LightlinkRpc& rpc, const v1::SceneOpened& o, std::uint64_t last_seen = 0) {
  v1::GetTexturesRequest rq;
  *rq.mutable_scene() = refOf(o);
  rq.set_last_seen_version(last_seen);
  rq.mutable_spec()->set_precision(v1::PRECISION_FLOAT);
  auto ctx = context();
  auto reader = rpc.GetTextures(ctx.get(), rq);
  Result r;
  std::string err;
  const grpc::Status s = readOne(reader.get(), r, &err);
  EXPECT_TRUE(s.ok()) << s.error_message();
  EXPECT_TRUE(err.empty()) << err;
  return r;
}

// Sum of the grid's L00 coefficients over the three channels: how much light the grid holds.
double gridL00(const Result& r) {
  const auto it = r.payloads.find(v1::PAYLOAD_GRID_SH);
  if (it == r.payloads.end()) return 0.0;
  const auto v = decodeValues(it->second, v1::PRECISION_FLOAT);
  const std::size_t nc = std::size_t(r.header.bands()) * r.header.bands();
  double sum = 0.0;
  for (std::size_t i = 0; i < v.size(); i += nc) sum += v[i];
  return sum;
}

TEST(DaemonPreview, FirstVersionIsThePreviewThenTheLinkedResultWithTheUpdatesMadeMeanwhile) {
  TempDir tmp;
  DaemonProcess d(tmp / "cache", previewFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  auto octx = context(120000);
  const auto t0 = Clock::now();
  auto open = rpc->OpenScene(octx.get(), slowCornell());
  v1::OpenSceneProgress m;
  std::optional<v1::SceneOpened> preview, opened;
  double preview_s = 0.0;
  Result first, relit;
  v1::UpdateLightsResponse ur;
  bool updated_during_preview = false;
  while (open->Read(&m)) {
    if (m.has_preview()) {
      ASSERT_FALSE(preview) << "one preview announcement";
      ASSERT_FALSE(opened);
      preview = m.preview();
      preview_s = std::chrono::duration<double>(Clock::now() - t0).count();
      // The scene is readable now, while OpenScene goes on.
      first = newest(*rpc, *preview);
      EXPECT_EQ(first.header.version(), preview->version());
      EXPECT_EQ(first.header.kind(), v1::RESULT_KIND_INSTANT_PREVIEW);
      EXPECT_TRUE(first.header.preview());
      EXPECT_EQ(first.header.lightmap().width(), 0) << "a preview has no lightmap";
      EXPECT_EQ(first.payloads.count(v1::PAYLOAD_LIGHTMAP_SH), 0u);
      ASSERT_TRUE(first.header.grid().present());
      const std::size_t points = std::size_t(first.header.grid().nx()) * first.header.grid().ny() * first.header.grid().nz();
      EXPECT_EQ(first.payloads[v1::PAYLOAD_GRID_SH].size(), points * 3 * 9 * 4);
      EXPECT_EQ(first.payloads[v1::PAYLOAD_GRID_VALID].size(), points);
      for (float v : decodeValues(first.payloads[v1::PAYLOAD_GRID_SH], v1::PRECISION_FLOAT)) ASSERT_TRUE(std::isfinite(v));
      EXPECT_GT(gridL00(first), 0.0);
      // A light change while the links are computed: the preview is re-lit with it.
      v1::UpdateLightsRequest up;
      *up.mutable_scene() = refOf(*preview);
      v1::Light* key = up.add_add();
      key->set_id("key");
      key->set_type(v1::LIGHT_TYPE_POINT);
      key->mutable_position()->set_x(0.0f);
      key->mutable_position()->set_y(0.5f);
      key->mutable_position()->set_z(0.0f);
      key->set_intensity(20.0f);
      up.set_wait_ms(10000);
      ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok()) << d.log();
      EXPECT_EQ(ur.version(), preview->version() + 1);
      EXPECT_TRUE(ur.relit());
      relit = newest(*rpc, *preview);
      updated_during_preview = relit.header.kind() == v1::RESULT_KIND_INSTANT_PREVIEW;
      // Reading the scene back while it shows its preview: the light set is there at once; the
      // lightmap UVs once the precompute is done (UNAVAILABLE before, never a crash).
      v1::GetLightsRequest gl;
      *gl.mutable_scene() = refOf(*preview);
      v1::GetLightsResponse lights;
      ASSERT_TRUE(rpc->GetLights(context().get(), gl, &lights).ok()) << d.log();
      EXPECT_GE(lights.version(), ur.version());
      EXPECT_TRUE(std::any_of(lights.lights().begin(), lights.lights().end(),
                              [](const v1::Light& l) { return l.id() == "key"; }));
      v1::GetLightmapUvsRequest gu;
      *gu.mutable_scene() = refOf(*preview);
      auto uctx = context();
      auto uvs = rpc->GetLightmapUvs(uctx.get(), gu);
      v1::LightmapUvsMessage um;
      while (uvs->Read(&um)) {
      }
      const auto us = uvs->Finish();
      EXPECT_TRUE(us.ok() || (us.error_code() == grpc::StatusCode::UNAVAILABLE &&
                              us.error_message().find("instant preview") != std::string::npos))
          << us.error_code() << " " << us.error_message();
    }
    if (m.has_opened()) opened = m.opened();
  }
  ASSERT_TRUE(open->Finish().ok()) << d.log();
  ASSERT_TRUE(preview) << "no preview announced\n" << d.log();
  ASSERT_TRUE(opened);
  std::printf("[ preview ] Cornell: preview %.3f s after OpenScene, linked result %.3f s after\n", preview_s,
              std::chrono::duration<double>(Clock::now() - t0).count());
  EXPECT_EQ(opened->scene_id(), preview->scene_id());
  EXPECT_EQ(preview->version(), 1u);
  EXPECT_EQ(preview->lightmap().width(), 0);
  EXPECT_TRUE(preview->grid().present());
  // The update was made while the links were computed (the precompute takes seconds).
  ASSERT_TRUE(updated_during_preview) << "the update landed after the linked result; slowCornell() is too fast here";
  EXPECT_EQ(relit.header.version(), ur.version());
  EXPECT_GT(gridL00(relit), 1.2 * gridL00(first)) << "the preview reflects the added light";

  // The linked result replaces the preview under the next version, with the update in it.
  EXPECT_EQ(opened->version(), ur.version() + 1);
  EXPECT_GT(opened->lightmap().width(), 0);
  const auto& ids = opened->light_ids();
  EXPECT_NE(std::find(ids.begin(), ids.end(), "key"), ids.end());
  const Result linked = newest(*rpc, *opened);
  EXPECT_EQ(linked.header.version(), opened->version());
  EXPECT_EQ(linked.header.kind(), v1::RESULT_KIND_LINKED);
  EXPECT_FALSE(linked.header.preview());
  EXPECT_GT(linked.header.lightmap().width(), 0);
  EXPECT_GT(linked.payloads.at(v1::PAYLOAD_LIGHTMAP_SH).size(), 0u);
  EXPECT_EQ(linked.header.grid().nx(), relit.header.grid().nx()) << "the preview's grid is the linked one";
  // Same lights, linked and preview: the same light within the preview's accuracy.
  const double ratio = gridL00(linked) / gridL00(relit);
  EXPECT_GT(ratio, 0.6);
  EXPECT_LT(ratio, 1.6);

  // Stats count the previews apart from the relights.
  v1::StatsRequest sr;
  *sr.mutable_scene() = refOf(*opened);
  v1::StatsResponse stats;
  ASSERT_TRUE(rpc->Stats(context().get(), sr, &stats).ok());
  ASSERT_EQ(stats.scene_size(), 1);
  EXPECT_EQ(stats.scene(0).instant_previews(), 2u);
}

TEST(DaemonPreview, ASubscriberGetsThePreviewThenTheLinkedResultInFull) {
  TempDir tmp;
  DaemonProcess d(tmp / "cache", previewFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  auto octx = context(120000);
  auto open = rpc->OpenScene(octx.get(), slowCornell());
  v1::OpenSceneProgress m;
  std::optional<v1::SceneOpened> opened;
  std::unique_ptr<grpc::ClientContext> sctx;
  std::unique_ptr<grpc::ClientReader<v1::ResultMessage>> stream;
  std::optional<ResultReader> reader;
  Result r;
  while (open->Read(&m)) {
    if (m.has_preview()) {
      v1::SubscribeRequest sub;
      *sub.mutable_scene() = refOf(m.preview());
      sub.set_deltas(true);
      sctx = context(60000);
      stream = rpc->Subscribe(sctx.get(), sub);
      reader.emplace(stream.get());
      ASSERT_TRUE(reader->next(r)) << reader->error();
      EXPECT_EQ(r.header.kind(), v1::RESULT_KIND_INSTANT_PREVIEW);
      EXPECT_EQ(r.header.version(), m.preview().version());
    }
    if (m.has_opened()) opened = m.opened();
  }
  ASSERT_TRUE(open->Finish().ok()) << d.log();
  ASSERT_TRUE(reader && opened);
  // The next result on the stream is the linked one, sent whole (its payloads differ from the
  // preview's: a lightmap now), with every payload the header announces.
  ASSERT_TRUE(reader->next(r)) << reader->error();
  EXPECT_EQ(r.header.kind(), v1::RESULT_KIND_LINKED);
  EXPECT_EQ(r.header.version(), opened->version());
  EXPECT_FALSE(r.header.delta());
  EXPECT_GT(r.header.lightmap().width(), 0);
  EXPECT_EQ(r.payloads.count(v1::PAYLOAD_LIGHTMAP_SH), 1u);
  EXPECT_EQ(r.payloads.count(v1::PAYLOAD_GRID_SH), 1u);
  sctx->TryCancel();
}

TEST(DaemonPreview, CloseDuringThePrecomputeStopsItAndTheOpenFails) {
  TempDir tmp;
  DaemonProcess d(tmp / "cache", previewFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  auto octx = context(120000);
  auto open = rpc->OpenScene(octx.get(), slowCornell());
  v1::OpenSceneProgress m;
  bool closed = false;
  Clock::time_point closed_at;
  while (open->Read(&m)) {
    EXPECT_FALSE(m.has_opened());
    if (!m.has_preview()) continue;
    v1::CloseSceneRequest c;
    *c.mutable_scene() = refOf(m.preview());
    v1::CloseSceneResponse cr;
    ASSERT_TRUE(rpc->CloseScene(context().get(), c, &cr).ok());
    closed = true;
    closed_at = Clock::now();
  }
  const grpc::Status s = open->Finish();
  ASSERT_TRUE(closed) << d.log();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND) << s.error_message();
  // The precompute polls for cancellation per chunk: it stops soon, not after its seconds.
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - closed_at).count(), 2.0);
  v1::ListScenesResponse list;
  ASSERT_TRUE(rpc->ListScenes(context().get(), {}, &list).ok());
  EXPECT_EQ(list.scenes_size(), 0);
}

TEST(DaemonPreview, OffPerRequestOrPerDaemon) {
  TempDir tmp;
  for (const bool daemon_on : {true, false}) {
    auto flags = previewFlags();
    flags.back() = daemon_on ? "on" : "off";
    DaemonProcess d(tmp / (daemon_on ? "on" : "off"), flags);
    ASSERT_TRUE(d.ok()) << d.error();
    auto rpc = d.rpc();
    v1::OpenSceneRequest r = cornellRequest();
    if (daemon_on) r.set_preview(false);
    auto ctx = context(60000);
    auto open = rpc->OpenScene(ctx.get(), r);
    v1::OpenSceneProgress m;
    std::optional<v1::SceneOpened> opened;
    while (open->Read(&m)) {
      EXPECT_FALSE(m.has_preview());
      if (m.has_opened()) opened = m.opened();
    }
    ASSERT_TRUE(open->Finish().ok()) << d.log();
    ASSERT_TRUE(opened);
    EXPECT_EQ(opened->version(), 1u) << "without a preview the first version is the linked result";
    EXPECT_EQ(newest(*rpc, *opened).header.kind(), v1::RESULT_KIND_LINKED);
  }
}

}  // namespace
}  // namespace lightlink::testing
