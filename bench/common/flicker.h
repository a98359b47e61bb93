// Temporal stability of lightmaps along a light path (issue 48): how rough the frame-to-frame
// change of one scalar per texel is while one light moves at a constant step, and those
// scalars taken from relight results (appendFlickerFrame). Shared by
// bench/relight/flicker_bench and tests/relight/flicker_test; header only, no IO.
//
// Per texel, with values divided by the texel's mean over the path (so a dim texel's change
// counts as much as a bright one's), d1 = L[t+1] - L[t] and d2 = L[t+1] - 2 L[t] + L[t-1].
// For a response smooth in the light's position d2 is O(step^2) and d1 O(step), so the
// roughness R = RMS(d2) / RMS(d1) over lit texels halves when the step halves. A jump (a
// shadow ray flipping, a frame stopping its bounces one earlier than the last) keeps R, or
// raises it up to sqrt(2) where the jumps weigh in d2 but not yet in d1; a kink (light
// crossing a surface's plane, a range window's edge) lowers it by 1/sqrt(2) only. One sequence of 2N + 1 frames at step s/2 gives
// both steps: every other frame is the sequence at step s.
//
// A texel *pops* when its largest |d1| does not shrink with the step: at s/2 it is at least
// `pop_d1_ratio` of its largest at s (a smooth or kinked texel gives 0.5, a jump larger than
// one step's change gives more than 0.75) and at least `pop_floor` of the RMS change, so that
// a texel the light barely changes cannot pop by rounding. Roughness is also reported with
// the popping texels left out: what the rest of the lightmap does.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/precompute/precompute.h"
#include "core/relight/relight.h"

namespace lightlink::bench {

// frames x texels values, frame-major (values[t * texels + i]); `has_value` per texel: 1 where
// every frame holds a value (a texel with a cache, a valid direct texel).
struct FlickerFrames {
  std::size_t texels = 0;
  std::vector<float> values;
  std::vector<std::uint8_t> has_value;

  std::size_t frames() const { return texels ? values.size() / texels : 0; }
  float at(std::size_t frame, std::size_t texel) const { return values[frame * texels + texel]; }
};

struct FlickerOptions {
  // Lit: the texel's mean over the path is above this fraction of the mean over the texels
  // with a value.
  double lit_fraction = 1e-2;
  double pop_d1_ratio = 0.75;
  double pop_floor = 0.1;  // of the RMS |d1| at s/2 over lit texels
  std::size_t worst = 8;   // texels listed by their largest |d2|
};

// At one step, over lit texels and frames; d1 and d2 relative to each texel's mean.
struct StepRoughness {
  double rms_d1 = 0.0, rms_d2 = 0.0;
  double roughness = 0.0;  // rms_d2 / rms_d1 (0 when nothing changes)
  double p999_d2 = 0.0;    // 99.9th percentile of |d2|, over rms_d1
};

// Values over the layer's RMS |d1| at s/2.
struct FlickerTexel {
  std::size_t texel = 0;
  std::size_t frame = 0;         // frame (step s/2) at the middle of the largest |d2|
  double d2 = 0.0;               // that |d2|
  double d1_half_step = 0.0;     // largest |d1| at s/2
  double d1_step = 0.0;          // largest |d1| at s
  bool pops = false;
};

struct FlickerLayer {
  std::size_t texels_with_value = 0, lit_texels = 0, popping_texels = 0;
  StepRoughness coarse, fine;  // step s, step s/2
  double ratio = 0.0;          // fine.roughness / coarse.roughness: 0.5 smooth, >= 1 jumps
  StepRoughness coarse_smooth, fine_smooth;  // popping texels left out
  double ratio_smooth = 0.0;
  std::vector<std::size_t> popping;       // the popping texels, ascending
  std::vector<std::size_t> popping_step;  // for each: its largest |d1| is from frame k to k + 1
  // A popping texel's largest |d1| at s/2 relative to its mean: how far it jumps, median and
  // largest over the popping texels.
  double popping_jump_median = 0.0, popping_jump_max = 0.0;
  std::vector<FlickerTexel> worst;        // largest |d2| first
};

namespace flicker_detail {

struct Accum {
  double d1 = 0.0, d2 = 0.0;
  std::size_t n1 = 0, n2 = 0;
  std::vector<float> abs_d2;
};

inline double percentile(std::vector<float>& v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * double(v.size())));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

inline StepRoughness finish(Accum& a) {
  StepRoughness r;
  r.rms_d1 = a.n1 ? std::sqrt(a.d1 / double(a.n1)) : 0.0;
  r.rms_d2 = a.n2 ? std::sqrt(a.d2 / double(a.n2)) : 0.0;
  if (r.rms_d1 > 0.0) {
    r.roughness = r.rms_d2 / r.rms_d1;
    r.p999_d2 = percentile(a.abs_d2, 0.999) / r.rms_d1;
  }
  return r;
}

inline double ratio(const StepRoughness& fine, const StepRoughness& coarse) {
  return coarse.roughness > 0.0 ? fine.roughness / coarse.roughness : 0.0;
}

// One texel's relative series at stride 1 (step s/2) or 2 (step s) into `a`; returns the
// largest |d1| (and its first frame), and the largest |d2| with its middle frame through the
// out-parameters.
inline double addSeries(const std::vector<double>& x, std::size_t stride, Accum& a, double* max_d2 = nullptr,
                        std::size_t* max_frame = nullptr, std::size_t* max_d1_frame = nullptr) {
  double max_d1 = 0.0;
  for (std::size_t t = 0; t + stride < x.size(); t += stride) {
    const double d1 = x[t + stride] - x[t];
    a.d1 += d1 * d1, ++a.n1;
    if (std::abs(d1) > max_d1) {
      max_d1 = std::abs(d1);
      if (max_d1_frame) *max_d1_frame = t;
    }
    if (t < stride) continue;
    const double d2 = x[t + stride] - 2.0 * x[t] + x[t - stride];
    a.d2 += d2 * d2, ++a.n2;
    a.abs_d2.push_back(float(std::abs(d2)));
    if (max_d2 && std::abs(d2) > *max_d2) *max_d2 = std::abs(d2), *max_frame = t;
  }
  return max_d1;
}

}  // namespace flicker_detail

// Needs at least 5 frames (3 at step s); an odd count uses them all at both steps.
inline FlickerLayer measureFlicker(const FlickerFrames& f, const FlickerOptions& o = {}) {
  using namespace flicker_detail;
  FlickerLayer out;
  const std::size_t frames = f.frames();
  if (frames < 5) return out;
  const std::size_t coarse_frames = frames % 2 ? frames : frames - 1;  // step s ends on a frame

  std::vector<double> mean(f.texels, 0.0);
  double mean_sum = 0.0;
  for (std::size_t i = 0; i < f.texels; ++i) {
    if (!f.has_value[i]) continue;
    for (std::size_t t = 0; t < frames; ++t) mean[i] += f.at(t, i);
    mean[i] /= double(frames);
    mean_sum += mean[i];
    ++out.texels_with_value;
  }
  const double lit = out.texels_with_value ? o.lit_fraction * mean_sum / double(out.texels_with_value) : 0.0;

  struct Texel {
    std::size_t texel, frame, d1_frame;
    double max_d1_fine, max_d1_coarse, max_d2;
  };
  std::vector<Texel> texels;
  Accum fine, coarse;
  std::vector<double> x(frames);
  for (std::size_t i = 0; i < f.texels; ++i) {
    if (!f.has_value[i] || !(mean[i] > lit) || !(mean[i] > 0.0)) continue;
    for (std::size_t t = 0; t < frames; ++t) x[t] = f.at(t, i) / mean[i];
    Texel tx{i, 0, 0, 0.0, 0.0, 0.0};
    tx.max_d1_fine = addSeries(x, 1, fine, &tx.max_d2, &tx.frame, &tx.d1_frame);
    x.resize(coarse_frames);
    tx.max_d1_coarse = addSeries(x, 2, coarse);
    x.resize(frames);
    texels.push_back(tx);
  }
  out.lit_texels = texels.size();
  out.fine = finish(fine);
  out.coarse = finish(coarse);
  out.ratio = ratio(out.fine, out.coarse);

  auto pops = [&](const Texel& t) {
    return t.max_d1_fine >= o.pop_d1_ratio * t.max_d1_coarse && t.max_d1_fine >= o.pop_floor * out.fine.rms_d1 &&
           t.max_d1_fine > 0.0;
  };
  Accum fine_smooth, coarse_smooth;
  std::vector<float> jumps;
  for (const Texel& t : texels) {
    if (pops(t)) {
      out.popping.push_back(t.texel);
      out.popping_step.push_back(t.d1_frame);
      jumps.push_back(float(t.max_d1_fine));
      out.popping_jump_max = std::max(out.popping_jump_max, t.max_d1_fine);
      continue;
    }
    for (std::size_t k = 0; k < frames; ++k) x[k] = f.at(k, t.texel) / mean[t.texel];
    addSeries(x, 1, fine_smooth);
    x.resize(coarse_frames);
    addSeries(x, 2, coarse_smooth);
    x.resize(frames);
  }
  out.popping_texels = out.popping.size();
  out.popping_jump_median = percentile(jumps, 0.5);
  out.fine_smooth = finish(fine_smooth);
  out.coarse_smooth = finish(coarse_smooth);
  out.ratio_smooth = ratio(out.fine_smooth, out.coarse_smooth);

  std::stable_sort(texels.begin(), texels.end(), [](const Texel& a, const Texel& b) { return a.max_d2 > b.max_d2; });
  for (std::size_t k = 0; k < std::min(o.worst, texels.size()); ++k) {
    const Texel& t = texels[k];
    const double unit = out.fine.rms_d1 > 0.0 ? 1.0 / out.fine.rms_d1 : 0.0;
    out.worst.push_back({t.texel, t.frame, t.max_d2 * unit, t.max_d1_fine * unit, t.max_d1_coarse * unit, pops(t)});
  }
  return out;
}

inline float flickerLuminance(const glm::vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

// Appends one relight's frame: the luminance of the direct layer, and of the indirect
// irradiance for the cache's normal, at texels with a cache of their own (gutter texels only
// repeat their neighbours). Every frame of a sequence must come from the same precomputation.
inline void appendFlickerFrame(const relight::RelightResult& r, const precompute::Precomputation& p,
                               FlickerFrames& direct, FlickerFrames& indirect) {
  const std::size_t texels = std::size_t(r.width) * std::size_t(r.height);
  if (indirect.values.empty()) {
    indirect.texels = texels;
    indirect.has_value.assign(texels, 1);
  }
  for (std::size_t i = 0; i < texels; ++i) {
    const std::int32_t c = p.lightmap.cache_of_texel[i];
    if (c < 0 || !r.texel_valid[i]) {
      indirect.has_value[i] = 0;
      indirect.values.push_back(0.0f);
      continue;
    }
    const glm::vec3 e = r.lightmapIndirect(std::uint32_t(i), p.lightmap.normal[std::size_t(c)]);
    indirect.values.push_back(flickerLuminance(e));
  }
  const bool finer = r.directIsFiner();
  const caches::LightmapCaches& layer = finer ? p.direct_texels : p.lightmap;
  const std::size_t direct_texels = finer ? std::size_t(r.direct_width) * std::size_t(r.direct_height) : texels;
  if (direct.values.empty()) {
    direct.texels = direct_texels;
    direct.has_value.assign(direct_texels, 1);
  }
  for (std::size_t i = 0; i < direct_texels; ++i) {
    if (layer.cache_of_texel[i] < 0 || !(finer ? r.direct_valid[i] : r.texel_valid[i])) direct.has_value[i] = 0;
    direct.values.push_back(flickerLuminance(r.direct[i]));
  }
}

}  // namespace lightlink::bench
