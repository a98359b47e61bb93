// stage_probe: where the baker's first-bounce energy goes, stage by stage (docs/quality.md "What limits accuracy").
//
// For a scene and a punctual light set, bake with no bounce feedback (max_bounces 0: the
// lightmap SH holds light reflected once, from surfels lit directly) and compare, at evenly
// strided valid lightmap caches, the following estimates of the same one-bounce irradiance:
//
//   baked      the relight's lightmap SH (cut of nL nodes, node radiosity, fp16 links)
//   leaf_sh    the same link rays re-traced, every hit credited to its owner surfel's own
//              radiosity (no cut), projected to the baked band count and evaluated like the
//              lightmap: baked / leaf_sh is the cut (and fp16)
//   leaf_cos   the same hits, integrated against the exact clamped cosine instead of SH:
//              leaf_sh / leaf_cos is the SH band truncation
//   hit_cos    the same rays, each hit lit exactly at the hit point (punctual light, shadow
//              ray, albedo there): leaf_cos / hit_cos is the surfel discretisation
//   reference  the path tracer's single-bounce indirect at the cache (max_bounces 1):
//              hit_cos / reference is what is left (ray offsets, sampling)
//
// Each ratio is printed as mean / mean over the compared caches (the study's "bias") with the
// RMS of the per-cache relative difference; also the owned-area check (surfel areas vs the
// locator's cells), the cut with owned areas, and the texels' baked direct vs the reference's.
// Only punctual lights are lit exactly at hit points (hit_cos): compare the first rows on
// punctual light sets.
//
// --mode surfels: what surfels receive, against the reference at the surfel: the first bounce
//   gather for punctual lights, the emitters' direct light with --no-punctual 1.
// --mode hidden: surfels that no valid lightmap cache's link ray reaches, and their share of
//   the converged reflected flux (light only coarse cut nodes carry to caches).
// Its stage table is in docs/quality.md ("What limits accuracy").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/links/links.h"
#include "core/links/surfel_locator.h"
#include "core/precompute/precompute.h"
#include "core/reference/compare.h"
#include "core/reference/reference.h"
#include "core/relight/relight.h"
#include "core/scene/light_eval.h"
#include "core/scene/load.h"
#include "core/scene/material_eval.h"
#include "core/sh/sh.h"

using namespace lightlink;

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

int fail(const Status& s) {
  std::fprintf(stderr, "stage_probe: %s\n", s.message().c_str());
  return 1;
}

struct Args {
  std::string scene, lights, preset = "medium";
  int surfels = 0, links = 0, rays = 0, resolution = 0, points = 200, ref_samples = 4096;
  bool surfel_mode = false, no_punctual = false, hidden_mode = false;
  int emitter_samples = 32;
};

void compareLine(const char* what, const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
  double sa = 0.0, sb = 0.0, se = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double la = reference::luminance(a[i]), lb = reference::luminance(b[i]);
    sa += la, sb += lb;
    if (lb > 0.0) se += (la - lb) * (la - lb) / (lb * lb), ++n;
  }
  std::printf("  %-24s ratio of means %.4f   rms rel diff %.2f %%\n", what, sb > 0 ? sa / sb : 0.0,
              n ? 100.0 * std::sqrt(se / n) : 0.0);
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--scene") a.scene = v;
    else if (k == "--lights") a.lights = v;
    else if (k == "--preset") a.preset = v;
    else if (k == "--surfels") a.surfels = std::atoi(v.c_str());
    else if (k == "--links") a.links = std::atoi(v.c_str());
    else if (k == "--rays") a.rays = std::atoi(v.c_str());
    else if (k == "--resolution") a.resolution = std::atoi(v.c_str());
    else if (k == "--points") a.points = std::atoi(v.c_str());
    else if (k == "--ref-samples") a.ref_samples = std::atoi(v.c_str());
    else if (k == "--mode") a.surfel_mode = v == "surfels", a.hidden_mode = v == "hidden";
    else if (k == "--emitter-samples") a.emitter_samples = std::atoi(v.c_str());
    else if (k == "--no-punctual") a.no_punctual = v == "1";
    else return fail(invalidInput("unknown option {}", k));
  }
  if (a.scene.empty()) return fail(invalidInput("--scene is required"));
  auto scene = scene::loadScene(a.scene);
  if (!scene) return fail(scene.status());
  auto lights = relight::LightSet::fromSceneLights(scene->lights);
  if (!a.lights.empty())
    if (Status s = lights.applyFile(a.lights); !s) return fail(s);
  if (a.no_punctual) {
    std::vector<std::string> ids;
    for (const auto& e : lights.lights()) ids.push_back(e.id);
    for (const auto& id : ids)
      if (Status s = lights.remove(id); !s) return fail(s);
  }
  auto opt = precompute::preset(a.preset);
  if (!opt) return fail(opt.status());
  if (a.surfels) opt->surfels = std::uint32_t(a.surfels);
  if (a.links) opt->links = a.links;
  if (a.rays) opt->rays = a.rays;
  if (a.resolution) opt->lightmap_resolution = a.resolution;
  opt->direct_scale = 1;  // every stage is probed at the caches, direct light included
  auto p = precompute::run(*scene, *opt);
  if (!p) return fail(p.status());
  auto accel = rt::Accel::build(*scene);
  if (!accel) return fail(accel.status());
  auto relighter = relight::Relighter::create(*scene, *accel, *p);
  if (!relighter) return fail(relighter.status());
  relight::RelightOptions ro;
  ro.max_bounces = 0;
  ro.emitter_samples = a.emitter_samples;
  auto baked = relighter->relight(lights, ro);
  if (!baked) return fail(baked.status());
  for (const auto& t : baked->timings)
    if (t.stage == "surfel_emitter" || t.stage == "emissive_direct" || t.stage == "surfel_direct")
      std::printf("relight stage %-16s %.2f ms\n", t.stage.c_str(), 1e3 * t.seconds);

  if (a.surfel_mode) {
    // (d) + (e): what a surfel receives from the first bounce gather (caches -> surfels), against
    // the reference at the surfel: its single-bounce indirect for punctual lights, its emitted
    // direct for emitters (the gather is how surfels receive emitter light).
    ro.max_bounces = 1;
    ro.bounce_threshold = 0.0f;
    auto one = relighter->relight(lights, ro);
    if (!one) return fail(one.status());
    std::vector<glm::vec3> emit_b;
    relighter->surfelEmission(lights, emit_b);
    const std::size_t ns = p->surfels.size();
    const std::size_t step = std::max<std::size_t>(1, ns / std::size_t(a.points));
    std::vector<glm::vec3> sp, sn, gathered;
    std::vector<std::uint32_t> which;
    for (std::size_t i = 0; i < ns; i += step) {
      const glm::vec3 alb = p->surfels.albedo[i];
      if (emit_b[i] != glm::vec3(0.0f) || alb.x <= 0.0f || alb.y <= 0.0f || alb.z <= 0.0f) continue;
      sp.push_back(p->surfels.position[i]), sn.push_back(p->surfels.normal[i]);
      // Emitters: what the surfel holds before any bounce (its emitter direct); punctual: what
      // the first bounce gather added.
      gathered.push_back(a.no_punctual ? (baked->surfel_radiosity[i] - emit_b[i]) / alb
                                       : (one->surfel_radiosity[i] - baked->surfel_radiosity[i]) / alb);
      which.push_back(std::uint32_t(i));
    }
    auto ref = reference::ReferenceRenderer::create(*scene, *accel, lights);
    if (!ref) return fail(ref.status());
    reference::ReferenceOptions ref_opt;
    ref_opt.max_bounces = a.no_punctual ? 0 : 1;
    ref_opt.target_rel_error = 0.0f;
    ref_opt.min_samples = a.ref_samples;
    ref_opt.max_samples = a.ref_samples;
    auto est = ref->irradiance({sp, sn}, ref_opt);
    if (!est) return fail(est.status());
    std::vector<glm::vec3> e_ref;
    for (const auto& e : *est) e_ref.push_back(a.no_punctual ? e.direct - e.direct_punctual : e.indirect);
    std::printf("stage_probe surfels %s: nS %u nL %d, %zu surfels; gather of bounce 1 vs reference %s\n",
                a.scene.c_str(), opt->surfels, opt->links, sp.size(),
                a.no_punctual ? "emitted direct" : "single-bounce indirect");
    compareLine("surfel / reference", gathered, e_ref);
    // By surface orientation, to see where it goes.
    for (const glm::vec3 axis : {glm::vec3(0, 1, 0), glm::vec3(0, -1, 0), glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0),
                                 glm::vec3(0, 0, -1)}) {
      std::vector<glm::vec3> g, r;
      for (std::size_t k = 0; k < sp.size(); ++k)
        if (glm::dot(sn[k], axis) > 0.9f) g.push_back(gathered[k]), r.push_back(e_ref[k]);
      const std::string label = fmt::format("  normal ({:g},{:g},{:g}) n={}", axis.x, axis.y, axis.z, g.size());
      compareLine(label.c_str(), g, r);
    }
    return 0;
  }
  if (a.hidden_mode) {
    // Surfels no lightmap cache sees (no link ray of any valid cache ends on them): their
    // light reaches caches only averaged into coarse cut nodes. Share of the surfel flux.
    const links::LinkRays pattern(opt->linkOptions());
    const links::SurfelLocator locator(p->surfels, *scene);
    std::vector<std::uint8_t> seen(p->surfels.size(), 0);
    std::vector<rt::Ray> rays(pattern.count());
    std::vector<rt::Hit> hits(pattern.count());
    for (std::size_t c = 0; c < p->lightmap.size(); ++c) {
      if (!p->lightmap.valid[c]) continue;
      pattern.generate(*accel, c, p->lightmap.position[c], p->lightmap.normal[c], rays);
      accel->intersect(rays, hits, rt::Coherence::kCoherent);
      for (std::size_t i = 0; i < rays.size(); ++i) {
        const rt::Hit& h = hits[i];
        if (!h.hit()) continue;
        const bool back = h.backFacing(rays[i].dir);
        if (back && !scene->materialOf(scene->meshes[h.mesh]).double_sided) continue;
        const std::uint32_t o = locator.ownerOfHit(locator.sideMesh(h.mesh, back), h.triangle, h.u, h.v, rays[i].origin + h.t * rays[i].dir,
                                                   back ? -h.ng : h.ng);
        if (o != links::kNoSurfel) seen[o] = 1;
      }
    }
    relight::RelightOptions full;
    full.max_bounces = 64;
    full.bounce_threshold = 1e-4f;
    auto conv = relighter->relight(lights, full);
    if (!conv) return fail(conv.status());
    std::vector<glm::vec3> emit_b;
    relighter->surfelEmission(lights, emit_b);
    double all = 0.0, hid = 0.0;
    std::size_t n_hidden = 0;
    for (std::size_t i = 0; i < seen.size(); ++i) {
      const double f = reference::luminance(conv->surfel_radiosity[i] - emit_b[i]) * p->surfels.area[i];
      all += f;
      if (!seen[i]) hid += f, ++n_hidden;
    }
    std::printf("hidden surfels %s: %zu of %zu surfels seen by no lightmap cache, %.2f %% of the reflected flux\n",
                a.scene.c_str(), n_hidden, seen.size(), all > 0.0 ? 100.0 * hid / all : 0.0);
    return 0;
  }
  const auto& lm = p->lightmap;
  std::vector<std::uint32_t> valid;
  for (std::uint32_t c = 0; c < lm.size(); ++c)
    if (lm.valid[c]) valid.push_back(c);
  const std::size_t stride = std::max<std::size_t>(1, (valid.size() + a.points - 1) / a.points);
  std::vector<std::uint32_t> pick;
  for (std::size_t k = 0; k < valid.size(); k += stride) pick.push_back(valid[k]);
  std::vector<glm::vec3> pos, nrm;
  for (std::uint32_t c : pick) pos.push_back(lm.position[c]), nrm.push_back(lm.normal[c]);

  const int bands = baked->bands, nc = bands * bands;
  const links::LinkRays pattern(opt->linkOptions());
  const links::SurfelLocator locator(p->surfels, *scene);
  std::vector<rt::Ray> rays(pattern.count());
  // Owned area per surfel: area-uniform points on the static triangles, credited to their owner
  // the way link hits are. Surfels all carry area A / nS; if the partition the locator draws
  // gives some more and some less, node radiosity (flux / area) weights them wrongly.
  const std::size_t ns = p->surfels.size();
  std::vector<double> owned(ns, 0.0);
  {
    std::vector<double> tri_cdf;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> tri_of;
    double total = 0.0;
    for (std::uint32_t m = 0; m < scene->meshes.size(); ++m) {
      const auto& mesh = scene->meshes[m];
      if (!mesh.is_static) continue;
      for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t) {
        const glm::vec3 p0 = mesh.positions[mesh.indices[3 * t]], p1 = mesh.positions[mesh.indices[3 * t + 1]],
                        p2 = mesh.positions[mesh.indices[3 * t + 2]];
        total += 0.5 * glm::length(glm::cross(p1 - p0, p2 - p0));
        tri_cdf.push_back(total);
        tri_of.emplace_back(m, t);
      }
    }
    const std::size_t samples = 64 * ns;
    std::uint64_t state = 12345;
    auto next = [&] {
      state = state * 6364136223846793005ULL + 1442695040888963407ULL;
      return float((state >> 40) * 0x1.0p-24);
    };
    for (std::size_t i = 0; i < samples; ++i) {
      const double u = double(next()) * total;
      const std::size_t k = std::min<std::size_t>(
          std::size_t(std::lower_bound(tri_cdf.begin(), tri_cdf.end(), u) - tri_cdf.begin()), tri_cdf.size() - 1);
      const auto [m, t] = tri_of[k];
      const auto& mesh = scene->meshes[m];
      float u1 = next(), u2 = next();
      if (u1 + u2 > 1.0f) u1 = 1.0f - u1, u2 = 1.0f - u2;
      const glm::vec3 p0 = mesh.positions[mesh.indices[3 * t]], p1 = mesh.positions[mesh.indices[3 * t + 1]],
                      p2 = mesh.positions[mesh.indices[3 * t + 2]];
      const glm::vec3 q = (1.0f - u1 - u2) * p0 + u1 * p1 + u2 * p2;
      const glm::vec3 ng = glm::cross(p1 - p0, p2 - p0);
      const std::uint32_t o = locator.ownerOfHit(m, t, u1, u2, q, ng);
      if (o != links::kNoSurfel) owned[o] += total / double(samples);
    }
    double flux_a = 0.0, flux_o = 0.0, mn = 1e30, mx = 0.0, var = 0.0;
    for (std::size_t i = 0; i < ns; ++i) {
      const double l = reference::luminance(baked->surfel_radiosity[i]);
      flux_a += l * p->surfels.area[i], flux_o += l * owned[i];
      const double r = owned[i] / p->surfels.area[i];
      mn = std::min(mn, r), mx = std::max(mx, r), var += (r - 1.0) * (r - 1.0);
    }
    std::printf("owned area / surfel area: min %.3f max %.3f rms dev %.3f; first-bounce flux with surfel areas / "
                "with owned areas %.4f\n",
                mn, mx, std::sqrt(var / double(ns)), flux_a / flux_o);
  }
  // Node radiosity from owned areas (what flux / area would be if surfel areas were the owned ones).
  const auto& tree = p->tree;
  std::vector<glm::dvec3> node_flux_o(tree.nodeCount(), glm::dvec3(0.0)), node_flux_a(tree.nodeCount(), glm::dvec3(0.0));
  std::vector<double> node_area_o(tree.nodeCount(), 0.0), node_area_a(tree.nodeCount(), 0.0);
  for (std::size_t i = 0; i < ns; ++i) {
    const std::uint32_t leaf = tree.leaf_of_surfel[i];
    node_flux_o[leaf] = glm::dvec3(baked->surfel_radiosity[i]) * owned[i], node_area_o[leaf] = owned[i];
    node_flux_a[leaf] = glm::dvec3(baked->surfel_radiosity[i]) * double(p->surfels.area[i]);
    node_area_a[leaf] = p->surfels.area[i];
  }
  for (std::size_t n = tree.nodeCount(); n-- > 0;)
    if (tree.left[n] >= 0) {
      node_flux_o[n] = node_flux_o[tree.left[n]] + node_flux_o[tree.right[n]];
      node_area_o[n] = node_area_o[tree.left[n]] + node_area_o[tree.right[n]];
      node_flux_a[n] = node_flux_a[tree.left[n]] + node_flux_a[tree.right[n]];
      node_area_a[n] = node_area_a[tree.left[n]] + node_area_a[tree.right[n]];
    }
  const links::Links& lk = p->lightmap_links;

  std::vector<glm::vec3> e_baked, e_leaf_sh, e_leaf_cos, e_hit_cos, e_cut_cos, e_cut_cos_o;
  std::vector<float> basis(static_cast<std::size_t>(nc), 0.0f);
  for (std::size_t k = 0; k < pick.size(); ++k) {
    const std::uint32_t c = pick[k];
    const glm::vec3 n = nrm[k];
    const float* sh = baked->lightmap_sh.data() + std::size_t(lm.texel[c]) * 3 * nc;
    e_baked.emplace_back(sh::irradiance(bands, sh, n), sh::irradiance(bands, sh + nc, n),
                         sh::irradiance(bands, sh + 2 * nc, n));
    pattern.generate(*accel, c, pos[k], n, rays);
    const float w = 2.0f * kPi / float(rays.size());  // solid angle per ray
    std::vector<float> coeffs(std::size_t(3 * nc), 0.0f);
    glm::vec3 leaf_cos(0.0f), hit_cos(0.0f), cut_cos(0.0f), cut_cos_o(0.0f);
    const std::uint32_t l0 = lk.offsets[c], l1 = lk.offsets[c + 1];
    auto cutNodeOf = [&](std::uint32_t surfel) -> std::int64_t {
      for (std::uint32_t l = l0; l < l1; ++l) {
        const std::uint32_t nd = lk.node[l];
        if (surfel >= tree.begin[nd] && surfel < tree.end[nd]) return nd;
      }
      return -1;
    };
    for (const rt::Ray& r : rays) {
      const rt::Hit h = accel->intersect(r);
      if (!h.hit()) continue;
      const bool back = h.backFacing(r.dir);
      const auto& mesh = scene->meshes[h.mesh];
      if (back && !scene->materialOf(mesh).double_sided) continue;
      const glm::vec3 hp = r.origin + h.t * r.dir;
      const glm::vec3 ng = glm::normalize(back ? -h.ng : h.ng);
      const float cos_t = std::max(0.0f, glm::dot(r.dir, n));
      const std::uint32_t owner = locator.ownerOfHit(locator.sideMesh(h.mesh, back), h.triangle, h.u, h.v, hp, ng);
      if (owner != links::kNoSurfel) {
        const glm::vec3 b = baked->surfel_radiosity[owner];
        leaf_cos += b / kPi * cos_t * w;
        const std::int64_t nd = cutNodeOf(owner);
        if (nd >= 0) {
          cut_cos += glm::vec3(node_flux_a[std::size_t(nd)] / node_area_a[std::size_t(nd)]) / kPi * cos_t * w;
          if (node_area_o[std::size_t(nd)] > 0.0)
            cut_cos_o += glm::vec3(node_flux_o[std::size_t(nd)] / node_area_o[std::size_t(nd)]) / kPi * cos_t * w;
        }
        sh::evalBasis(bands, r.dir, basis.data());
        for (int ch = 0; ch < 3; ++ch)
          for (int q = 0; q < nc; ++q) coeffs[std::size_t(ch * nc + q)] += b[ch] * w / kPi * basis[std::size_t(q)];
      }
      // Exact one-bounce radiance at the hit point.
      glm::vec3 e(0.0f);
      for (const auto& entry : lights.lights()) {
        const glm::vec3 le = scene::irradianceFrom(entry.light, hp, ng);
        if (le == glm::vec3(0.0f)) continue;
        rt::Ray s;
        if (entry.light.kind == scene::Light::Kind::kDirectional) {
          s.dir = -entry.light.direction;
          s.origin = accel->offsetOrigin(hp, ng, s.dir);
        } else {
          s.origin = accel->offsetOrigin(hp, ng, entry.light.position - hp);
          s.dir = entry.light.position - s.origin;
          s.tfar = std::max(0.0f, 1.0f - accel->rayEpsilon() / std::max(glm::length(s.dir), 1e-30f));
        }
        if (!accel->occluded(s)) e += le;
      }
      const glm::vec3 alb = scene::albedoAt(*scene, mesh, h.triangle, glm::vec2(h.u, h.v));
      hit_cos += alb * e / kPi * cos_t * w;
    }
    e_leaf_sh.emplace_back(sh::irradiance(bands, coeffs.data(), n), sh::irradiance(bands, coeffs.data() + nc, n),
                           sh::irradiance(bands, coeffs.data() + 2 * nc, n));
    e_leaf_cos.push_back(leaf_cos);
    e_cut_cos.push_back(cut_cos);
    e_cut_cos_o.push_back(cut_cos_o);
    e_hit_cos.push_back(hit_cos);
  }

  auto ref = reference::ReferenceRenderer::create(*scene, *accel, lights);
  if (!ref) return fail(ref.status());
  reference::ReferenceOptions ref_opt;
  ref_opt.max_bounces = 1;
  ref_opt.target_rel_error = 0.0f;
  ref_opt.min_samples = a.ref_samples;
  ref_opt.max_samples = a.ref_samples;
  auto est = ref->irradiance({pos, nrm}, ref_opt);
  if (!est) return fail(est.status());
  std::vector<glm::vec3> e_ref, d_ref, d_baked;
  double noise = 0.0;
  for (std::size_t k = 0; k < pick.size(); ++k) d_baked.push_back(baked->direct[lm.texel[pick[k]]]);
  for (const auto& e : *est) {
    d_ref.push_back(e.direct);
    e_ref.push_back(e.indirect);
    const float l = reference::luminance(e.indirect);
    if (l > 0.0f) noise += double(reference::luminance(e.std_error_indirect) / l) * (reference::luminance(e.std_error_indirect) / l);
  }
  std::printf("stage_probe %s: nS %u nL %d rays %d bands %d, %zu caches (of %zu valid), reference %d paths/point "
              "(rms rel std error %.2f %%)\n",
              a.scene.c_str(), opt->surfels, opt->links, opt->rays, opt->bands, pick.size(), valid.size(),
              a.ref_samples, 100.0 * std::sqrt(noise / double(pick.size())));
  compareLine("baked / leaf_sh (cut)", e_baked, e_leaf_sh);
  compareLine("cut_cos / leaf_cos", e_cut_cos, e_leaf_cos);
  compareLine("cut_cos_owned / leaf_cos", e_cut_cos_o, e_leaf_cos);
  compareLine("leaf_sh / leaf_cos (SH)", e_leaf_sh, e_leaf_cos);
  compareLine("leaf_cos / hit_cos (surfels)", e_leaf_cos, e_hit_cos);
  compareLine("hit_cos / reference", e_hit_cos, e_ref);
  compareLine("baked / reference", e_baked, e_ref);
  compareLine("texel direct / reference", d_baked, d_ref);
  return 0;
}
