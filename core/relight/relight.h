// Relighter: the per-light-change half of seed 000 (sec 3, 3.1, 3.2), on the CPU — the one
// relight pipeline (pipeline.h) running the CPU backend's passes (cpu_passes.h); the GPU
// backend (gpu/gpu_relight.h) runs the same pipeline with its own passes. This header also
// holds the types every backend shares: options, effects plan, counts and the result.
//
//   LightSet --(a) surfel direct light (shadow rays) + emission--> surfel radiosity B
//            --(b) pull: flux up the tree, node radiosity B_node = Phi_node / A_node
//            --(c) cache lighting: L_cache = sum_links B_node F_node (+ sky)
//            --(d) bounces: surfels gather the caches, B += rho E_ind, repeat (b)-(c)
//            --(e) fill invalid caches, lightmap texels, dilation
//            --(f) baked direct light per texel: punctual lights (shadow rays) and emissive
//                  surfaces (emitter area sampled, soft shadows)  --> RelightResult
//
// Direct and indirect are disjoint in the lightmap: the lightmap caches gather only the
// *reflected* surfel radiosity rho * E, never the emitted pi * L_e, because the emitters'
// direct light is sampled into `direct` (docs/relight.md "Direct vs indirect"). Grid caches
// also gather reflected radiosity only, and the emitters' light is sampled into their SH
// (EmissionState::updateGrid): dynamic objects have no baked direct, so grid_sh holds both.
//
// Units (docs/units.md): radiosity B in W/m^2-equivalent (the photometric units of the
// lights: lux for lights in candela/lux, pi * radiance for emitters), node flux Phi = B * A,
// cache SH = incident radiance, per texel direct = irradiance. A Relighter keeps references
// to the static inputs (scene, accel, precomputation, link views): they must outlive it. It
// owns the per-relight buffers and reuses them, so repeated relights do not allocate, and it
// remembers the last light set so that a change of exactly one light with bounces off is
// relit incrementally (only surfels the light reaches, only their tree paths, only caches
// linked to changed nodes) with the same result as a full relight.
//
// Before any work an EffectsPlan (DESIGN.md sec 5) says which passes the scene and light
// set call for; skipped passes do not run and are counted in RelightResult::passes, so the
// report shows each saving. Results are identical for any TBB thread count: every parallel
// loop writes disjoint outputs and every sum runs in a fixed order.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "core/common/enum_names.h"
#include "core/common/status.h"
#include "core/links/links.h"
#include "core/precompute/precompute.h"
#include "core/relight/light_set.h"
#include "core/relight/seam_stitch.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::relight {

// kProjected: links' stored fp16 SH coefficients. kRuntime: direction + solid angle per
// link, projected as a spherical cap at relight time (seed 000 sec 4.6), any band count.
enum class LinkForm { kProjected, kRuntime };
// The one table of link-form names (options, reports, EXR attributes, benchmarks).
inline constexpr EnumNames<LinkForm, 2> kLinkFormNames{
    {{"projected", LinkForm::kProjected}, {"runtime", LinkForm::kRuntime}}};
constexpr std::string_view linkFormName(LinkForm f) { return enumName(kLinkFormNames, f); }
// kAuto: AVX2 + F16C kernels when the CPU has them, else scalar. kScalar forces scalar.
enum class Kernel { kAuto, kScalar };

struct RelightOptions {
  LinkForm link_form = LinkForm::kProjected;
  int bands = 0;                   // output SH bands; 0 = the links' bands. kProjected: <= links' bands
  // Bounces run to convergence (bounce_threshold); the cap is a safety net for scenes whose
  // albedo is near 1 (0 = direct + emission only). The one default of bake, open and the daemon.
  int max_bounces = 100;
  float bounce_threshold = 1e-3f;  // stop when a bounce adds less than this fraction of the total flux
  // Allow incremental relight when exactly one light changed. With bounces on it needs the
  // last relight converged (bounce_stop "threshold") at the same bounce_threshold, and it
  // propagates the change until a round adds less than bounce_threshold of the total flux;
  // node radiosity changes below bounce_threshold of the scene's mean radiosity are not
  // pushed to the caches (the error this leaves is of the order of the full relight's).
  bool incremental = true;
  // Start the bounce iteration from the last relight's solution (its caches) instead of from
  // the direct light alone, as seed 000's progressive multi-bounce does from frame to frame:
  // after a small light move one iteration is close to the converged answer, and each further
  // iteration (a warm relight of the same light set) converges it. Applies when the last
  // relight completed at the same bands, link form and kernel (RelightPasses::warm); the
  // bounce log then holds each iteration's change against the one before, and max_bounces
  // caps this call's iterations.
  bool warm_start = false;
  Kernel kernel = Kernel::kAuto;
  // Shadow rays, 1..64, spread over the footprint of a surfel near a shadow edge (its centre's
  // visibility differs from a neighbour's; the others test their centre only): the visible
  // fraction scales its punctual light. With one, a surfel switches between lit and dark at
  // once as a shadow edge crosses it and the indirect light pops from frame to frame while a
  // light moves (docs/quality.md, "Temporal stability"). The CPU backend's; the GPU filters
  // its shadow maps (3x3 PCF) instead.
  int surfel_shadow_rays = 32;
  // Samples (one shadow ray each) per lightmap texel for the direct light of emissive
  // surfaces, 1..4096; the Monte Carlo noise of a texel's direct falls as 1/sqrt(samples).
  int emitter_samples = 32;
  // Make texels on the two sides of smooth UV seams agree (SeamStitch), in the SH and the
  // direct light: what engines show as lines along chart borders otherwise.
  bool stitch_seams = true;
  // Replace each texel's indirect SH by a local linear fit over its 3x3 neighbourhood on the
  // same plane (IndirectSmooth): removes the texel-to-texel jumps of light from small, bright
  // patches (a narrow spot light's), which the link rays' noise puts there (+-40 % between
  // neighbours at 1024 rays), at the cost of about a texel of indirect detail. Off by default.
  bool smooth_indirect = false;
  // When not empty (one entry per surfel, tree order): the surfels' direct irradiance (lux)
  // used instead of evaluating the punctual lights' surfel lighting, so that two backends can
  // be fed identical surfel light and compared from the pull on (tests/gpu). Such a relight
  // counts as punctual lighting, is never incremental, and the next relight is a full one.
  std::span<const glm::vec3> surfel_irradiance;
};

// DESIGN.md sec 5: which passes this relight runs, and why.
struct EffectsPlan {
  bool punctual = false;      // any light with non-zero power
  bool emissive = false;      // any surfel emits after overrides
  bool sky = false;           // the sky emits
  bool grid = false;          // the precomputation has grid caches
  bool bounces = false;       // max_bounces > 0 and some light reaches the scene
  int max_bounces = 0;
  bool baked_direct = false;  // some baked light has non-zero power
  bool emissive_direct = false;  // some static triangle emits and the light set bakes emitters
  std::vector<std::string> reasons;  // one line per decision

  std::string toText() const;
  nlohmann::ordered_json toJson() const;
};

// Passes executed (incremented when a pass runs) by one relight, so tests and reports can
// see what was skipped.
struct PassCounts {
  int warm = 0;              // 1: the bounces started from the last relight's solution
  int surfel_direct = 0;     // punctual-light evaluation over surfels
  int emission = 0;          // emission added to surfel radiosity
  int pulls = 0;
  int cache_lighting = 0;    // lightmap-cache summations
  int grid_lighting = 0;     // grid-cache summations
  int sky = 0;               // sky term added to caches
  int bounces = 0;
  int baked_direct = 0;
  int emissive_direct = 0;   // emitter-sampled direct light into lightmap texels
  int surfel_emitter = 0;    // the emitters' direct light sampled at the surfels (what bounces start from)
  int grid_emitter = 0;      // the emitters' light sampled into the grid caches' SH
  int fill = 0;
  int incremental = 0;       // 1 when this relight was incremental
  int unchanged = 0;         // 1 when the light set and options equal the last relight's: only
                             // the texels were rewritten from the kept state
};

struct BounceRecord {
  int bounce = 0;              // 1 = first indirect bounce
  double added_flux = 0.0;     // sum over channels and surfels of |Phi_k - Phi_{k-1}|, lm-equivalent
  double total_flux = 0.0;     // sum of surfel flux after this bounce
  double seconds = 0.0;
};

struct StageTime {
  std::string stage;
  double seconds = 0.0;
};

struct RelightCounts {
  std::size_t surfels = 0, surfels_lit = 0;     // lit = direct light re-evaluated this relight
  std::size_t nodes = 0, nodes_pulled = 0;
  std::size_t caches = 0, caches_summed = 0;    // lightmap caches
  std::size_t grid_caches = 0, grid_caches_summed = 0;
  std::size_t links_read = 0;
  std::size_t surfels_gathered = 0;             // bounce gathers summed over bounces (incremental: the rounds')
  std::size_t shadow_rays = 0;                  // punctual and emitter shadow rays
  std::size_t emitter_triangles = 0;            // triangles sampled for emitter direct light
  std::size_t emitter_direct_reused = 0;        // 1: emission unchanged, the last emitter direct reused
  std::size_t surfel_emitter_reused = 0;       // 1: emission unchanged, the surfels' emitter light reused
  std::size_t grid_emitter_reused = 0;         // 1: emission and bands unchanged, the grid's emitter SH reused
  // Emitter products (surfels, texels, direct layer, grid) rescaled from their per-material
  // layers instead of sampled: the emission changed in strength or colour only. They also
  // count as reused above.
  std::size_t emitter_rescaled = 0;
  std::size_t texels = 0, texels_filled = 0;    // texels with a value after fill + dilation
  std::size_t surfels_without_gather = 0;       // bounces: no lightmap texel nor grid to read
};

struct RelightResult {
  std::uint64_t version = 0;        // the LightSet version this result is for
  std::string backend = "cpu";
  std::string kernel;               // "avx2" or "scalar"
  LinkForm link_form = LinkForm::kProjected;
  int bands = 0;
  int width = 0, height = 0;        // lightmap texels
  // Per texel (y * width + x), 3 * bands^2 floats: R coefficients, then G, then B (docs/sh.md
  // order in each): SH of *indirect* incident radiance: light reflected by surfaces (of any
  // light, emitters included) and the sky; no radiance straight from an emitter. Texels
  // without a value are 0 and have texel_valid = 0.
  std::vector<float> lightmap_sh;
  // Per direct texel (y * direct_width + x): direct irradiance (lux), linear RGB, of baked
  // punctual lights (hard shadows) plus, when the light set bakes emitters, of emissive
  // surfaces (sampled, soft shadows). The direct layer is the lightmap's size, or
  // direct_scale times finer when the precomputation has a direct layer (same UVs).
  std::vector<glm::vec3> direct;
  int direct_width = 0, direct_height = 0;
  // With a finer direct layer: 1 where its texel holds a value (else empty: texel_valid).
  std::vector<std::uint8_t> direct_valid;
  // The seam stitch of the SH (jump measured on R L00) and of the direct layer (R).
  SeamStats seams, direct_seams;
  std::vector<std::uint8_t> texel_valid;    // 1 = the texel has a cache, a fill or a dilation
  // Per grid cache (GridCaches order), 3 * bands^2 floats as above; empty without a grid.
  // All light arriving from surfaces and the sky: reflected light through the links, and
  // the emitters' direct light sampled on the emitting triangles (EmissionState::updateGrid).
  std::vector<float> grid_sh;
  std::vector<glm::vec3> surfel_radiosity;  // final B = rho * E + pi * L_e per surfel (tree order)
  EffectsPlan plan;
  PassCounts passes;
  RelightCounts counts;
  std::vector<StageTime> timings;
  std::vector<BounceRecord> bounce_log;
  std::string bounce_stop;          // "threshold", "cap", "disabled" or "no light"
  std::vector<std::string> warnings;

  int coeffCount() const { return bands * bands; }
  // The indirect irradiance (lux, RGB) of lightmap texel `texel` on a surface of unit normal n.
  glm::vec3 lightmapIndirect(std::uint32_t texel, const glm::vec3& n) const;
  // direct_width 0 (a result assembled by hand, e.g. from the wire): the lightmap's size.
  bool directIsFiner() const { return direct_width > 0 && (direct_width != width || direct_height != height); }
  double totalSeconds() const;
  nlohmann::ordered_json report() const;
};

// What the pull averages node radiosity over. A surfel that no cache sees
// (Precomputation::surfel_seen is 0: no link ray of any lightmap or grid cache was credited
// to it) adds neither flux nor area to its nodes: a link to a node carries the radiosity of
// the part of it some cache can see, not of a patch hidden behind a lamp or under a box that
// happens to share the node (docs/relight.md, "Surfels no cache sees"). Such surfels still
// gather light and are lit. Without seen flags (an empty surfel_seen) every surfel counts.
struct PullAreas {
  std::vector<float> surfel;    // per surfel: its area if seen, else 0
  std::vector<float> inv_node;  // per node: 1 / (sum of its surfels' `surfel`), 0 when that is 0
  std::size_t unseen = 0;       // surfels left out
};
Expected<PullAreas> pullAreas(const precompute::Precomputation& p);

class Relighter {
 public:
  // Static inputs; all must outlive the Relighter. `lightmap_links`/`grid_links` are views
  // of the precomputation's links (in memory or an artifact mapping).
  static Expected<Relighter> create(const scene::Scene& scene, const rt::Accel& accel,
                                    const precompute::Precomputation& p, links::LinksView lightmap_links,
                                    links::LinksView grid_links);
  // Same, with the links held in `p`.
  static Expected<Relighter> create(const scene::Scene& scene, const rt::Accel& accel,
                                    const precompute::Precomputation& p);

  Relighter(Relighter&&) noexcept;
  Relighter& operator=(Relighter&&) noexcept;
  ~Relighter();

  EffectsPlan plan(const LightSet& lights, const RelightOptions& options) const;
  // Whether relightInto(lights, options) would relight one changed light incrementally
  // (bounces included: then it converges in one call, where a warm start would not).
  bool incrementalFor(const LightSet& lights, const RelightOptions& options) const;
  Expected<RelightResult> relight(const LightSet& lights, const RelightOptions& options = {});
  // Same, into `out`, reusing its arrays' capacity: the steady state of a daemon or an editor
  // session relighting the same scene allocates nothing. On error `out` is unspecified.
  Status relightInto(const LightSet& lights, const RelightOptions& options, RelightResult& out);
  // What invalidate() forgets. kLightState: the next relight is a full one, but what depends
  // on emission alone (the emitter direct light of texels and of surfels)
  // is still reused while the emissive overrides are unchanged: the steady state of a session
  // that edits punctual lights. kEverything: nothing is reused.
  enum class Forget { kLightState, kEverything };
  // Forgets the last light set, so the next relight is a full one.
  void invalidate(Forget what = Forget::kEverything);
  // True when this CPU runs the AVX2 + F16C kernels.
  static bool simdAvailable();

  // The bounce gather tables (scene_tables.h): surfel s reads caches cache[begin[s] ..
  // begin[s + 1]) with weights, from the grid when from_grid[s], else from the lightmap
  // caches; has_value: the caches that hold a value after the fill.
  struct GatherTables {
    std::span<const std::uint32_t> begin, cache;
    std::span<const float> weight;
    std::span<const std::uint8_t> from_grid, lightmap_has_value, grid_has_value;
    std::size_t surfels_without_gather = 0;
  };
  GatherTables gatherTables() const;
  // Emitted radiosity pi * L_e per surfel (tree order) after the light set's overrides.
  void surfelEmission(const LightSet& lights, std::vector<glm::vec3>& out) const;

 private:
  struct Impl;
  explicit Relighter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Checks a relight request against a precomputation with `link_bands` projected bands,
// `surfels` surfels and `materials` materials: option ranges, the band count the link form
// allows, emissive overrides naming real materials, every light (LightSet::validate). The
// one check every backend runs first, so CPU and GPU reject the same requests with the same
// message.
Status validateRequest(const LightSet& lights, const RelightOptions& options, int link_bands, std::size_t surfels,
                       std::size_t materials);

// Exposed for tests and the benchmark: the cap projection of seed 000 sec 4.6 in closed form
// (polynomials of cos(half angle) = 1 - omega / 2pi, no trigonometry). Writes band factors
// k_l with coefficient (l, m) = k_l * Y_lm(direction); equals projectRuntimeLink.
void capBandFactors(float omega_over_pi, float* k /* kMaxBands */);

}  // namespace lightlink::relight
