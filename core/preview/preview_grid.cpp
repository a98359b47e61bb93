#include "core/preview/preview_grid.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "core/common/check.h"
#include "core/links/links.h"
#include "core/relight/direct_points.h"
#include "core/scene/material_eval.h"
#include "core/sh/sh.h"

namespace lightlink::preview {
namespace {

using Clock = std::chrono::steady_clock;
constexpr float kPi = std::numbers::pi_v<float>;
// Probes per task: a chunk traces 16 x rays rays (~2k at the default), enough to amortise a
// task; fixed, so the split never depends on the thread count.
constexpr std::size_t kProbeChunk = 16;

enum HitKind : std::uint8_t { kSky = 0, kSurface = 1, kBlack = 2 };

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

Status validate(const PreviewOptions& o) {
  if (o.rays < 4 || o.rays > 4096) return invalidInput("preview rays {} is out of range (4..4096)", o.rays);
  if (o.bands < 1 || o.bands > sh::kMaxBands)
    return invalidInput("preview bands {} is out of range (1..{})", o.bands, sh::kMaxBands);
  if (o.bounces < 0 || o.bounces > 8) return invalidInput("preview bounces {} is out of range (0..8)", o.bounces);
  if (o.max_total_rays < 16) return invalidInput("preview max_total_rays {} is below 16", o.max_total_rays);
  return {};
}

}  // namespace

struct PreviewGrid::Impl {
  const rt::Accel* accel = nullptr;
  int bands = 3;
  int bounces = 1;
  caches::GridCaches grid;
  caches::FillPlan fill;
  std::vector<std::uint8_t> has_value;  // per probe: valid, or filled from valid neighbours
  std::vector<std::uint32_t> traced;    // the valid probes, in grid order; hits of traced[i] at i * rays
  std::uint32_t rays = 0;               // per traced probe
  std::size_t materials = 0;
  // Per hit (traced probe i, ray r at i * rays + r).
  std::vector<glm::vec3> dir;       // unit
  std::vector<std::uint8_t> kind;   // HitKind
  std::vector<glm::vec3> position;  // surface hits: the hit point
  std::vector<glm::vec3> normal;    // surface hits: unit geometric normal of the side the probe sees
  std::vector<glm::vec3> albedo;    // bounce albedo (0 for contribute_gi = false)
  std::vector<glm::vec3> emission;  // emitted radiance before overrides
  std::vector<std::int32_t> material;
  PreviewStats stats;

  std::size_t stride() const { return std::size_t(3) * std::size_t(bands) * std::size_t(bands); }
  // Projects the hits' radiance of every traced probe into `grid_sh` (untraced probes 0), then
  // fills the invalid probes.
  void project(const std::vector<glm::vec3>& radiance, std::vector<float>& grid_sh) const;
  // Irradiance at a surface hit from `grid_sh` (trilinear over probes that hold a value).
  glm::vec3 gridIrradiance(const std::vector<float>& grid_sh, const glm::vec3& p, const glm::vec3& n) const;
};

void PreviewGrid::Impl::project(const std::vector<glm::vec3>& radiance, std::vector<float>& grid_sh) const {
  const std::size_t nc = std::size_t(bands) * bands, st = stride();
  grid_sh.assign(grid.size() * st, 0.0f);
  const float weight = 4.0f * kPi / float(rays);  // uniform sphere pdf 1 / 4 pi
  relight::detail::forChunks(traced.size(), kProbeChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
    float y[sh::kMaxBands * sh::kMaxBands];
    for (std::size_t i = begin; i < end; ++i) {
      float* out = grid_sh.data() + std::size_t(traced[i]) * st;
      for (std::uint32_t r = 0; r < rays; ++r) {
        const std::size_t h = i * rays + r;
        const glm::vec3 l = radiance[h] * weight;
        if (l == glm::vec3(0.0f)) continue;
        sh::evalBasis(bands, dir[h], y);
        for (std::size_t c = 0; c < nc; ++c) {
          out[c] += l.x * y[c];
          out[nc + c] += l.y * y[c];
          out[2 * nc + c] += l.z * y[c];
        }
      }
    }
  });
  relight::detail::applyFill(fill, grid_sh.data(), st);
}

glm::vec3 PreviewGrid::Impl::gridIrradiance(const std::vector<float>& grid_sh, const glm::vec3& p,
                                            const glm::vec3& n) const {
  const std::size_t nc = std::size_t(bands) * bands, st = stride();
  const glm::vec3 g = glm::clamp((p - grid.origin) / grid.spacing_m, glm::vec3(0.0f), glm::vec3(grid.dims - 1));
  const glm::ivec3 base = glm::min(glm::ivec3(glm::floor(g)), glm::max(grid.dims - 2, glm::ivec3(0)));
  const glm::vec3 f = g - glm::vec3(base);
  float acc[3 * sh::kMaxBands * sh::kMaxBands] = {};
  float total = 0.0f;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::ivec3 o(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
    const glm::ivec3 q = glm::min(base + o, grid.dims - 1);
    const std::size_t probe = (std::size_t(q.z) * grid.dims.y + q.y) * grid.dims.x + q.x;
    if (!has_value[probe]) continue;
    const float w = (o.x ? f.x : 1.0f - f.x) * (o.y ? f.y : 1.0f - f.y) * (o.z ? f.z : 1.0f - f.z);
    if (w <= 0.0f) continue;
    const float* src = grid_sh.data() + probe * st;
    for (std::size_t c = 0; c < st; ++c) acc[c] += w * src[c];
    total += w;
  }
  if (!(total > 0.0f)) return glm::vec3(0.0f);
  // E(n) = max(0, sum A_l L_lm Y_lm(n)) per channel (sh::irradiance), the basis evaluated once.
  float y[sh::kMaxBands * sh::kMaxBands];
  sh::evalBasis(bands, n, y);
  glm::vec3 e(0.0f);
  for (std::size_t i = 0; i < nc; ++i) {
    const float w = sh::kIrradianceBandFactors[std::size_t(sh::bandOf(int(i)))] * y[i];
    e += w * glm::vec3(acc[i], acc[nc + i], acc[2 * nc + i]);
  }
  return glm::max(e / total, glm::vec3(0.0f));
}

Expected<PreviewGrid> PreviewGrid::build(const scene::Scene& scene, const rt::Accel& accel,
                                         const PreviewOptions& options, const Progress* progress) {
  if (Status s = validate(options); !s) return s;
  auto impl = std::make_unique<Impl>();
  impl->accel = &accel;
  impl->bands = options.bands;
  impl->bounces = options.bounces;
  impl->materials = scene.materials.size();

  const auto t_place = Clock::now();
  caches::GridCacheOptions go = options.grid;
  go.validity.progress = progress;
  auto grid = caches::placeGridCaches(scene, accel, go);
  if (!grid) return grid.status();
  impl->grid = std::move(grid).value();
  impl->fill = caches::planGridFill(impl->grid);
  impl->has_value = relight::detail::hasValue(impl->grid.valid, impl->fill);
  for (std::size_t p = 0; p < impl->grid.size(); ++p)
    if (impl->grid.valid[p]) impl->traced.push_back(std::uint32_t(p));
  impl->stats.place_seconds = secondsSince(t_place);

  // Rays per probe: a square (stratified), lowered so the total stays within the budget.
  std::uint32_t strata = std::uint32_t(std::sqrt(double(options.rays)));
  const std::size_t valid = impl->traced.size();
  if (valid > 0 && std::uint64_t(strata) * strata * valid > options.max_total_rays)
    strata = std::max<std::uint32_t>(4, std::uint32_t(std::sqrt(double(options.max_total_rays) / double(valid))));
  links::LinkOptions lo;
  lo.rays = int(strata * strata);
  lo.seed = options.seed;
  const links::LinkRays pattern(lo);
  const std::uint32_t R = pattern.count();
  impl->rays = R;
  const std::size_t hits = valid * R;
  impl->dir.resize(hits);
  impl->kind.assign(hits, kSky);
  impl->position.assign(hits, glm::vec3(0.0f));
  impl->normal.assign(hits, glm::vec3(0.0f, 0.0f, 1.0f));
  impl->albedo.assign(hits, glm::vec3(0.0f));
  impl->emission.assign(hits, glm::vec3(0.0f));
  impl->material.assign(hits, -1);

  const auto t_trace = Clock::now();
  Impl& m = *impl;
  relight::detail::forChunks(valid, kProbeChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
    if (stopRequested(progress)) return;
    std::vector<float> dx(R), dy(R), dz(R), t(R), u(R), v(R), nx(R), ny(R), nz(R);
    std::vector<std::uint32_t> mesh(R), tri(R);
    const links::LinkRays::Directions dirs{dx.data(), dy.data(), dz.data()};
    const rt::HitArrays out{mesh.data(), tri.data(), u.data(), v.data(), t.data(), nx.data(), ny.data(), nz.data()};
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t probe = m.traced[i];
      const rt::RayFan fan = pattern.fan(accel, probe, m.grid.position[probe], glm::vec3(0.0f), dirs);
      accel.intersectFan(fan, out);
      for (std::uint32_t r = 0; r < R; ++r) {
        const std::size_t h = i * R + r;
        const glm::vec3 d = glm::normalize(glm::vec3(dx[r], dy[r], dz[r]));
        m.dir[h] = d;
        if (mesh[r] == rt::kNoHit) continue;
        const scene::MeshInstance& mi = scene.meshes[mesh[r]];
        const glm::vec3 ng(nx[r], ny[r], nz[r]);
        const float len = glm::length(ng);
        const bool back = rt::backFacing(ng, d);
        const bool two_sided = mi.material >= 0 && scene.materials[std::size_t(mi.material)].double_sided;
        if ((back && !two_sided) || !(len > 0.0f)) {
          m.kind[h] = kBlack;
          continue;
        }
        const glm::vec2 bary(u[r], v[r]);
        m.kind[h] = kSurface;
        m.position[h] = fan.origin + t[r] * glm::vec3(dx[r], dy[r], dz[r]);
        m.normal[h] = (back ? -ng : ng) / len;
        m.albedo[h] = scene::bounceAlbedoAt(scene, mi, tri[r], bary);
        m.emission[h] = scene::emissionAt(scene, mi, tri[r], bary);
        m.material[h] = mi.material;
      }
    }
  });
  if (stopRequested(progress)) return cancelled("preview grid: cancelled");
  impl->stats.probes = impl->grid.size();
  impl->stats.probes_valid = valid;
  impl->stats.rays_per_probe = int(R);
  impl->stats.rays = hits;
  impl->stats.trace_seconds = secondsSince(t_trace);
  return PreviewGrid(std::move(impl));
}

Status PreviewGrid::light(const lights::LightSet& lights, std::vector<float>& grid_sh, PreviewStats* stats) const {
  const Impl& m = *impl_;
  for (std::size_t i = 0; i < lights.lights().size(); ++i)
    if (Status s = lights::LightSet::validate(lights.lights()[i], fmt::format("lights[{}]", i)); !s) return s;
  if (Status s = lights.checkMaterials(m.materials); !s) return s;
  if (Status s = lights::LightSet::validate(lights.sky(), "sky"); !s) return s;
  const auto t0 = Clock::now();
  const std::size_t hits = m.dir.size();

  // Punctual lights at every surface hit, one shadow ray per light and hit, summed in light order.
  std::vector<std::uint8_t> surface(hits);
  for (std::size_t h = 0; h < hits; ++h) surface[h] = m.kind[h] == kSurface && m.albedo[h] != glm::vec3(0.0f);
  std::vector<glm::vec3> irradiance(hits, glm::vec3(0.0f)), one;
  std::size_t shadow_rays = 0;
  for (const auto& e : lights.lights()) {
    if (!relight::detail::lightEmits(e.light)) continue;
    relight::detail::shadowedLight(*m.accel, e.light, m.position, m.normal, surface, nullptr, one, shadow_rays,
                                   rt::Coherence::kIncoherent);
    for (std::size_t h = 0; h < hits; ++h) irradiance[h] += one[h];
  }

  // Emission after overrides, per material (as relight's surfel emission).
  std::vector<int> mode(m.materials, -1);
  std::vector<glm::vec3> value(m.materials, glm::vec3(1.0f));
  for (const auto& e : lights.emissive()) mode[std::size_t(e.material)] = int(e.mode), value[std::size_t(e.material)] = e.value;
  const bool sky_emits = lights.sky().emits();
  const auto sky_sh = lights.sky().radianceSh();
  float sky_coeffs[3][9];
  for (int c = 0; c < 9; ++c)
    for (int ch = 0; ch < 3; ++ch) sky_coeffs[ch][c] = sky_sh[std::size_t(c)][ch];

  // The radiance every hit sends towards its probe, before grid bounces.
  std::vector<glm::vec3> base(hits, glm::vec3(0.0f));
  relight::detail::forChunks(hits, relight::detail::kChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t h = begin; h < end; ++h) {
      if (m.kind[h] == kSky) {
        if (!sky_emits) continue;
        const glm::vec3& d = m.dir[h];
        base[h] = glm::max(glm::vec3(sh::evaluate(3, sky_coeffs[0], d), sh::evaluate(3, sky_coeffs[1], d),
                                     sh::evaluate(3, sky_coeffs[2], d)),
                           glm::vec3(0.0f));
        continue;
      }
      if (m.kind[h] != kSurface) continue;
      glm::vec3 le = m.emission[h];
      const int mat = m.material[h];
      if (mat >= 0 && mode[std::size_t(mat)] == int(lights::EmissiveOverride::Mode::kScale)) le *= value[std::size_t(mat)];
      if (mat >= 0 && mode[std::size_t(mat)] == int(lights::EmissiveOverride::Mode::kRadiance)) le = value[std::size_t(mat)];
      base[h] = m.albedo[h] / kPi * irradiance[h] + le;
    }
  });
  m.project(base, grid_sh);

  // Radiance Hints' multi-bounce: each iteration re-lights the hits with the irradiance of
  // the previous grid and projects again.
  std::vector<glm::vec3> bounced;
  for (int b = 0; b < m.bounces; ++b) {
    bounced = base;
    relight::detail::forChunks(hits, relight::detail::kChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
      for (std::size_t h = begin; h < end; ++h)
        if (surface[h]) bounced[h] += m.albedo[h] / kPi * m.gridIrradiance(grid_sh, m.position[h], m.normal[h]);
    });
    m.project(bounced, grid_sh);
  }
  if (stats) {
    *stats = m.stats;
    stats->shadow_rays = shadow_rays;
    stats->light_seconds = secondsSince(t0);
  }
  return {};
}

PreviewGrid::PreviewGrid(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PreviewGrid::PreviewGrid(PreviewGrid&&) noexcept = default;
PreviewGrid& PreviewGrid::operator=(PreviewGrid&&) noexcept = default;
PreviewGrid::~PreviewGrid() = default;

const caches::GridCaches& PreviewGrid::grid() const { return impl_->grid; }
int PreviewGrid::bands() const { return impl_->bands; }
const PreviewStats& PreviewGrid::buildStats() const { return impl_->stats; }

}  // namespace lightlink::preview
