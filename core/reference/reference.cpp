#include "core/reference/reference.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/common/check.h"
#include "core/reference/path_sampling.h"
#include "core/scene/light_eval.h"
#include "core/scene/material_eval.h"
#include "core/sh/sh.h"

namespace lightlink::reference {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
constexpr float kInvPi = std::numbers::inv_pi_v<float>;
// Russian roulette starts at this vertex (after this many bounces): the first bounces carry
// most of the energy and are cheap, so killing them would only add variance.
constexpr int kRouletteFromVertex = 3;
// Samples per work item. Blocks are the unit of parallelism and of summation order: a point's
// sums are the block sums added in block order, whatever thread ran each block.
constexpr std::uint32_t kBlockSamples = 64;
// Smallest extra batch after the first round, so rounds do not degenerate into many tiny ones.
constexpr std::uint32_t kMinBatch = 64;

float maxChannel(glm::vec3 v) { return std::max(v.x, std::max(v.y, v.z)); }
bool isZero(glm::vec3 v) { return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f; }

// A surface point a path leaves from. ng and ns are unit and face the side the path arrived
// from; f is what incident radiance is multiplied by before the cosine: 1 at the query point
// (irradiance itself), albedo / pi on a Lambertian surface.
struct Vertex {
  glm::vec3 pos{0.0f};
  glm::vec3 ng{0.0f};
  glm::vec3 ns{0.0f};
  glm::vec3 f{0.0f};
  glm::vec3 albedo{0.0f};
};

// Sums of one block or one point, in double so that 1e5 samples of values spanning 1e-6..1e6
// lose nothing to cancellation in sum2 - sum^2 / n.
struct Sums {
  std::array<double, 3> e{}, e2{}, i{}, i2{}, t2{};  // emitted direct, indirect, their total
  std::uint32_t n = 0;
  std::uint32_t truncated = 0;
  std::uint64_t rays = 0;

  void add(const Sums& o) {
    for (int c = 0; c < 3; ++c) {
      e[c] += o.e[c], e2[c] += o.e2[c], i[c] += o.i[c], i2[c] += o.i2[c], t2[c] += o.t2[c];
    }
    n += o.n, truncated += o.truncated, rays += o.rays;
  }
};

double stdError(double sum, double sum2, std::uint32_t n) {
  if (n < 2) return std::numeric_limits<double>::infinity();
  const double dn = n;
  const double var = std::max(0.0, (sum2 - sum * sum / dn) / (dn - 1.0));
  return std::sqrt(var / dn);
}

struct PathSample {
  glm::vec3 emitted{0.0f};   // emitters and sky seen directly from the query point
  glm::vec3 indirect{0.0f};  // everything that bounced at least once
  std::uint32_t rays = 0;
  bool truncated = false;
};

struct PointState {
  Sums sums;
  glm::vec3 punctual{0.0f};
  std::uint32_t next_sample = 0;  // first sample index of the next batch
  bool done = false;
  bool converged = false;
};

struct Block {
  std::uint32_t point = 0, first = 0, count = 0;
};

}  // namespace

struct ReferenceRenderer::Impl {
  const scene::Scene& scene;
  const rt::Accel& accel;
  std::vector<scene::Light> lights;     // the light set's punctual lights that emit
  relight::Sky sky;
  bool sky_emits = false;
  std::vector<int> override_mode;       // per material: -1 none, else EmissiveOverride::Mode
  std::vector<glm::vec3> override_value;

  // Emitter sampling: every triangle of an emissive mesh in the accel, chosen with
  // probability proportional to area * (max channel of its material's radiance bound). The
  // bound ignores the emissive texture (<= 1), so textured emitters are sampled where dark
  // too; the estimator stays unbiased because pmf > 0 wherever emission can be > 0.
  std::vector<std::int64_t> mesh_first_emitter;  // per mesh: index of its triangle 0, or -1
  std::vector<float> emitter_pdf_area;           // per emitter triangle: pmf / area (1/m^2)
  std::vector<double> emitter_cdf;               // inclusive, normalised, last = 1
  std::vector<std::uint32_t> emitter_mesh, emitter_tri;

  Impl(const scene::Scene& s, const rt::Accel& a) : scene(s), accel(a) {}

  glm::vec3 emission(std::uint32_t mesh, std::uint32_t tri, glm::vec2 bary) const {
    const scene::MeshInstance& m = scene.meshes[mesh];
    const int mat = m.material;
    const int mode = mat >= 0 ? override_mode[std::size_t(mat)] : -1;
    // Same order as the relight's computeEmission: the override replaces or scales the
    // scene's emission (texture included).
    if (mode == int(relight::EmissiveOverride::Mode::kRadiance)) return override_value[std::size_t(mat)];
    glm::vec3 le = scene::emissionAt(scene, m, tri, bary);
    if (mode == int(relight::EmissiveOverride::Mode::kScale)) le *= override_value[std::size_t(mat)];
    return le;
  }

  // An upper bound of emission over a mesh (texture <= 1), used only to build the pmf.
  glm::vec3 emissionBound(const scene::MeshInstance& m) const {
    const scene::Material& mat = scene.materialOf(m);
    const int mode = m.material >= 0 ? override_mode[std::size_t(m.material)] : -1;
    if (mode == int(relight::EmissiveOverride::Mode::kRadiance)) return override_value[std::size_t(m.material)];
    glm::vec3 le = mat.isEmissive() ? mat.emissive_factor * mat.emissive_strength : glm::vec3(0.0f);
    if (mode == int(relight::EmissiveOverride::Mode::kScale)) le *= override_value[std::size_t(m.material)];
    return le;
  }

  glm::vec3 skyRadiance(const glm::vec3& dir) const {
    if (!sky_emits) return glm::vec3(0.0f);
    if (!sky.sh) return sky.radiance;
    float basis[9];
    sh::evalBasis<3>(dir, basis);
    glm::vec3 l(0.0f);
    for (int k = 0; k < 9; ++k) l += (*sky.sh)[std::size_t(k)] * basis[k];
    return l;
  }

  void corners(std::uint32_t mesh, std::uint32_t tri, glm::vec3& p0, glm::vec3& p1, glm::vec3& p2) const {
    const scene::MeshInstance& m = scene.meshes[mesh];
    const std::uint32_t* idx = &m.indices[3 * std::size_t(tri)];
    p0 = m.positions[idx[0]], p1 = m.positions[idx[1]], p2 = m.positions[idx[2]];
  }

  // The shadow ray from x towards a point light or emitter sample at `target`, stopping short
  // of it by the ray epsilon like the relight's shadow rays (a light on a surface is not
  // shadowed by that surface).
  bool visible(const Vertex& x, const glm::vec3& target) const {
    rt::Ray ray;
    ray.origin = accel.offsetOrigin(x.pos, x.ng, target - x.pos);
    ray.dir = target - ray.origin;
    ray.tfar = std::max(0.0f, 1.0f - accel.rayEpsilon() / std::max(glm::length(ray.dir), 1e-30f));
    return !accel.occluded(ray);
  }

  // Shadowed irradiance from every punctual light at x (normal ns), lux.
  glm::vec3 punctualIrradiance(const Vertex& x, std::uint32_t& rays) const {
    glm::vec3 sum(0.0f);
    for (const scene::Light& light : lights) {
      const glm::vec3 e = scene::irradianceFrom(light, x.pos, x.ns);
      if (isZero(e)) continue;
      if (light.kind == scene::Light::Kind::kDirectional) {
        const glm::vec3 dir = -light.direction;
        if (glm::dot(x.ng, dir) <= 0.0f) continue;  // shading normal above, surface below
        rt::Ray ray;
        ray.origin = accel.offsetOrigin(x.pos, x.ng, dir);
        ray.dir = dir;
        ++rays;
        if (!accel.occluded(ray)) sum += e;
      } else {
        if (glm::dot(x.ng, light.position - x.pos) <= 0.0f) continue;
        ++rays;
        if (visible(x, light.position)) sum += e;
      }
    }
    return sum;
  }

  // Next-event estimate of emitted radiance reflected at x (already times f and MIS weight,
  // not yet times the path throughput).
  glm::vec3 sampleEmitter(const Vertex& x, SampleRng& rng, std::uint32_t& rays) const {
    const double u = (double(rng.next()) + double(rng.next()) * 0x1.0p-24);
    const auto it = std::upper_bound(emitter_cdf.begin(), emitter_cdf.end(), u);
    const std::size_t k = std::min<std::size_t>(std::size_t(it - emitter_cdf.begin()), emitter_cdf.size() - 1);
    const float u1 = rng.next(), u2 = rng.next();
    if (emitter_pdf_area[k] <= 0.0f) return glm::vec3(0.0f);
    const std::uint32_t mesh = emitter_mesh[k], tri = emitter_tri[k];
    glm::vec3 p0, p1, p2;
    corners(mesh, tri, p0, p1, p2);
    const glm::vec2 b = uniformTriangle(u1, u2);
    const glm::vec3 y = (1.0f - b.x - b.y) * p0 + b.x * p1 + b.y * p2;
    const glm::vec3 d = y - x.pos;
    const float dist2 = glm::dot(d, d);
    if (!(dist2 > 0.0f)) return glm::vec3(0.0f);
    const glm::vec3 w = d / std::sqrt(dist2);
    const float cos_x = glm::dot(x.ns, w);
    if (cos_x <= 0.0f || glm::dot(x.ng, w) <= 0.0f) return glm::vec3(0.0f);
    const glm::vec3 ny = glm::normalize(glm::cross(p1 - p0, p2 - p0));
    float cos_y = -glm::dot(ny, w);  // > 0: x sees the front face
    if (cos_y <= 0.0f) {
      if (!scene.materialOf(scene.meshes[mesh]).double_sided) return glm::vec3(0.0f);
      cos_y = -cos_y;
    }
    if (!(cos_y > 1e-7f)) return glm::vec3(0.0f);  // edge-on: zero solid angle
    const glm::vec3 le = emission(mesh, tri, b);
    if (isZero(le)) return glm::vec3(0.0f);
    ++rays;
    if (!visible(x, y)) return glm::vec3(0.0f);
    const float pdf_light = emitter_pdf_area[k] * dist2 / cos_y;  // per steradian
    const float pdf_cos = cos_x * kInvPi;
    return x.f * le * (cos_x / pdf_light * powerHeuristic(pdf_light, pdf_cos));
  }

  // pdf per steradian with which sampleEmitter would pick the hit point, seen from a vertex at
  // distance^2 dist2 with |cos| cos_y at the emitter.
  float emitterPdf(std::uint32_t mesh, std::uint32_t tri, float dist2, float cos_y) const {
    if (emitter_cdf.empty()) return 0.0f;
    const std::int64_t first = mesh_first_emitter[mesh];
    if (first < 0) return 0.0f;
    return emitter_pdf_area[std::size_t(first) + tri] * dist2 / std::max(cos_y, 1e-7f);
  }

  PathSample trace(const glm::vec3& position, const glm::vec3& normal, SampleRng& rng, int max_bounces) const;
};

PathSample ReferenceRenderer::Impl::trace(const glm::vec3& position, const glm::vec3& normal, SampleRng& rng,
                                          int max_bounces) const {
  PathSample out;
  const bool emitters = !emitter_cdf.empty();
  Vertex x{position, normal, normal, glm::vec3(1.0f), glm::vec3(1.0f)};
  glm::vec3 beta(1.0f);  // path throughput up to (excluding) x.f
  for (int k = 0;; ++k) {
    // Everything gathered at vertex k (its next-event estimates, and emitters or sky that its
    // continuation ray finds) has bounced k times: direct at the query point, indirect after.
    glm::vec3& target = k == 0 ? out.emitted : out.indirect;
    if (k > max_bounces) {
      out.truncated = true;
      break;
    }
    if (k >= kRouletteFromVertex) {
      const float survive = std::min(1.0f, maxChannel(x.albedo));
      if (!(rng.next() < survive)) break;
      beta /= survive;
    }
    if (k > 0 && !lights.empty()) target += beta * x.f * punctualIrradiance(x, out.rays);
    if (emitters) target += beta * sampleEmitter(x, rng, out.rays);

    // Continue by cosine sampling around the shading normal; directions below the geometric
    // surface carry nothing (the pdf of next-event estimation excludes them too).
    glm::vec3 t, b;
    orthonormalBasis(x.ns, t, b);
    const float u1 = rng.next(), u2 = rng.next();
    const glm::vec3 local = cosineHemisphere(u1, u2);
    const glm::vec3 dir = glm::normalize(local.x * t + local.y * b + local.z * x.ns);
    const float cos_x = local.z;
    if (!(cos_x > 0.0f) || glm::dot(x.ng, dir) <= 0.0f) break;
    beta *= x.f * kPi;  // f * cos / pdf with pdf = cos / pi

    rt::Ray ray;
    ray.origin = accel.offsetOrigin(x.pos, x.ng, dir);
    ray.dir = dir;
    ++out.rays;
    const rt::Hit h = accel.intersect(ray);
    if (!h.hit()) {
      target += beta * skyRadiance(dir);
      break;
    }
    const scene::MeshInstance& mesh = scene.meshes[h.mesh];
    const scene::Material& mat = scene.materialOf(mesh);
    const bool back = h.backFacing(dir);
    if (back && !mat.double_sided) break;  // the inside of something: black

    const glm::vec2 bary(h.u, h.v);
    glm::vec3 p0, p1, p2;
    corners(h.mesh, h.triangle, p0, p1, p2);
    Vertex y;
    y.pos = (1.0f - h.u - h.v) * p0 + h.u * p1 + h.v * p2;
    y.ng = glm::normalize(back ? -h.ng : h.ng);
    const float cos_y = -glm::dot(y.ng, dir);
    const glm::vec3 le = emission(h.mesh, h.triangle, bary);
    if (!isZero(le)) {
      float weight = 1.0f;
      if (emitters) {
        const glm::vec3 d = y.pos - x.pos;
        weight = powerHeuristic(cos_x * kInvPi, emitterPdf(h.mesh, h.triangle, glm::dot(d, d), cos_y));
      }
      target += beta * le * weight;
    }

    y.ns = y.ng;
    if (mesh.normals.size() == mesh.positions.size()) {
      const std::uint32_t* idx = &mesh.indices[3 * std::size_t(h.triangle)];
      const glm::vec3 interp =
          (1.0f - h.u - h.v) * mesh.normals[idx[0]] + h.u * mesh.normals[idx[1]] + h.v * mesh.normals[idx[2]];
      const float len = glm::length(interp);
      if (len > 1e-6f && std::isfinite(len)) y.ns = glm::dot(interp, y.ng) < 0.0f ? -interp / len : interp / len;
    }
    y.albedo = scene::bounceAlbedoAt(scene, mesh, h.triangle, bary);
    if (isZero(y.albedo)) break;
    y.f = y.albedo * kInvPi;
    x = y;
  }
  return out;
}

ReferenceRenderer::ReferenceRenderer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ReferenceRenderer::ReferenceRenderer(ReferenceRenderer&&) noexcept = default;
ReferenceRenderer& ReferenceRenderer::operator=(ReferenceRenderer&&) noexcept = default;
ReferenceRenderer::~ReferenceRenderer() = default;

std::size_t ReferenceRenderer::emitterTriangleCount() const { return impl_->emitter_cdf.size(); }

Expected<ReferenceRenderer> ReferenceRenderer::create(const scene::Scene& scene, const rt::Accel& accel,
                                                      const relight::LightSet& lights) {
  // The accel holds either every mesh or only the static ones (AccelOptions::static_only);
  // its triangle count says which, and emitters must come from the same meshes rays can hit.
  bool static_only = false;
  if (accel.triangleCount() == scene.triangleCount())
    static_only = false;
  else if (accel.triangleCount() == scene.staticTriangleCount())
    static_only = true;
  else
    return invalidInput("the accel holds {} triangles but the scene has {} ({} static): not built from this scene",
                        accel.triangleCount(), scene.triangleCount(), scene.staticTriangleCount());

  auto impl = std::make_unique<Impl>(scene, accel);
  for (const auto& e : lights.lights()) impl->lights.push_back(e.light);
  impl->sky = lights.sky();
  impl->sky_emits = lights.sky().emits();
  impl->override_mode.assign(scene.materials.size(), -1);
  impl->override_value.assign(scene.materials.size(), glm::vec3(1.0f));
  for (std::size_t i = 0; i < lights.emissive().size(); ++i) {
    const relight::EmissiveOverride& e = lights.emissive()[i];
    if (e.material < 0 || std::size_t(e.material) >= scene.materials.size())
      return invalidInput("emissive[{}].material: {} is not a material of the scene ({} materials)", i, e.material,
                          scene.materials.size());
    impl->override_mode[std::size_t(e.material)] = int(e.mode);
    impl->override_value[std::size_t(e.material)] = e.value;
  }

  impl->mesh_first_emitter.assign(scene.meshes.size(), -1);
  std::vector<double> weight;
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    if (static_only && !mesh.is_static) continue;
    const float bound = maxChannel(impl->emissionBound(mesh));
    if (!(bound > 0.0f)) continue;
    impl->mesh_first_emitter[m] = std::int64_t(weight.size());
    for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t) {
      glm::vec3 p0, p1, p2;
      impl->corners(std::uint32_t(m), t, p0, p1, p2);
      const double area = 0.5 * glm::length(glm::dvec3(glm::cross(p1 - p0, p2 - p0)));
      weight.push_back(area * bound);
      impl->emitter_mesh.push_back(std::uint32_t(m));
      impl->emitter_tri.push_back(t);
      impl->emitter_pdf_area.push_back(float(area));  // area for now; pmf / area below
    }
  }
  double total = 0.0;
  for (double w : weight) total += w;
  if (total > 0.0 && std::isfinite(total)) {
    impl->emitter_cdf.resize(weight.size());
    double run = 0.0;
    for (std::size_t i = 0; i < weight.size(); ++i) {
      run += weight[i];
      impl->emitter_cdf[i] = run / total;
      const double area = impl->emitter_pdf_area[i];
      impl->emitter_pdf_area[i] = area > 0.0 ? float(weight[i] / total / area) : 0.0f;
    }
    impl->emitter_cdf.back() = 1.0;
  } else {
    impl->mesh_first_emitter.assign(scene.meshes.size(), -1);
    impl->emitter_pdf_area.clear();
    impl->emitter_mesh.clear();
    impl->emitter_tri.clear();
  }
  return ReferenceRenderer(std::move(impl));
}

Status ReferenceRenderer::validate(const ReferenceOptions& o) {
  if (o.min_samples < 2) return invalidInput("min_samples: {} must be >= 2 (a variance needs two samples)", o.min_samples);
  if (o.max_samples < o.min_samples)
    return invalidInput("max_samples: {} is below min_samples {}", o.max_samples, o.min_samples);
  if (!std::isfinite(o.target_rel_error) || o.target_rel_error < 0.0f)
    return invalidInput("target_rel_error: {} must be finite and >= 0", o.target_rel_error);
  if (!std::isfinite(o.time_budget_s) || o.time_budget_s < 0.0)
    return invalidInput("time_budget_s: {} must be finite and >= 0", o.time_budget_s);
  if (o.max_bounces < 0 || o.max_bounces > 1 << 16)
    return invalidInput("max_bounces: {} must be in [0, 65536]", o.max_bounces);
  return {};
}

Expected<std::vector<IrradianceEstimate>> ReferenceRenderer::irradiance(const Query& query,
                                                                        const ReferenceOptions& options,
                                                                        Progress* progress) const {
  if (Status s = validate(options); !s) return s;
  if (query.position.size() != query.normal.size())
    return invalidInput("query: {} positions but {} normals", query.position.size(), query.normal.size());
  const std::size_t n_points = query.position.size();
  std::vector<glm::vec3> normal(n_points);
  for (std::size_t i = 0; i < n_points; ++i) {
    const glm::vec3 p = query.position[i], n = query.normal[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      return invalidInput("query.position[{}]: ({}, {}, {}) is not finite", i, p.x, p.y, p.z);
    const float len = glm::length(n);
    if (!std::isfinite(len) || !(len > 0.0f))
      return invalidInput("query.normal[{}]: ({}, {}, {}) is not a finite non-zero vector", i, n.x, n.y, n.z);
    normal[i] = n / len;
  }
  NullProgress null_progress;
  Progress& sink = progress ? *progress : null_progress;
  sink.begin("reference irradiance", n_points);

  const Impl& m = *impl_;
  using Clock = std::chrono::steady_clock;
  const bool budgeted = options.time_budget_s > 0.0;
  const Clock::time_point deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options.time_budget_s));
  std::atomic<bool> out_of_time{false}, cancelled{false};

  // The punctual lights' direct irradiance at each point: deterministic, computed once.
  std::vector<PointState> state(n_points);
  std::vector<std::uint32_t> punctual_rays(n_points, 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_points, 64), [&](const auto& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const Vertex x{query.position[i], normal[i], normal[i], glm::vec3(1.0f), glm::vec3(1.0f)};
      state[i].punctual = m.punctualIrradiance(x, punctual_rays[i]);
      state[i].sums.rays = punctual_rays[i];
    }
  });

  const std::uint32_t min_samples = std::uint32_t(options.min_samples);
  const std::uint32_t max_samples = std::uint32_t(options.max_samples);
  std::vector<Block> blocks;
  std::vector<Sums> block_sums;
  std::vector<std::uint8_t> block_ran;
  std::size_t finished = 0;
  for (;;) {
    // Issue this round's batches: min_samples first, then as many as the observed error says
    // are needed (plus 10 %), between kMinBatch and 4x what the point already has.
    blocks.clear();
    for (std::size_t i = 0; i < n_points; ++i) {
      PointState& s = state[i];
      if (s.done) continue;
      std::uint32_t batch = min_samples;
      if (s.sums.n > 0) {
        const double n = s.sums.n;
        double ref = 0.0, worst = 0.0;
        for (int c = 0; c < 3; ++c) {
          ref = std::max(ref, double(s.punctual[c]) + (s.sums.e[c] + s.sums.i[c]) / n);
          worst = std::max(worst, stdError(s.sums.e[c] + s.sums.i[c], s.sums.t2[c], s.sums.n));
        }
        const double goal = double(options.target_rel_error) * ref;
        double want = 4.0 * n;
        if (goal > 0.0) want = std::min(want, std::max(double(kMinBatch), n * (worst / goal) * (worst / goal) * 1.1 - n));
        batch = std::uint32_t(std::clamp(want, double(kMinBatch), 4.0 * n));
      }
      batch = std::min(batch, max_samples - s.next_sample);
      for (std::uint32_t first = 0; first < batch; first += kBlockSamples)
        blocks.push_back({std::uint32_t(i), s.next_sample + first, std::min(kBlockSamples, batch - first)});
      s.next_sample += batch;
    }
    if (blocks.empty()) break;

    block_sums.assign(blocks.size(), Sums{});
    block_ran.assign(blocks.size(), 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks.size(), 1), [&](const auto& r) {
      for (std::size_t bi = r.begin(); bi < r.end(); ++bi) {
        if (sink.cancelled()) cancelled.store(true, std::memory_order_relaxed);
        if (budgeted && Clock::now() > deadline) out_of_time.store(true, std::memory_order_relaxed);
        if (cancelled.load(std::memory_order_relaxed) || out_of_time.load(std::memory_order_relaxed)) continue;
        const Block& blk = blocks[bi];
        Sums& sums = block_sums[bi];
        for (std::uint32_t j = blk.first; j < blk.first + blk.count; ++j) {
          SampleRng rng(options.seed, blk.point, j);
          const PathSample p = m.trace(query.position[blk.point], normal[blk.point], rng, options.max_bounces);
          for (int c = 0; c < 3; ++c) {
            const double e = p.emitted[c], in = p.indirect[c], t = e + in;
            sums.e[c] += e, sums.e2[c] += e * e, sums.i[c] += in, sums.i2[c] += in * in, sums.t2[c] += t * t;
          }
          ++sums.n;
          sums.truncated += p.truncated ? 1u : 0u;
          sums.rays += p.rays;
        }
        block_ran[bi] = 1;
      }
    });
    if (cancelled.load()) {
      sink.end();
      return internalError("reference rendering cancelled");
    }
    for (std::size_t bi = 0; bi < blocks.size(); ++bi)
      if (block_ran[bi]) state[blocks[bi].point].sums.add(block_sums[bi]);

    for (PointState& s : state) {
      if (s.done) continue;
      bool ok = options.target_rel_error > 0.0f && s.sums.n >= min_samples;
      double ref = 0.0;
      for (int c = 0; c < 3; ++c)
        ref = std::max(ref, double(s.punctual[c]) + (s.sums.e[c] + s.sums.i[c]) / std::max<double>(s.sums.n, 1.0));
      for (int c = 0; c < 3 && ok; ++c)
        ok = stdError(s.sums.e[c] + s.sums.i[c], s.sums.t2[c], s.sums.n) <= double(options.target_rel_error) * ref;
      s.converged = ok;
      s.done = ok || s.next_sample >= max_samples;
      finished += s.done ? 1 : 0;
    }
    sink.update(finished);
    if (out_of_time.load()) break;
  }
  sink.end();

  std::vector<IrradianceEstimate> out(n_points);
  for (std::size_t i = 0; i < n_points; ++i) {
    const Sums& s = state[i].sums;
    IrradianceEstimate& est = out[i];
    const double n = std::max<double>(s.n, 1.0);
    est.direct_punctual = state[i].punctual;
    for (int c = 0; c < 3; ++c) {
      est.direct[c] = est.direct_punctual[c] + float(s.e[c] / n);
      est.indirect[c] = float(s.i[c] / n);
      est.std_error_direct[c] = float(stdError(s.e[c], s.e2[c], s.n));
      est.std_error_indirect[c] = float(stdError(s.i[c], s.i2[c], s.n));
      est.std_error_total[c] = float(stdError(s.e[c] + s.i[c], s.t2[c], s.n));
    }
    est.total = est.direct + est.indirect;
    est.samples = s.n;
    est.truncated_paths = s.truncated;
    est.rays = s.rays;
    est.converged = state[i].converged;
  }
  return out;
}

}  // namespace lightlink::reference
