// What an editor reads back from a real lightlinkd (issue 50): the current light set
// (GetLights, as the light-set JSON and as proto lights), the lightmap UVs a scene is lit with
// (GetLightmapUvs, per primitive and as a .glb), and the per-session idle timeout
// (--session-idle-timeout) that closes a scene no client names any more, consistently with
// sessions.json.
#include <signal.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

std::vector<std::string> flags(std::vector<std::string> extra = {}) {
  std::vector<std::string> f{"--backend", "cpu", "--bounces", "1"};
  f.insert(f.end(), extra.begin(), extra.end());
  return f;
}

v1::SceneRef refOf(const v1::SceneOpened& o) {
  v1::SceneRef r;
  r.set_scene_id(o.scene_id());
  r.set_token(o.scene_token());
  return r;
}

TEST(DaemonReadback, GetLightsReturnsTheCurrentSetAsJsonAndProtoAfterAnUpdate) {
  TempDir tmp;
  DaemonProcess d(tmp / "cache", flags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
  ASSERT_GT(opened.light_ids_size(), 0);
  const std::string id = opened.light_ids(0);

  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  auto* m = up.add_modify();
  m->set_id(id);
  m->mutable_position()->set_x(0.15f);
  m->mutable_position()->set_y(0.45f);
  m->mutable_position()->set_z(0.3f);
  m->set_intensity(7.5f);
  auto* a = up.add_add();
  a->set_id("spot_new");
  a->set_type(v1::LIGHT_TYPE_SPOT);
  a->mutable_position()->set_y(0.9f);
  a->mutable_direction()->set_y(-2.0f);  // normalised by the daemon
  a->set_outer_cone_angle(0.5f);
  a->set_baked(false);
  v1::UpdateLightsResponse ack;
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ack).ok()) << d.log();

  v1::GetLightsRequest rq;
  *rq.mutable_scene() = refOf(opened);
  v1::GetLightsResponse got;
  ASSERT_TRUE(rpc->GetLights(context().get(), rq, &got).ok()) << d.log();
  EXPECT_EQ(got.version(), ack.version());
  ASSERT_EQ(got.lights_size(), opened.light_ids_size() + 1);
  const auto& moved = got.lights(0);
  EXPECT_EQ(moved.id(), id);
  EXPECT_FLOAT_EQ(moved.position().x(), 0.15f);
  EXPECT_FLOAT_EQ(moved.position().z(), 0.3f);
  EXPECT_FLOAT_EQ(moved.intensity(), 7.5f);
  EXPECT_TRUE(moved.baked());
  const auto& spot = got.lights(got.lights_size() - 1);
  EXPECT_EQ(spot.id(), "spot_new");
  EXPECT_EQ(spot.type(), v1::LIGHT_TYPE_SPOT);
  EXPECT_FLOAT_EQ(spot.direction().y(), -1.0f);
  EXPECT_FLOAT_EQ(spot.outer_cone_angle(), 0.5f);
  EXPECT_TRUE(spot.has_color() && spot.has_range() && spot.has_inner_cone_angle()) << "every field set";
  EXPECT_FALSE(spot.baked());

  // The JSON is a light-set document of the one schema: given back to OpenScene it
  // reproduces the lights (same ids and values).
  const auto doc = nlohmann::json::parse(got.light_set_json());
  EXPECT_EQ(doc.at("version"), 1);
  ASSERT_EQ(doc.at("lights").size(), std::size_t(got.lights_size()));
  EXPECT_EQ(doc["lights"][0]["id"], id);
  EXPECT_FLOAT_EQ(doc["lights"][0]["position"][0].get<float>(), 0.15f);
  EXPECT_EQ(doc["lights"].back()["type"], "spot");
  auto again = cornellRequest();
  again.set_lightset_json(got.light_set_json());
  v1::SceneOpened reopened;
  ASSERT_TRUE(openScene(*rpc, again, &reopened).ok()) << d.log();
  *rq.mutable_scene() = refOf(reopened);
  v1::GetLightsResponse round;
  ASSERT_TRUE(rpc->GetLights(context().get(), rq, &round).ok());
  ASSERT_EQ(round.lights_size(), got.lights_size());
  for (int i = 0; i < got.lights_size(); ++i)
    EXPECT_EQ(round.lights(i).SerializeAsString(), got.lights(i).SerializeAsString()) << "light " << i;

  // A wrong token is refused like every scene call.
  rq.mutable_scene()->set_token("nope");
  const auto denied = rpc->GetLights(context().get(), rq, &round);
  EXPECT_EQ(denied.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_NE(denied.error_message().find("token"), std::string::npos) << denied.error_message();
}

TEST(DaemonReadback, GetLightmapUvsReturnsEveryPrimitivesUvsAndTheGlb) {
  TempDir tmp;
  // Small chunks, so the .glb and the larger meshes come in several messages.
  DaemonProcess d(tmp / "cache", flags({"--chunk-bytes", "4096"}));
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();

  v1::GetLightmapUvsRequest rq;
  *rq.mutable_scene() = refOf(opened);
  rq.set_gltf(true);
  auto ctx = context();
  auto reader = rpc->GetLightmapUvs(ctx.get(), rq);
  v1::LightmapUvsMessage msg;
  v1::LightmapUvsHeader header;
  std::map<std::uint32_t, v1::MeshLightmapUv> meshes;
  std::map<std::uint32_t, std::vector<float>> uv;
  std::map<std::uint32_t, std::vector<std::uint32_t>> indices;
  std::string glb;
  std::size_t mesh_messages = 0;
  while (reader->Read(&msg)) {
    mesh_messages += msg.has_mesh();
    if (msg.has_header()) header = msg.header();
    if (msg.has_mesh()) {
      const auto& m = msg.mesh();
      if (m.vertex_offset() == 0 && m.index_offset() == 0) meshes[m.index()] = m;
      auto& u = uv[m.index()];
      EXPECT_EQ(m.vertex_offset() * 2, u.size());
      u.resize(u.size() + m.uv().size() / 4);
      std::memcpy(u.data() + u.size() - m.uv().size() / 4, m.uv().data(), m.uv().size());
      auto& ix = indices[m.index()];
      EXPECT_EQ(m.index_offset(), ix.size());
      ix.resize(ix.size() + m.indices().size() / 4);
      std::memcpy(ix.data() + ix.size() - m.indices().size() / 4, m.indices().data(), m.indices().size());
      if (m.vertex_offset() > 0) meshes[m.index()].mutable_source_vertex()->MergeFrom(m.source_vertex());
    }
    if (msg.has_glb()) {
      EXPECT_EQ(msg.glb().offset(), glb.size());
      glb += msg.glb().data();
    }
  }
  ASSERT_TRUE(reader->Finish().ok()) << d.log();
  EXPECT_EQ(header.width(), opened.lightmap().width());
  EXPECT_EQ(header.height(), opened.lightmap().height());
  EXPECT_GT(header.texel_size_m(), 0.0f);
  EXPECT_TRUE(header.generated()) << "the Cornell box has no TEXCOORD_1: the daemon made them";
  ASSERT_EQ(meshes.size(), header.meshes());
  int lit = 0;
  for (const auto& [i, m] : meshes) {
    if (!m.lightmapped()) continue;
    ++lit;
    const std::size_t nv = uv[i].size() / 2;
    EXPECT_EQ(nv, m.vertex_count()) << m.name();
    EXPECT_EQ(indices[i].size(), m.index_count());
    EXPECT_EQ(indices[i].size() % 3, 0u);
    EXPECT_EQ(std::size_t(m.source_vertex_size()), nv) << "generated UVs split vertices: each names its source";
    for (std::uint32_t ix : indices[i]) ASSERT_LT(ix, nv) << m.name();
    for (float t : uv[i]) {
      ASSERT_GE(t, 0.0f);
      ASSERT_LE(t, 1.0f);
    }
    EXPECT_GE(m.node(), 0);
    EXPECT_GE(m.mesh(), 0);
  }
  EXPECT_GT(lit, 0);
  std::printf("%zu meshes (%d lightmapped) in %zu messages, .glb %zu bytes\n", meshes.size(), lit, mesh_messages,
              glb.size());
  ASSERT_EQ(glb.size(), header.glb_bytes());
  ASSERT_GT(glb.size(), 12u);
  EXPECT_EQ(glb.substr(0, 4), "glTF");
  // The .glb's JSON chunk names TEXCOORD_1.
  EXPECT_NE(glb.find("TEXCOORD_1"), std::string::npos);
  // Nothing of the temporary write stays in the cache.
  for (const auto& e : std::filesystem::directory_iterator(tmp / "cache"))
    EXPECT_EQ(e.path().filename().string().rfind(".uvs.", 0), std::string::npos) << e.path();
}

TEST(DaemonReadback, IdleScenesAreClosedAndForgottenWhileSubscribedOnesStay) {
  TempDir tmp;
  v1::SceneOpened idle, watched;
  {
    DaemonProcess d(tmp / "cache", flags({"--session-idle-timeout", "1.5"}));
    ASSERT_TRUE(d.ok()) << d.error();
    auto rpc = d.rpc();
    ASSERT_TRUE(openScene(*rpc, cornellRequest(), &idle).ok()) << d.log();
    ASSERT_TRUE(openScene(*rpc, cornellRequest(), &watched).ok()) << d.log();
    // A subscriber keeps its scene alive without sending anything.
    v1::SubscribeRequest sr;
    *sr.mutable_scene() = refOf(watched);
    sr.mutable_spec()->set_skip_grid(true);
    auto sctx = context(30000);
    auto stream = rpc->Subscribe(sctx.get(), sr);
    v1::ResultMessage first;
    ASSERT_TRUE(stream->Read(&first));
    std::this_thread::sleep_for(std::chrono::milliseconds(2500));

    v1::GetLightsRequest rq;
    *rq.mutable_scene() = refOf(idle);
    v1::GetLightsResponse got;
    const auto gone = rpc->GetLights(context().get(), rq, &got);
    EXPECT_EQ(gone.error_code(), grpc::StatusCode::NOT_FOUND);
    EXPECT_NE(gone.error_message().find("--session-idle-timeout"), std::string::npos) << gone.error_message();
    *rq.mutable_scene() = refOf(watched);
    EXPECT_TRUE(rpc->GetLights(context().get(), rq, &got).ok()) << d.log();
    v1::ListScenesResponse list;
    ASSERT_TRUE(rpc->ListScenes(context().get(), {}, &list).ok());
    ASSERT_EQ(list.scenes_size(), 1);
    EXPECT_EQ(list.scenes(0).scene_id(), watched.scene_id());
    EXPECT_NE(d.log().find("scene_idle_closed"), std::string::npos) << d.log();
    sctx->TryCancel();
    v1::ResultMessage rest;
    while (stream->Read(&rest)) {
    }
    stream->Finish();
    EXPECT_EQ(d.signalAndWait(SIGTERM), 0) << d.log();
  }
  // sessions.json forgot the idle scene: a restart brings back only the watched one.
  DaemonProcess d(tmp / "cache", flags({"--session-idle-timeout", "0"}));
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::ListScenesResponse list;
  ASSERT_TRUE(rpc->ListScenes(context().get(), {}, &list).ok());
  ASSERT_EQ(list.scenes_size(), 1) << d.log();
  EXPECT_EQ(list.scenes(0).scene_id(), watched.scene_id());
}

TEST(DaemonReadback, ABadIdleTimeoutIsRefusedNamingTheFlag) {
  TempDir tmp;
  std::string out;
  const int code = runDaemonToExit({"--cache-dir", (tmp / "c").string(), "--session-idle-timeout", "-3"}, &out);
  EXPECT_NE(code, 0);
  EXPECT_NE(out.find("--session-idle-timeout"), std::string::npos) << out;
}

}  // namespace
}  // namespace lightlink::testing
