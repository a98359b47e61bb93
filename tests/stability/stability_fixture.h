// Shared helpers for the hard-case stability suite (DESIGN.md sec 6, docs/stability.md):
// small scenes through the real precompute and relight, and the checks every case repeats
// (finite, non-negative, bounded). Scenes come from tests/common/scene_builders.h and the
// relight fixture, so "a room" means the same thing here as in tests/relight.
#pragma once

#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include "core/precompute/precompute.h"
#include "core/relight/light_set.h"
#include "core/relight/relight.h"
#include "core/scene/light_eval.h"
#include "core/sh/sh.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::stability {

using relight::LightEntry;
using relight::LightSet;
using relight::RelightOptions;
using relight::RelightResult;
using relight::testing::addBox;
using relight::testing::addMaterial;
using relight::testing::addQuad;
using relight::testing::Baked;

inline LightEntry pointLight(std::string id, glm::vec3 pos, float intensity_cd, glm::vec3 color = glm::vec3(1.0f)) {
  LightEntry e;
  e.id = std::move(id);
  e.light.kind = scene::Light::Kind::kPoint;
  e.light.position = pos;
  e.light.intensity = intensity_cd;
  e.light.color = color;
  return e;
}

// Small enough that a whole bake of a room runs in well under a second on 2 cores.
inline precompute::PrecomputeOptions tinyOptions() {
  precompute::PrecomputeOptions o;
  o.surfels = 1024;
  o.links = 32;
  o.rays = 144;
  o.lightmap_resolution = 24;
  o.validity_rays = 16;
  o.grid_resolution = 5;
  o.builder = hierarchy::Builder::kKdMedian;
  return o;
}

// Runs `body` with exactly `threads` TBB threads (an arena of that size, and the global
// limit raised or lowered to match), so 4 threads really run on a 2-core machine.
template <class F>
auto withThreads(int threads, F&& body) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
  tbb::task_arena arena(threads);
  return arena.execute(std::forward<F>(body));
}

// Indirect irradiance (R, G, B) at normal n from one cache's 3 * nc SH floats (clamped at 0,
// as every consumer evaluates it).
inline glm::vec3 shIrradiance(const float* sh_rgb, int bands, glm::vec3 n) {
  const int nc = bands * bands;
  return {sh::irradiance(bands, sh_rgb, n), sh::irradiance(bands, sh_rgb + nc, n),
          sh::irradiance(bands, sh_rgb + 2 * nc, n)};
}

// Total irradiance (indirect SH at the cache normal + baked direct) of lightmap cache c.
inline glm::vec3 cacheIrradiance(const RelightResult& r, const caches::LightmapCaches& lm, std::size_t c) {
  const std::size_t t = lm.texel[c];
  return r.direct[t] + shIrradiance(r.lightmap_sh.data() + t * 3 * std::size_t(r.coeffCount()), r.bands, lm.normal[c]);
}

inline bool finite3(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Every float of a result is finite; radiosity, direct light and the SH mean (L00, which is
// the sphere-averaged radiance and cannot be negative for non-negative senders) are >= 0.
// Returns the number of offending values (0 = clean); prints the first few.
inline std::size_t countBadValues(const RelightResult& r, const std::string& what) {
  std::size_t bad = 0;
  auto report = [&](const char* array, std::size_t i, float v) {
    if (++bad <= 5) ADD_FAILURE() << what << ": " << array << "[" << i << "] = " << v;
  };
  const std::size_t nc = std::size_t(r.coeffCount());
  for (std::size_t i = 0; i < r.lightmap_sh.size(); ++i)
    if (!std::isfinite(r.lightmap_sh[i]) || (i % nc == 0 && r.lightmap_sh[i] < -1e-6f * (1.0f + std::abs(r.lightmap_sh[i]))))
      report("lightmap_sh", i, r.lightmap_sh[i]);
  for (std::size_t i = 0; i < r.grid_sh.size(); ++i)
    if (!std::isfinite(r.grid_sh[i]) || (i % nc == 0 && r.grid_sh[i] < -1e-6f * (1.0f + std::abs(r.grid_sh[i]))))
      report("grid_sh", i, r.grid_sh[i]);
  for (std::size_t i = 0; i < r.direct.size(); ++i)
    for (int ch = 0; ch < 3; ++ch)
      if (!std::isfinite(r.direct[i][ch]) || r.direct[i][ch] < 0.0f) report("direct", i, r.direct[i][ch]);
  for (std::size_t i = 0; i < r.surfel_radiosity.size(); ++i)
    for (int ch = 0; ch < 3; ++ch)
      if (!std::isfinite(r.surfel_radiosity[i][ch]) || r.surfel_radiosity[i][ch] < 0.0f)
        report("surfel_radiosity", i, r.surfel_radiosity[i][ch]);
  for (const auto& b : r.bounce_log)
    if (!std::isfinite(b.added_flux) || !std::isfinite(b.total_flux)) report("bounce_log", std::size_t(b.bounce), 0.0f);
  return bad;
}

// Sum of triangle areas of the static meshes (m^2): what the surfel areas must add up to.
inline double staticArea(const scene::Scene& s) {
  double a = 0.0;
  for (const auto& m : s.meshes) {
    if (!m.is_static) continue;
    for (std::size_t t = 0; t < m.triangleCount(); ++t) {
      const glm::dvec3 p0 = m.positions[m.indices[3 * t]], p1 = m.positions[m.indices[3 * t + 1]],
                       p2 = m.positions[m.indices[3 * t + 2]];
      a += 0.5 * glm::length(glm::cross(p1 - p0, p2 - p0));
    }
  }
  return a;
}

inline double surfelArea(const surfels::Surfels& s) {
  double a = 0.0;
  for (float x : s.area) a += x;
  return a;
}

template <class T>
bool sameBytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

}  // namespace lightlink::stability
