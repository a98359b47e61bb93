// Lighting scenarios through a real lightlinkd (docs/service.md "Lighting scenarios"): named
// light sets per scene (SetScenario), switched and blended by name (UseScenarios) as new
// versions; the blend's lightmap is the blend of the scenarios' lightmaps; scenarios survive
// a restart; bad requests are refused naming what is wrong, with nothing changed.
#include <signal.h>

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

std::vector<std::string> flags() { return {"--backend", "cpu", "--bounces", "2", "--log-level", "debug"}; }

v1::SceneRef refOf(const v1::SceneOpened& o) {
  v1::SceneRef r;
  r.set_scene_id(o.scene_id());
  r.set_token(o.scene_token());
  return r;
}

std::vector<float> lightmapOf(LightlinkRpc& rpc, const v1::SceneOpened& o, std::uint64_t* version) {
  v1::GetTexturesRequest rq;
  *rq.mutable_scene() = refOf(o);
  rq.mutable_spec()->set_precision(v1::PRECISION_FLOAT);
  auto ctx = context();
  auto reader = rpc.GetTextures(ctx.get(), rq);
  Result r;
  std::string err;
  EXPECT_TRUE(readOne(reader.get(), r, &err).ok()) << err;
  *version = r.header.version();
  return decodeValues(r.payloads[v1::PAYLOAD_LIGHTMAP_SH], v1::PRECISION_FLOAT);
}

grpc::Status setScenario(LightlinkRpc& rpc, const v1::SceneOpened& o, const std::string& name,
                         const std::string& json, v1::SetScenarioResponse* out = nullptr) {
  v1::SetScenarioRequest rq;
  *rq.mutable_scene() = refOf(o);
  rq.set_name(name);
  rq.set_light_set_json(json);
  v1::SetScenarioResponse resp;
  return rpc.SetScenario(context().get(), rq, out ? out : &resp);
}

grpc::Status use(LightlinkRpc& rpc, const v1::SceneOpened& o, std::vector<std::pair<std::string, float>> weights,
                 v1::UpdateLightsResponse* out) {
  v1::UseScenariosRequest rq;
  *rq.mutable_scene() = refOf(o);
  for (const auto& [n, w] : weights) {
    auto* x = rq.add_weights();
    x->set_name(n);
    x->set_weight(w);
  }
  rq.set_wait_ms(30000);
  return rpc.UseScenarios(context().get(), rq, out);
}

const char* kDay = R"({"version": 1, "lights": [{"id": "sun", "type": "point", "position": [-0.2, 0.4, 0.0],
                       "intensity": 3}], "sky": {"radiance": [0.2, 0.3, 0.5]}})";
const char* kNight = R"({"version": 1, "lights": [{"id": "lamp", "type": "point", "position": [0.2, 0.2, 0.1],
                         "intensity": 0.5, "color": [1.0, 0.6, 0.3]}]})";

TEST(DaemonScenarios, SwitchAndBlendByNameAndTheBlendIsTheBlendOfTheResults) {
  TempDir tmp;
  v1::SceneOpened opened;
  std::uint64_t blend_version = 0;
  {
    DaemonProcess d(tmp / "cache", flags());
    ASSERT_TRUE(d.ok()) << d.error();
    auto rpc = d.rpc();
    ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
    ASSERT_TRUE(setScenario(*rpc, opened, "day", kDay).ok()) << d.log();
    v1::SetScenarioResponse names;
    ASSERT_TRUE(setScenario(*rpc, opened, "night", kNight, &names).ok());
    ASSERT_EQ(names.scenarios_size(), 2);
    EXPECT_EQ(names.scenarios(0), "day");
    EXPECT_EQ(names.scenarios(1), "night");

    v1::UpdateLightsResponse day_v, night_v, blend_v;
    std::uint64_t version = 0;
    ASSERT_TRUE(use(*rpc, opened, {{"day", 1.0f}}, &day_v).ok()) << d.log();
    ASSERT_TRUE(day_v.relit());
    const auto day = lightmapOf(*rpc, opened, &version);
    EXPECT_EQ(version, day_v.version());
    ASSERT_TRUE(use(*rpc, opened, {{"night", 1.0f}}, &night_v).ok());
    EXPECT_GT(night_v.version(), day_v.version());
    const auto night = lightmapOf(*rpc, opened, &version);
    ASSERT_TRUE(use(*rpc, opened, {{"day", 0.25f}, {"night", 0.75f}}, &blend_v).ok());
    const auto blend = lightmapOf(*rpc, opened, &version);
    blend_version = blend_v.version();
    ASSERT_EQ(blend.size(), day.size());
    ASSERT_EQ(blend.size(), night.size());
    double err = 0.0, scale = 0.0, differ = 0.0;
    for (std::size_t i = 0; i < blend.size(); ++i) {
      const double want = 0.25 * day[i] + 0.75 * night[i];
      err = std::max(err, std::abs(blend[i] - want));
      scale = std::max(scale, std::abs(want));
      differ = std::max(differ, double(std::abs(day[i] - night[i])));
    }
    EXPECT_GT(differ, 0.1 * scale) << "the scenarios light the room differently";
    EXPECT_LT(err, 1e-3 * scale) << "blend vs the blend of the switched results";
    std::printf("blend vs 0.25 day + 0.75 night: max error %.3g of max %.3g\n", err, scale);

    v1::ListScenesResponse list;
    ASSERT_TRUE(rpc->ListScenes(context().get(), {}, &list).ok());
    ASSERT_EQ(list.scenes_size(), 1);
    ASSERT_EQ(list.scenes(0).scenarios_size(), 2);
    EXPECT_EQ(d.signalAndWait(SIGTERM), 0) << d.log();
  }
  // A restart keeps the scenarios and the blended light set.
  DaemonProcess d(tmp / "cache", flags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::ListScenesResponse list;
  for (int i = 0; i < 200; ++i) {  // restored in the background
    list.Clear();
    ASSERT_TRUE(rpc->ListScenes(context().get(), {}, &list).ok());
    if (list.scenes_size() == 1 && list.scenes(0).backend() != "restoring") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_EQ(list.scenes_size(), 1);
  EXPECT_EQ(list.scenes(0).version(), blend_version);
  ASSERT_EQ(list.scenes(0).scenarios_size(), 2) << d.log();
  v1::UpdateLightsResponse again;
  ASSERT_TRUE(use(*rpc, opened, {{"night", 1.0f}}, &again).ok()) << d.log();
  EXPECT_GT(again.version(), blend_version);
}

TEST(DaemonScenarios, BadRequestsAreRefusedNamingWhatIsWrongAndChangeNothing) {
  TempDir tmp;
  DaemonProcess d(tmp / "cache", flags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
  ASSERT_TRUE(setScenario(*rpc, opened, "day", kDay).ok());
  const auto refused = [](const grpc::Status& s, grpc::StatusCode code, const std::string& what) {
    EXPECT_EQ(s.error_code(), code) << what << ": " << s.error_message();
    EXPECT_NE(s.error_message().find(what), std::string::npos) << s.error_message();
  };
  refused(setScenario(*rpc, opened, "../etc", kDay), grpc::StatusCode::INVALID_ARGUMENT, "must not start with '.'");
  refused(setScenario(*rpc, opened, "a b", kDay), grpc::StatusCode::INVALID_ARGUMENT, "only letters");
  refused(setScenario(*rpc, opened, "bad", "{\"version\": 1, \"lights\": ["), grpc::StatusCode::INVALID_ARGUMENT,
          "light_set_json");
  refused(setScenario(*rpc, opened, "bad", R"({"version": 1, "emissive": [{"material": 999, "scale": [1,1,1]}]})"),
          grpc::StatusCode::INVALID_ARGUMENT, "999");
  v1::SetScenarioRequest none;
  *none.mutable_scene() = refOf(opened);
  none.set_name("x");
  v1::SetScenarioResponse resp;
  refused(rpc->SetScenario(context().get(), none, &resp), grpc::StatusCode::INVALID_ARGUMENT, "source");
  none.set_remove(true);
  refused(rpc->SetScenario(context().get(), none, &resp), grpc::StatusCode::NOT_FOUND, "no scenario \"x\"");

  v1::ListScenesResponse before;
  ASSERT_TRUE(rpc->ListScenes(context().get(), {}, &before).ok());
  v1::UpdateLightsResponse ur;
  refused(use(*rpc, opened, {{"dusk", 1.0f}}, &ur), grpc::StatusCode::INVALID_ARGUMENT, "\"dusk\": no such scenario");
  refused(use(*rpc, opened, {{"day", -1.0f}}, &ur), grpc::StatusCode::INVALID_ARGUMENT, "outside");
  refused(use(*rpc, opened, {{"day", std::nanf("")}}, &ur), grpc::StatusCode::INVALID_ARGUMENT, "outside");
  refused(use(*rpc, opened, {}, &ur), grpc::StatusCode::INVALID_ARGUMENT, "no scenario named");
  v1::ListScenesResponse after;
  ASSERT_TRUE(rpc->ListScenes(context().get(), {}, &after).ok());
  EXPECT_EQ(after.scenes(0).version(), before.scenes(0).version()) << "a refused request makes no version";
  ASSERT_EQ(after.scenes(0).scenarios_size(), 1);

  // Removing works and is what the list says.
  v1::SetScenarioRequest rm;
  *rm.mutable_scene() = refOf(opened);
  rm.set_name("day");
  rm.set_remove(true);
  ASSERT_TRUE(rpc->SetScenario(context().get(), rm, &resp).ok());
  EXPECT_EQ(resp.scenarios_size(), 0);
  // Another scene's token does not reach this scene's scenarios.
  v1::SceneOpened forged = opened;
  forged.set_scene_token("not-the-token");
  refused(setScenario(*rpc, forged, "day", kDay), grpc::StatusCode::PERMISSION_DENIED, "");
}

}  // namespace
}  // namespace lightlink::testing
