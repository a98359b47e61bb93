// Light intensities from 1e-6 to 1e6 cd (DESIGN.md sec 6: no fp16 overflow or underflow
// silently clipping). What happens, measured: the relight works in float end to end (fp16
// holds only the link coefficients, which are bounded visibilities |c| <= ~4 whatever the
// lights), so every relight output scales linearly with the intensity over the whole range.
// fp16 enters again only when a result is written as a half EXR: values beyond 65504 are
// clamped and counted (WriteStats::clamped), and non-zero L00/direct values below the
// smallest normal half are counted too (WriteStats::underflowed), so neither end is silent.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <gtest/gtest.h>

#include "core/common/half.h"
#include "core/output/output.h"
#include "tests/common/testing.h"
#include "tests/stability/stability_fixture.h"

namespace lightlink::stability {
namespace {

struct Room {
  std::unique_ptr<Baked> baked;
  Room() {
    scene::Scene s;
    const int m = addMaterial(s, glm::vec3(0.7f, 0.5f, 0.3f));
    addBox(s, {0, 0, 0}, {3, 2, 3}, /*inward=*/true, m);
    addBox(s, {1.2f, 0.0f, 1.2f}, {1.8f, 0.8f, 1.8f}, /*inward=*/false, m);
    auto o = tinyOptions();
    o.grid = precompute::GridMode::kOn;
    baked = Baked::make(std::move(s), o);
  }
};

const Room& room() {
  static Room r;
  return r;
}

RelightResult relightAt(relight::Relighter& r, float intensity) {
  LightSet set;
  EXPECT_TRUE(set.add(pointLight("lamp", {0.6f, 1.5f, 0.7f}, intensity)));
  // Threshold 0: every intensity runs the same bounce count (the cap), so outputs compare
  // value by value.
  auto res = r.relight(set, {.max_bounces = 4, .bounce_threshold = 0.0f});
  EXPECT_TRUE(res) << res.status().toString();
  return std::move(res).value();
}

// Largest |a - k b| over an array of vec3s, relative to |k b| (values below 1e-6 of the
// array's peak compare against that floor).
double scaledDiff(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b, double k) {
  double peak = 0.0, worst = 0.0;
  for (const auto& v : b)
    for (int ch = 0; ch < 3; ++ch) peak = std::max(peak, std::abs(k * v[ch]));
  for (std::size_t i = 0; i < a.size(); ++i)
    for (int ch = 0; ch < 3; ++ch) {
      const double ref = k * b[i][ch];
      worst = std::max(worst, std::abs(a[i][ch] - ref) / std::max(std::abs(ref), 1e-6 * peak));
    }
  return worst;
}

// Same for SH arrays (3 * nc floats per cache): each coefficient relative to its channel's
// largest coefficient in that cache, since higher coefficients that nearly cancel carry
// rounding of the size of the L00 they are part of.
double scaledShDiff(const std::vector<float>& a, const std::vector<float>& b, double k, int nc) {
  double peak = 0.0, worst = 0.0;
  for (float v : b) peak = std::max(peak, std::abs(k * v));
  for (std::size_t g = 0; g + nc <= b.size(); g += std::size_t(nc)) {
    double scale = 1e-6 * peak;
    for (int i = 0; i < nc; ++i) scale = std::max(scale, std::abs(k * b[g + i]));
    for (int i = 0; i < nc; ++i) worst = std::max(worst, std::abs(a[g + i] - k * b[g + i]) / scale);
  }
  return worst;
}

TEST(StabilityIntensity, OutputsScaleLinearlyFromMicroToMegaCandela) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  relight::Relighter r = rm.baked->relighter();
  const RelightResult unit = relightAt(r, 1.0f);
  ASSERT_EQ(countBadValues(unit, "1 cd"), 0u);
  for (float intensity : {1e-6f, 1e-4f, 1e-2f, 1e2f, 1e4f, 1e6f}) {
    r.invalidate();
    const RelightResult res = relightAt(r, intensity);
    EXPECT_EQ(countBadValues(res, "intensity"), 0u) << intensity << " cd";
    EXPECT_TRUE(res.warnings.empty()) << intensity << " cd: " << res.warnings.front();
    ASSERT_EQ(res.bounce_log.size(), unit.bounce_log.size());
    const int nc = res.coeffCount();
    std::printf("%g cd: lightmap SH %.1e, grid SH %.1e, direct %.1e, radiosity %.1e\n", double(intensity),
                scaledShDiff(res.lightmap_sh, unit.lightmap_sh, intensity, nc),
                scaledShDiff(res.grid_sh, unit.grid_sh, intensity, nc), scaledDiff(res.direct, unit.direct, intensity),
                scaledDiff(res.surfel_radiosity, unit.surfel_radiosity, intensity));
    // Bound: 1e-5 relative (float rounding of the same operations on scaled inputs; a
    // flush to zero or a clip anywhere in the chain would show as 1e-2 .. 1).
    EXPECT_LE(scaledShDiff(res.lightmap_sh, unit.lightmap_sh, intensity, nc), 1e-5) << intensity << " cd";
    EXPECT_LE(scaledShDiff(res.grid_sh, unit.grid_sh, intensity, nc), 1e-5) << intensity << " cd";
    EXPECT_LE(scaledDiff(res.direct, unit.direct, intensity), 1e-5) << intensity << " cd";
    EXPECT_LE(scaledDiff(res.surfel_radiosity, unit.surfel_radiosity, intensity), 1e-5) << intensity << " cd";
    for (std::size_t k = 0; k < res.bounce_log.size(); ++k)
      EXPECT_NEAR(res.bounce_log[k].added_flux, intensity * unit.bounce_log[k].added_flux,
                  1e-5 * intensity * unit.bounce_log[k].added_flux);
  }
}

// Reads one half channel of an EXR back as floats.
std::vector<float> readHalfChannel(const std::string& path, const std::string& channel) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i dw = file.header().dataWindow();
  const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
  EXPECT_EQ(file.header().channels().findChannel(channel)->type, Imf::HALF);
  std::vector<half_bits> bits(std::size_t(w) * h);
  Imf::FrameBuffer fb;
  fb.insert(channel, Imf::Slice(Imf::HALF, reinterpret_cast<char*>(bits.data()), sizeof(half_bits),
                                sizeof(half_bits) * w));
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  std::vector<float> out(bits.size());
  for (std::size_t i = 0; i < bits.size(); ++i) out[i] = fromHalf(bits[i]);
  return out;
}

TEST(StabilityIntensity, HalfExrClampsAndCountsOverflowAndCountsUnderflow) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  relight::Relighter r = rm.baked->relighter();
  testing::TempDir dir;
  const precompute::Precomputation& p = rm.baked->p;
  const caches::LightmapCaches* direct_texels = p.hasDirectLayer() ? &p.direct_texels : nullptr;
  // The lightmap files of `res` (irradiance.exr, the SH maps, direct.exr, validity) in dir/sub.
  const auto write = [&](const RelightResult& res, const char* sub, output::ExrOptions o = {}) {
    std::filesystem::create_directories(dir / sub);
    auto w = output::writeLightmapExrs(res, p.lightmap, (dir / sub).string(), o, direct_texels);
    return w ? Expected<output::WriteStats>(w->stats) : Expected<output::WriteStats>(w.status());
  };

  // 1 cd: nothing near either end of the half range.
  const RelightResult unit = relightAt(r, 1.0f);
  auto s1 = write(unit, "unit");
  ASSERT_TRUE(s1) << s1.status().toString();
  EXPECT_EQ(s1->clamped, 0u);
  EXPECT_EQ(s1->underflowed, 0u);

  // 1e6 cd at ~1 m: direct irradiance ~1e6 lux > 65504. Clamped to 65504 (never +Inf) and
  // counted, as many as the float result has beyond the half range.
  r.invalidate();
  const RelightResult bright = relightAt(r, 1e6f);
  std::size_t beyond = 0;
  for (const auto& d : bright.direct)
    for (int ch = 0; ch < 3; ++ch) beyond += d[ch] > kHalfMax;
  for (float v : bright.lightmap_sh) beyond += std::abs(v) > kHalfMax;
  auto irradiance = output::evaluateIrradiance(bright, p.lightmap, true, direct_texels);
  ASSERT_TRUE(irradiance) << irradiance.status().toString();
  for (const auto& e : irradiance->irradiance)
    for (int ch = 0; ch < 3; ++ch) beyond += e[ch] > kHalfMax;
  ASSERT_GT(beyond, 0u) << "the scene should push values beyond the half range";
  auto s2 = write(bright, "bright");
  ASSERT_TRUE(s2) << s2.status().toString();
  EXPECT_EQ(s2->clamped, beyond);
  const auto direct_r = readHalfChannel((dir / "bright" / "direct.exr").string(), "R");
  float most = 0.0f;
  for (float v : direct_r) {
    ASSERT_TRUE(std::isfinite(v)) << "an infinity was written";
    most = std::max(most, v);
  }
  EXPECT_EQ(most, kHalfMax);

  // 1e-6 cd: direct ~1e-6 lux, below the smallest normal half: counted as underflowed.
  r.invalidate();
  const RelightResult dim = relightAt(r, 1e-6f);
  auto s3 = write(dim, "dim");
  ASSERT_TRUE(s3) << s3.status().toString();
  EXPECT_EQ(s3->clamped, 0u);
  EXPECT_GT(s3->underflowed, 0u) << "dim values lost half precision silently";
  // Float files keep the dim result exactly: nothing to count.
  auto s4 = write(dim, "dim_float", {.half = false});
  ASSERT_TRUE(s4);
  EXPECT_EQ(s4->clamped + s4->underflowed, 0u);
}

}  // namespace
}  // namespace lightlink::stability
