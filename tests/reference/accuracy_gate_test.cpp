// The accuracy gate (issue 47, after Mitsuba's render tests): a fixed-seed, fixed-budget bake
// of two scenes against the path-traced reference at the same points, with tolerances tight
// enough that losing 3 % of the energy fails (checked below by feeding the gate a bake scaled
// by 0.97). Both sides are deterministic (fixed seeds, fixed sample counts), so the figures
// only move when the code does. On failure it writes the baked, reference and error maps as
// EXRs (lightmap layout, the compared texels only) into $LIGHTLINK_ACCURACY_OUT, or
// accuracy_gate/ in the build directory, and names the files.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <ImfArray.h>
#include <ImfRgbaFile.h>
#include <gtest/gtest.h>

#include "core/bake/bake_options.h"
#include "core/precompute/precompute.h"
#include "core/reference/compare.h"
#include "core/reference/reference.h"
#include "core/relight/direct_layer.h"
#include "core/relight/light_set.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"
#include "tests/common/scene_builders.h"
#include "tests/common/testing.h"

namespace lightlink::reference {
namespace {

namespace fs = std::filesystem;

// What the gate holds a scene to: the energy (mean baked / mean reference over the points)
// within [bias_lo, bias_hi], and the floored relative RMSE of the total at most max_rel_rmse.
struct Tolerance {
  double bias_lo = 0.0, bias_hi = 0.0, max_rel_rmse = 0.0;
};

// One scene baked and measured: per compared point its texel, baked and reference total.
struct Measured {
  int width = 0, height = 0;
  std::vector<std::uint32_t> texel;
  std::vector<glm::vec3> baked, reference;
};

constexpr std::size_t kMaxPoints = 512;
constexpr int kReferenceSamples = 1024;

// `s` gains its lightmap UVs (precompute unwraps it).
Measured bakeAndMeasure(scene::Scene& s, const relight::LightSet& lights) {
  Measured m;
  // The draft preset (what a CI bake uses), relit to convergence: the gate judges the method,
  // not the bounce cap.
  relight::RelightOptions converged;
  converged.max_bounces = 64;
  converged.bounce_threshold = 1e-4f;
  const std::vector<std::pair<std::string, std::string>> settings;
  auto options = bake::buildBakeOptions(settings, "draft", converged);
  EXPECT_TRUE(options) << options.status().toString();
  if (!options) return m;
  auto p = precompute::run(s, options->precompute);
  EXPECT_TRUE(p) << p.status().toString();
  if (!p) return m;
  auto accel = rt::Accel::build(s);
  EXPECT_TRUE(accel) << accel.status().toString();
  if (!accel) return m;
  auto relighter = relight::Relighter::create(s, *accel, *p);
  EXPECT_TRUE(relighter) << relighter.status().toString();
  if (!relighter) return m;
  auto res = relighter->relight(lights, options->relight);
  EXPECT_TRUE(res) << res.status().toString();
  if (!res) return m;

  const auto& lm = p->lightmap;
  m.width = lm.width;
  m.height = lm.height;
  std::vector<std::uint32_t> valid;
  for (std::uint32_t c = 0; c < lm.size(); ++c)
    if (lm.valid[c]) valid.push_back(c);
  const std::size_t stride = std::max<std::size_t>(1, (valid.size() + kMaxPoints - 1) / kMaxPoints);
  std::vector<glm::vec3> pos, nrm;
  std::vector<glm::vec3> direct;
  relight::directAtLightmapSize(*res, direct);
  for (std::size_t k = 0; k < valid.size(); k += stride) {
    const std::uint32_t c = valid[k];
    pos.push_back(lm.position[c]);
    nrm.push_back(lm.normal[c]);
    m.texel.push_back(lm.texel[c]);
    m.baked.push_back(res->lightmapIndirect(lm.texel[c], lm.normal[c]) + direct[lm.texel[c]]);
  }
  auto renderer = ReferenceRenderer::create(s, *accel, lights);
  EXPECT_TRUE(renderer) << renderer.status().toString();
  if (!renderer) return m;
  ReferenceOptions ro;
  ro.min_samples = kReferenceSamples;
  ro.max_samples = kReferenceSamples;
  ro.target_rel_error = 0.0f;  // a fixed budget: every point gets exactly kReferenceSamples
  ro.seed = 47;
  auto est = renderer->irradiance({pos, nrm}, ro);
  EXPECT_TRUE(est) << est.status().toString();
  if (!est) return m;
  for (const auto& e : *est) m.reference.push_back(e.total);
  return m;
}

// The gate's verdict: empty when the scene passes, else what failed.
std::string verdict(const ErrorStats& st, const Tolerance& tol) {
  std::string why;
  if (!(st.bias >= tol.bias_lo && st.bias <= tol.bias_hi))
    why += "energy " + std::to_string(st.bias) + " outside [" + std::to_string(tol.bias_lo) + ", " +
           std::to_string(tol.bias_hi) + "]; ";
  if (!(st.rel_rmse <= tol.max_rel_rmse))
    why += "total rel. RMSE " + std::to_string(st.rel_rmse) + " above " + std::to_string(tol.max_rel_rmse) + "; ";
  return why;
}

void writeExr(const fs::path& path, const Measured& m, const std::vector<glm::vec3>& values) {
  std::vector<Imf::Rgba> px(std::size_t(m.width) * std::size_t(m.height), Imf::Rgba(0, 0, 0, 0));
  for (std::size_t k = 0; k < m.texel.size(); ++k)
    px[m.texel[k]] = Imf::Rgba(values[k].x, values[k].y, values[k].z, 1.0f);
  Imf::RgbaOutputFile out(path.c_str(), m.width, m.height, Imf::WRITE_RGBA);
  out.setFrameBuffer(px.data(), 1, std::size_t(m.width));
  out.writePixels(m.height);
}

// Writes baked, reference and |baked - reference| maps; returns where.
std::string writeFailureImages(const std::string& scene, const Measured& m) {
  const char* env = std::getenv("LIGHTLINK_ACCURACY_OUT");
  const fs::path root = env != nullptr && *env != '\0' ? fs::path(env) : fs::path(LIGHTLINK_BINARY_DIR) / "accuracy_gate";
  const fs::path dir = root / scene;
  std::error_code ec;
  fs::create_directories(dir, ec);
  std::vector<glm::vec3> error(m.baked.size());
  for (std::size_t k = 0; k < error.size(); ++k) error[k] = glm::abs(m.baked[k] - m.reference[k]);
  try {
    writeExr(dir / "baked.exr", m, m.baked);
    writeExr(dir / "reference.exr", m, m.reference);
    writeExr(dir / "error.exr", m, error);
  } catch (const std::exception& e) {
    return std::string("(could not write the EXRs: ") + e.what() + ")";
  }
  return fs::absolute(dir).string() + "/{baked,reference,error}.exr";
}

void gate(const std::string& name, scene::Scene& s, const relight::LightSet& lights, const Tolerance& tol) {
  const Measured m = bakeAndMeasure(s, lights);
  ASSERT_FALSE(m.reference.empty());
  ASSERT_EQ(m.baked.size(), m.reference.size());
  const ErrorStats st = errorStats(m.baked, m.reference);
  const std::string why = verdict(st, tol);
  EXPECT_TRUE(why.empty()) << name << ": " << why << "(" << st.points << " points; baked, reference and error maps: "
                           << writeFailureImages(name, m) << ")";
  // Tight enough: the same bake with 3 % of its energy lost must fail.
  std::vector<glm::vec3> dimmer(m.baked);
  for (auto& b : dimmer) b *= 0.97f;
  EXPECT_FALSE(verdict(errorStats(dimmer, m.reference), tol).empty())
      << name << ": the gate passes a bake that lost 3 % of its energy (bias " << st.bias << ")";
  std::printf("[ gate     ] %s: %zu points, energy %.4f, total rel. RMSE %.4f, p95 %.4f\n", name.c_str(), st.points,
              st.bias, st.rel_rmse, st.p95_rel_error);
}

// The tolerances, from the figures the gate prints (draft preset, relit to convergence):
// energy 0.9745 and 0.9729 (the draft bake keeps 97.3-97.5 % of the reference's light), total
// rel. RMSE 6.9 % and 3.8 %. Each lower energy bound sits less than 3 % below its figure, so
// a 3 % loss fails (checked in gate()); move a bound only with the change that moves a figure,
// and say why in that commit.
constexpr Tolerance kCornellBox{.bias_lo = 0.96, .bias_hi = 1.02, .max_rel_rmse = 0.09};
constexpr Tolerance kRoomWithABlock{.bias_lo = 0.96, .bias_hi = 1.02, .max_rel_rmse = 0.06};

TEST(AccuracyGate, BundledCornellBox) {
  auto s = scene::loadScene(std::string(LIGHTLINK_SOURCE_DIR) + "/clients/demo/cornell_box.gltf");
  ASSERT_TRUE(s) << s.status().toString();
  gate("cornell_box", *s, relight::LightSet::fromSceneLights(s->lights), kCornellBox);
}

// A closed room (4 x 2.5 x 3 m, grey 0.5) with a block on its floor and a point light beside
// it: contacts all round and a shadowed side.
TEST(AccuracyGate, RoomWithABlock) {
  scene::Scene s;
  const int grey = testing::addMaterial(s, glm::vec3(0.5f));
  testing::addBox(s, {0, 0, 0}, {4, 2.5f, 3}, /*inward=*/true, grey);
  testing::addBox(s, {1.5f, 0.0f, 1.0f}, {2.5f, 0.8f, 2.0f}, /*inward=*/false, grey);
  s.source_path = "room-with-a-block";
  testing::finishScene(s);
  relight::LightSet lights;
  relight::LightEntry lamp;
  lamp.id = "lamp";
  lamp.light.kind = scene::Light::Kind::kPoint;
  lamp.light.position = {0.6f, 1.4f, 1.5f};
  lamp.light.intensity = 20.0f;
  ASSERT_TRUE(lights.add(lamp));
  gate("room_with_a_block", s, lights, kRoomWithABlock);
}

// What a failure leaves behind: the three maps, in the lightmap's layout, readable.
TEST(AccuracyGate, AFailureWritesTheBakedReferenceAndErrorMaps) {
  testing::TempDir tmp;
  ASSERT_EQ(setenv("LIGHTLINK_ACCURACY_OUT", tmp.path().c_str(), 1), 0);
  Measured m;
  m.width = 4;
  m.height = 2;
  m.texel = {1, 6};
  m.baked = {glm::vec3(1.0f, 2.0f, 3.0f), glm::vec3(0.5f)};
  m.reference = {glm::vec3(1.0f, 1.0f, 1.0f), glm::vec3(0.25f)};
  const std::string where = writeFailureImages("tiny", m);
  unsetenv("LIGHTLINK_ACCURACY_OUT");
  EXPECT_NE(where.find(tmp.path().string()), std::string::npos) << where;
  const auto texel = [&](const char* file, int t) {
    Imf::RgbaInputFile in((tmp.path() / "tiny" / file).c_str());
    const Imath::Box2i dw = in.dataWindow();
    EXPECT_EQ(dw.max.x - dw.min.x + 1, m.width);
    EXPECT_EQ(dw.max.y - dw.min.y + 1, m.height);
    Imf::Array2D<Imf::Rgba> px(m.height, m.width);
    in.setFrameBuffer(&px[0][0], 1, std::size_t(m.width));
    in.readPixels(dw.min.y, dw.max.y);
    const Imf::Rgba& p = px[t / m.width][t % m.width];
    return glm::vec3(float(p.r), float(p.g), float(p.b));
  };
  EXPECT_EQ(texel("baked.exr", 1), glm::vec3(1.0f, 2.0f, 3.0f));
  EXPECT_EQ(texel("reference.exr", 6), glm::vec3(0.25f));
  EXPECT_EQ(texel("error.exr", 1), glm::vec3(0.0f, 1.0f, 2.0f));
  EXPECT_EQ(texel("error.exr", 0), glm::vec3(0.0f));  // not compared: black
}

}  // namespace
}  // namespace lightlink::reference
