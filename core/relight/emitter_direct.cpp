#include "core/relight/emitter_direct.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/common/sampling.h"
#include "core/scene/material_eval.h"
#include "core/sh/sh.h"

namespace lightlink::relight::detail {
namespace {

// The override of each material (or none), as the relight applies it to surfels.
struct MaterialEmission {
  bool replace = false;   // kRadiance
  glm::vec3 value{1.0f};  // radiance (replace) or factor
};

std::vector<MaterialEmission> materialEmission(const scene::Scene& scene, std::span<const EmissiveOverride> overrides) {
  std::vector<MaterialEmission> out(scene.materials.size());
  for (const auto& o : overrides)
    if (o.material >= 0 && o.material < int(out.size()))
      out[o.material] = {o.mode == EmissiveOverride::Mode::kRadiance, o.value};
  return out;
}

// Upper bound of a mesh's emitted radiance (textures only darken: glTF textures are <= 1).
glm::vec3 emissionBound(const scene::Scene& scene, const scene::MeshInstance& mesh,
                        const std::vector<MaterialEmission>& me) {
  const MaterialEmission o = mesh.material >= 0 ? me[mesh.material] : MaterialEmission{};
  if (o.replace) return o.value;
  const scene::Material& m = scene.materialOf(mesh);
  if (!m.isEmissive()) return glm::vec3(0.0f);
  return m.emissive_factor * m.emissive_strength * o.value;
}

bool emits(glm::vec3 v) { return v.x > 0.0f || v.y > 0.0f || v.z > 0.0f; }

// Angle between unit vectors, accurate for nearly parallel and nearly opposite ones.
double angleBetween(const glm::dvec3& a, const glm::dvec3& b) {
  if (glm::dot(a, b) < 0.0) return std::numbers::pi - 2.0 * std::asin(std::min(1.0, glm::length(a + b) * 0.5));
  return 2.0 * std::asin(std::min(1.0, glm::length(b - a) * 0.5));
}

// Solid angle subtended at the origin by a spherical triangle, in [3e-4, 6.22] sr: below
// that, Arvo's construction loses its digits (area sampling is then as good, the emitter
// being far); above, the receiver nearly touches the triangle's plane.
constexpr double kMinSphericalSr = 3e-4, kMaxSphericalSr = 6.22;

// Arvo's uniform sampling of the spherical triangle (a, b, c unit directions from the
// receiver; "Stratified sampling of spherical triangles", SIGGRAPH 1995, as in pbrt-v4), in
// double precision. The set-up (angles, solid angle) depends only on the receiver and the
// triangle, so it is done once per run of samples on the same triangle.
struct SphericalTriangle {
  bool ok = false;  // false: degenerate, or solid angle outside [kMinSphericalSr, kMaxSphericalSr]
  glm::dvec3 a, b, c_perp;  // c_perp: unit, c orthogonalised against a
  double alpha = 0.0, cos_alpha = 0.0, sin_alpha = 0.0, cos_ab = 0.0;
  double omega_sr = 0.0;  // pdf = 1 / omega_sr
};

SphericalTriangle setUpSphericalTriangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  SphericalTriangle t;
  glm::dvec3 n_ab = glm::cross(a, b), n_bc = glm::cross(b, c), n_ca = glm::cross(c, a);
  const double l_ab = glm::length(n_ab), l_bc = glm::length(n_bc), l_ca = glm::length(n_ca);
  if (!(l_ab > 0.0 && l_bc > 0.0 && l_ca > 0.0)) return t;
  n_ab /= l_ab, n_bc /= l_bc, n_ca /= l_ca;
  t.alpha = angleBetween(n_ab, -n_ca);
  t.omega_sr = t.alpha + angleBetween(n_bc, -n_ab) + angleBetween(n_ca, -n_bc) - std::numbers::pi;
  if (!(t.omega_sr >= kMinSphericalSr && t.omega_sr <= kMaxSphericalSr)) return t;
  const glm::dvec3 c_perp = c - glm::dot(c, a) * a;
  const double lc = glm::length(c_perp);
  if (!(lc > 0.0)) return t;
  t.a = a, t.b = b, t.c_perp = c_perp / lc;
  t.cos_alpha = std::cos(t.alpha), t.sin_alpha = std::sin(t.alpha);
  t.cos_ab = glm::dot(a, b);
  t.ok = true;
  return t;
}

// The direction for (u0, u1) in [0, 1)^2, uniform in solid angle; false on a degenerate case.
bool sampleSphericalTriangle(const SphericalTriangle& t, double u0, double u1, glm::dvec3& w) {
  // Sub-triangle of area u0 * omega: its third vertex c' on the arc from a to c.
  const double ap_pi = std::numbers::pi + u0 * t.omega_sr;
  const double sin_ap = std::sin(ap_pi), cos_ap = std::cos(ap_pi);
  const double sin_phi = sin_ap * t.cos_alpha - cos_ap * t.sin_alpha;
  const double cos_phi = cos_ap * t.cos_alpha + sin_ap * t.sin_alpha;
  const double k1 = cos_phi + t.cos_alpha;
  const double k2 = sin_phi - t.sin_alpha * t.cos_ab;
  const double denom = (k2 * sin_phi + k1 * cos_phi) * t.sin_alpha;
  if (denom == 0.0) return false;
  const double cos_bp = std::clamp((k2 + (k2 * cos_phi - k1 * sin_phi) * t.cos_alpha) / denom, -1.0, 1.0);
  const double sin_bp = std::sqrt(std::max(0.0, 1.0 - cos_bp * cos_bp));
  const glm::dvec3 cp = cos_bp * t.a + sin_bp * t.c_perp;
  // Then uniformly in solid angle along the arc from b to c'.
  const double cos_theta = 1.0 - u1 * (1.0 - glm::dot(cp, t.b));
  const double sin_theta = std::sqrt(std::max(0.0, 1.0 - cos_theta * cos_theta));
  const glm::dvec3 cp_perp = cp - glm::dot(cp, t.b) * t.b;
  const double lp = glm::length(cp_perp);
  w = lp > 0.0 ? cos_theta * t.b + sin_theta * (cp_perp / lp) : t.b;
  return true;
}

}  // namespace

bool anyEmitter(const scene::Scene& scene, std::span<const EmissiveOverride> overrides) {
  const auto me = materialEmission(scene, overrides);
  for (const auto& mesh : scene.meshes)
    if (mesh.is_static && mesh.triangleCount() > 0 && emits(emissionBound(scene, mesh, me))) return true;
  return false;
}

glm::vec2 emitterRotation(std::uint64_t seed) {
  const std::uint64_t bits = mixBits(seed);
  return {unitFloat(bits), unitFloat(mixBits(bits))};
}
std::uint64_t surfelEmitterSeed(std::size_t surfel) { return mixBits(0x73757266656d6974ULL ^ std::uint64_t(surfel)); }
std::uint64_t texelEmitterSeed(std::uint32_t texel, std::uint64_t salt) {
  return mixBits(0x6c6c656d69747465ULL ^ (std::uint64_t(texel) | salt));
}
std::uint64_t gridEmitterSeed(std::size_t cache) { return mixBits(0x67726964656d6974ULL ^ std::uint64_t(cache)); }

EmitterSampler::Tables EmitterSampler::tables() const {
  return {p0_, e1_, e2_, normal_, double_sided_, layer_, cdf_, weight_, area_, inv_pick_, inv_pdf_area_};
}

bool EmitterSampler::uniformRadiance() const {
  return std::none_of(textured_.begin(), textured_.end(), [](std::uint8_t t) { return t != 0; });
}

EmitterSampler::EmitterSampler(const scene::Scene& scene, const rt::Accel& accel,
                               std::span<const EmissiveOverride> overrides, std::span<const int> layer_of_material)
    : scene_(scene), accel_(accel) {
  const auto me = materialEmission(scene, overrides);
  for (int l : layer_of_material) layers_ = std::max(layers_, l + 1);
  std::vector<double> weight;
  for (std::uint32_t mi = 0; mi < scene.meshes.size(); ++mi) {
    const auto& mesh = scene.meshes[mi];
    if (!mesh.is_static) continue;
    const glm::vec3 bound = emissionBound(scene, mesh, me);
    if (!emits(bound)) continue;
    const MaterialEmission o = mesh.material >= 0 ? me[mesh.material] : MaterialEmission{};
    const bool two_sided = scene.materialOf(mesh).double_sided;
    // emissionAt reads the emissive texture when it has one and the mesh has its TEXCOORD set.
    const scene::TextureRef& tex = scene.materialOf(mesh).emissive_texture;
    const bool textured = !o.replace && tex.valid() && !(tex.texcoord == 1 ? mesh.uv1 : mesh.uv0).empty();
    for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t) {
      const glm::vec3 a = mesh.positions[mesh.indices[3 * t]], b = mesh.positions[mesh.indices[3 * t + 1]],
                      c = mesh.positions[mesh.indices[3 * t + 2]];
      const glm::vec3 cr = glm::cross(b - a, c - a);
      const float len = glm::length(cr);
      if (!(len > 0.0f)) continue;
      const double area_m2 = 0.5 * double(len);
      p0_.push_back(a), e1_.push_back(b - a), e2_.push_back(c - a);
      normal_.push_back(cr / len);
      mesh_.push_back(mi), triangle_.push_back(t);
      double_sided_.push_back(two_sided);
      replace_.push_back(o.replace);
      textured_.push_back(textured);
      value_.push_back(o.value);
      const int layer = layer_of_material.empty() || mesh.material < 0 ? 0 : layer_of_material[mesh.material];
      layer_.push_back(std::uint16_t(std::max(0, layer)));
      weight.push_back(area_m2 * (double(bound.x) + bound.y + bound.z));
      inv_pdf_area_.push_back(float(area_m2));  // times W / w_t below
    }
  }
  weight_ = weight;
  area_.assign(inv_pdf_area_.begin(), inv_pdf_area_.end());
  double total = 0.0;
  for (double w : weight) total += w;
  cdf_.resize(weight.size());
  double run = 0.0;
  for (std::size_t i = 0; i < weight.size(); ++i) {
    run += weight[i];
    cdf_[i] = run / total;
    inv_pick_.push_back(float(total / weight[i]));
    inv_pdf_area_[i] = float(double(inv_pdf_area_[i]) * total / weight[i]);
  }
  if (!cdf_.empty()) cdf_.back() = 1.0;
}

glm::vec3 EmitterSampler::radianceAt(std::size_t e, glm::vec2 barycentric) const {
  if (replace_[e]) return value_[e];
  return scene::emissionAt(scene_, scene_.meshes[mesh_[e]], triangle_[e], barycentric) * value_[e];
}

std::size_t EmitterSampler::sample(glm::vec3 position, const glm::vec3* normal_or_null, int samples,
                                   std::uint64_t seed, Scratch& scratch, std::size_t& rays) const {
  if (cdf_.empty() || samples <= 0) return 0;
  const bool sphere = normal_or_null == nullptr;
  const glm::vec3 normal = sphere ? glm::vec3(0.0f) : *normal_or_null;
  const std::size_t n = std::size_t(samples);
  scratch.rays.resize(n), scratch.contrib.resize(n), scratch.blocked.resize(n), scratch.dir.resize(n);
  scratch.layer.resize(n);
  std::span<const double> cdf = cdf_;
  std::span<const float> inv_pick = inv_pick_, inv_pdf_area = inv_pdf_area_;
  if (cdf_.size() <= kLocalPickMax) {
    // The receiver's own pick. Weight 0 only where the triangle cannot light x: entirely
    // below its horizon (cos_r <= 0 at every point of a convex triangle), or x behind a
    // one-sided emitter's plane.
    const std::size_t m = cdf_.size();
    scratch.cdf.resize(m), scratch.inv_pick.resize(m), scratch.inv_pdf_area.resize(m);
    double total = 0.0;
    for (std::size_t e = 0; e < m; ++e) {
      const glm::vec3 v0 = p0_[e], v1 = p0_[e] + e1_[e], v2 = p0_[e] + e2_[e];
      const bool below = !sphere && glm::dot(normal, v0 - position) <= 0.0f &&
                         glm::dot(normal, v1 - position) <= 0.0f && glm::dot(normal, v2 - position) <= 0.0f;
      const bool behind = !double_sided_[e] && glm::dot(normal_[e], position - v0) <= 0.0f;
      double w = 0.0;
      if (!below && !behind) {
        const glm::dvec3 d = (glm::dvec3(v0) + glm::dvec3(v1) + glm::dvec3(v2)) / 3.0 - glm::dvec3(position);
        w = weight_[e] / std::max(glm::dot(d, d), area_[e]);
      }
      scratch.inv_pick[e] = float(w);  // the weight, until the total is known
      total += w;
      scratch.cdf[e] = total;
    }
    if (!(total > 0.0)) return 0;  // every emitter is below or behind x
    for (std::size_t e = 0; e < m; ++e) {
      const double w = scratch.inv_pick[e];
      scratch.cdf[e] /= total;
      scratch.inv_pick[e] = w > 0.0 ? float(total / w) : 0.0f;
      scratch.inv_pdf_area[e] = w > 0.0 ? float(area_[e] * total / w) : 0.0f;
    }
    scratch.cdf.back() = 1.0;
    cdf = scratch.cdf, inv_pick = scratch.inv_pick, inv_pdf_area = scratch.inv_pdf_area;
  }
  // Cranley-Patterson rotation of the Hammersley set: the receiver's own stratified pattern.
  const glm::vec2 rotation = emitterRotation(seed);
  const double r0 = rotation.x, r1 = rotation.y;
  std::size_t count = 0;
  // Stratified picks visit triangles in CDF order (one wrap-around): the set-up of the last
  // triangle serves the whole run of samples on it.
  std::size_t tri_of_setup = cdf.size();
  SphericalTriangle tri;
  for (std::size_t i = 0; i < n; ++i) {
    double u = double(i) / double(n) + r0;
    u -= std::floor(u);
    double v = radicalInverse(i, 2) + r1;
    v -= std::floor(v);
    const std::size_t e =
        std::min<std::size_t>(std::size_t(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin()),
                              cdf.size() - 1);
    const double lo = e ? cdf[e - 1] : 0.0;
    // The pick's remainder is a fresh uniform in [0, 1): keeps the stratification inside t.
    const double ur = std::clamp((u - lo) / std::max(cdf[e] - lo, 1e-300), 0.0, 1.0);
    // Uniform in the solid angle the triangle subtends (no 1/d^2 peak for a receiver next to
    // an emitter); far or grazing triangles fall back to uniform area sampling.
    glm::vec2 bary;
    float weight = 0.0f;  // cos_r (cos_e / d^2) / pdf, without L_e
    float cos_r = 0.0f, cos_e = 0.0f;
    const glm::dvec3 x(position), v0(p0_[e]), ed1(e1_[e]), ed2(e2_[e]);
    if (e != tri_of_setup) {
      tri_of_setup = e;
      tri = setUpSphericalTriangle(glm::normalize(v0 - x), glm::normalize(v0 + ed1 - x), glm::normalize(v0 + ed2 - x));
    }
    glm::dvec3 dir;
    bool spherical = tri.ok && sampleSphericalTriangle(tri, ur, v, dir);
    if (spherical) {
      // Where the sampled direction meets the triangle (Moller-Trumbore barycentrics).
      const glm::dvec3 s1 = glm::cross(dir, ed2);
      const double div = glm::dot(s1, ed1);
      spherical = div != 0.0;
      if (spherical) {
        const glm::dvec3 sv = x - v0;
        double b1 = std::clamp(glm::dot(sv, s1) / div, 0.0, 1.0);
        double b2 = std::clamp(glm::dot(dir, glm::cross(sv, ed1)) / div, 0.0, 1.0);
        if (b1 + b2 > 1.0) {
          const double sum = b1 + b2;
          b1 /= sum, b2 /= sum;
        }
        bary = glm::vec2(float(b1), float(b2));
        cos_r = sphere ? 1.0f : float(glm::dot(glm::dvec3(normal), dir));
        cos_e = -float(glm::dot(glm::dvec3(normal_[e]), dir));
        weight = cos_r * float(tri.omega_sr) * inv_pick[e];
      }
    }
    if (!spherical) {
      const float su = float(std::sqrt(ur));
      bary = glm::vec2(su * float(v), su * (1.0f - float(v)));  // uniform on the triangle
      const glm::vec3 w = p0_[e] + bary.x * e1_[e] + bary.y * e2_[e] - position;
      const float d2 = glm::dot(w, w);
      if (!(d2 > 0.0f)) continue;
      const float inv_d = 1.0f / std::sqrt(d2);
      cos_r = sphere ? 1.0f : glm::dot(normal, w) * inv_d;
      cos_e = -glm::dot(normal_[e], w) * inv_d;
      weight = cos_r * std::abs(cos_e) / d2 * inv_pdf_area[e];
    }
    if (double_sided_[e]) cos_e = std::abs(cos_e);
    if (cos_r <= 0.0f || cos_e <= 0.0f) continue;  // behind the receiver or the emitter's back
    const glm::vec3 q = p0_[e] + bary.x * e1_[e] + bary.y * e2_[e];
    const glm::vec3 w = q - position;
    const glm::vec3 le = radianceAt(e, bary);
    if (!emits(le)) continue;
    const glm::vec3 w_unit = glm::normalize(w);
    rt::Ray ray;
    // A grid cache has no surface to leave: step off the point along the ray itself.
    ray.origin = accel_.offsetOrigin(position, sphere ? w_unit : normal, w);
    ray.dir = q - ray.origin;
    // Stop short of the emitter by the ray epsilon, so the emitter does not shadow itself.
    ray.tfar = std::max(0.0f, 1.0f - accel_.rayEpsilon() / std::max(glm::length(ray.dir), 1e-30f));
    scratch.rays[count] = ray;
    scratch.dir[count] = w_unit;
    scratch.layer[count] = layer_[e];
    scratch.contrib[count++] = le * weight;
  }
  accel_.occluded(std::span(scratch.rays.data(), count), std::span(scratch.blocked.data(), count));
  rays += count;
  return count;
}

void EmitterSampler::irradiance(glm::vec3 position, glm::vec3 normal, int samples, std::uint64_t seed,
                                Scratch& scratch, glm::vec3* out, std::size_t& rays) const {
  std::fill(out, out + layers_, glm::vec3(0.0f));
  const std::size_t count = sample(position, &normal, samples, seed, scratch, rays);
  if (count == 0) return;
  for (std::size_t k = 0; k < count; ++k)  // in sample order: the same for any thread count
    if (!scratch.blocked[k]) out[scratch.layer[k]] += scratch.contrib[k];
  for (int l = 0; l < layers_; ++l) out[l] /= float(samples);
}

void EmitterSampler::radianceSh(glm::vec3 position, int bands, int samples, std::uint64_t seed, Scratch& scratch,
                                float* out, std::size_t& rays) const {
  const std::size_t count = sample(position, nullptr, samples, seed, scratch, rays);
  const int nc = bands * bands;
  const float inv_n = count ? 1.0f / float(samples) : 0.0f;
  float y[sh::kMaxCoeffs];
  for (std::size_t k = 0; k < count; ++k) {  // in sample order: the same for any thread count
    if (scratch.blocked[k]) continue;
    sh::evalBasis(bands, scratch.dir[k], y);
    const glm::vec3 c = scratch.contrib[k] * inv_n;
    float* o = out + std::size_t(scratch.layer[k]) * 3 * nc;
    for (int i = 0; i < nc; ++i) o[i] += c.x * y[i], o[nc + i] += c.y * y[i], o[2 * nc + i] += c.z * y[i];
  }
}

}  // namespace lightlink::relight::detail
