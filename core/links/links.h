// Links: for every cache, which sender nodes of the surfel tree it sees and how, as SH
// "form factors" (seed 000 sec 3.1, 4.5, 4.6; DESIGN.md sec 4).
//
// Per cache we trace a stratified set of directions (the hemisphere around a lightmap
// cache's normal, the whole sphere for a grid cache), credit every hit on a front face to
// the surfel that owns the hit point, and keep two things from the same samples:
//   1. importance: the visible solid angle per surfel, summed up the tree; the cut of at
//      most nL nodes is chosen by repeatedly refining the node with the largest visible
//      solid angle (nodes nobody sees are never linked), so the cut covers every visible
//      surfel exactly once;
//   2. transport: each cut node's visibility V_s(w)/pi projected into SH from the rays that
//      hit it (Monte Carlo with equal-solid-angle weights Omega/N).
// Rays that escape give the cache's sky visibility (also V/pi in SH, stored as float), and
// rays that hit the back of a single-sided surface are blocked (they see the inside of
// something). Incident radiance at relight time is L(w) = sum_links B_node F_node(w) with
// B_node = flux_node / area_node: node radiosity, never 1/A folded into the coefficients,
// which would overflow fp16 for small senders (DESIGN.md sec 4).
//
// Two stored forms, both built from the same cut:
//   - kShProjected: bands^2 fp16 coefficients per link (3 bands: 18 + 4 bytes);
//   - runtime projection: a direction (octahedral, 2 x snorm16) and the node's visible
//     solid angle / pi (fp16); at relight the node is treated as a spherical cap of that
//     solid angle around that direction and projected analytically (capZonal()), for any
//     band count (4 + 4 + 2 bytes).
// Generation is parallel over fixed-size chunks of caches whose results are concatenated in
// order, and every random number is a function of (seed, cache, ray): the output is
// bit-identical for any thread count.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/aligned_vector.h"
#include "core/common/half.h"
#include "core/common/memory.h"
#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/hierarchy/tree.h"
#include "core/links/hit_credit.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"
#include "core/surfels/surfels.h"

namespace lightlink::links {

class SurfelLocator;  // surfel_locator.h

struct LinkOptions {
  int rays = 1024;       // directions per cache, rounded down to a square (stratified n x n)
  int max_links = 128;   // nL: most sender nodes per cache
  int bands = 3;         // SH bands of the projected form, 1..4
  std::uint64_t seed = 0x5eed;
  // The global index of the first cache given: a shard of the caches (precompute --shard)
  // traces the rays of caches first_cache.. so its links are those slices of the whole run's.
  std::size_t first_cache = 0;
  const char* progress_label = "links";  // stage name shown by a Progress
  // Which hit-credit kernel runs: the best this CPU has, or the scalar one (both give the
  // same bits; precompute_bench --hit-credit scalar times the difference).
  HitCreditKernel hit_credit = HitCreditKernel::kBest;
  // Links the output arrays are sized for before the first cache (as if every cache had
  // max_links, up to this many; sized, not written: pages are faulted in as links land).
  // Past it they grow while no chunk is being copied in; the result is the same.
  std::size_t output_links_up_front = std::size_t(1) << 26;
};

// The caches to link: positions, and a unit normal for a hemisphere (lightmap) cache or a
// zero vector for a sphere (grid) cache.
struct CacheQuery {
  std::span<const glm::vec3> position;
  std::span<const glm::vec3> normal;
};

#ifndef LIGHTLINK_PROBES
#define LIGHTLINK_PROBES 0
#endif
// Whether this build times link generation's phases (LIGHTLINK_PROBES: benchmark builds).
// Without probes phase_ticks stay 0 and reports leave the phase shares out.
inline constexpr bool kPhaseProbes = LIGHTLINK_PROBES != 0;

// The phases of linking one cache, in order: where link generation's time goes. "trace" is
// Embree alone, so (sum - trace) / trace is link generation's own work per unit of tracing,
// the figure the ratio to raw Embree depends on (docs/precompute.md).
enum LinkPhase : int { kPhaseRays, kPhaseTrace, kPhaseCredit, kPhaseSky, kPhaseSort, kPhaseCut, kPhaseProject,
                       kPhaseOutput, kLinkPhases };
inline constexpr std::array<const char*, kLinkPhases> kLinkPhaseNames = {
    "rays", "trace", "credit", "sky", "sort", "cut", "project", "output"};

struct LinkStats {
  std::uint64_t rays = 0;           // traced
  std::uint64_t front_hits = 0;     // credited to a surfel
  std::uint64_t back_hits = 0;      // blocked by the inside of a single-sided surface
  std::uint64_t escaped = 0;        // sky
  std::uint64_t unowned = 0;        // front hits with no surfel near (not credited)
  double seconds = 0.0;
  // Per LinkPhase, with kPhaseProbes: ticks summed over all threads (x86: the timestamp
  // counter; elsewhere steady_clock nanoseconds). Their unit varies by machine; their
  // shares do not.
  std::array<std::uint64_t, kLinkPhases> phase_ticks{};
  std::uint64_t totalPhaseTicks() const {
    std::uint64_t total = 0;
    for (const std::uint64_t t : phase_ticks) total += t;
    return total;
  }
};

// phase_ticks per second on this machine (x86: the timestamp counter's rate, measured
// against steady_clock over ~20 ms on the first call; elsewhere 1e9). For a bench that sets
// the phases' time against the wall time.
double linkPhaseTicksPerSecond();

// Read-only view of link arrays, wherever they live (a Links in memory, or an artifact
// mapping): what relight consumes.
struct LinksView {
  int bands = 0;
  std::span<const std::uint32_t> offsets, node, direction;
  std::span<const half_bits> coeffs, solid_angle;
  std::span<const float> sky;

  std::size_t cacheCount() const { return offsets.empty() ? 0 : offsets.size() - 1; }
  std::size_t linkCount() const { return node.size(); }
};

struct Links {
  int bands = 0;
  std::vector<std::uint32_t> offsets;   // caches + 1: links of cache c are [offsets[c], offsets[c+1])
  HugeVector<std::uint32_t> node;       // per link: tree node
  HugeVector<half_bits> coeffs;         // per link, bands^2: SH of V/pi (projected form)
  HugeVector<std::uint32_t> direction;  // per link: octahedral direction, 2 x snorm16 (runtime form)
  HugeVector<half_bits> solid_angle;    // per link: visible solid angle / pi (runtime form)
  HugeVector<float> sky;                // per cache, bands^2: SH of sky visibility / pi
  // Per surfel (tree order): 1 when a front hit of some cache's ray was credited to it, else
  // 0. Relight averages node radiosity over these surfels only (docs/relight.md, "Surfels no
  // cache sees"); the precompute keeps their union over the lightmap and grid caches.
  std::vector<std::uint8_t> seen;
  LinkStats stats;

  std::size_t cacheCount() const { return offsets.empty() ? 0 : offsets.size() - 1; }
  std::size_t linkCount() const { return node.size(); }
  LinksView view() const { return {bands, offsets, node, direction, coeffs, solid_angle, sky}; }
  std::size_t bytesPerLinkProjected() const { return sizeof(std::uint32_t) + sizeof(half_bits) * bands * bands; }
  static constexpr std::size_t bytesPerLinkRuntime() {
    return sizeof(std::uint32_t) + sizeof(std::uint32_t) + sizeof(half_bits);
  }
};

// `surfels` must be in the tree's order (buildTree reorders them).
Expected<Links> generateLinks(const scene::Scene& scene, const rt::Accel& accel,
                              const surfels::Surfels& surfels, const hierarchy::Tree& tree,
                              const CacheQuery& caches, const LinkOptions& options,
                              Progress* progress = nullptr);

// The same over an owner lookup the caller built (from the same surfels, in tree order), so
// that several cache sets share one: the precompute builds it once, as its own stage, for the
// lightmap and the grid caches. Links::stats.seconds then counts the caches' work alone.
Expected<Links> generateLinks(const scene::Scene& scene, const rt::Accel& accel, const SurfelLocator& locator,
                              const hierarchy::Tree& tree, const CacheQuery& caches, const LinkOptions& options,
                              Progress* progress = nullptr);

// The rays link generation traces for each cache: a strata x strata jittered stratified
// grid (strata = floor(sqrt(options.rays))) over the hemisphere around the cache normal (or
// the sphere for a zero normal). One base pattern of jitters (from the seed) is randomised
// per (seed, cache): its polar jitters shifted modulo 1 inside their strata, the whole
// pattern turned about the normal, so every cache's samples are stratified and unbiased and
// different caches' errors are uncorrelated (docs/precompute.md). Exposed so a benchmark
// can trace exactly the same rays through the bare BVH and compare throughput.
class LinkRays {
 public:
  explicit LinkRays(const LinkOptions& options);
  std::uint32_t count() const { return strata_ * strata_; }
  // Fills rays[0 .. count()), and when given, the directions again as three arrays of
  // count() floats each (what vectorised loops over a cache's rays read).
  struct Directions {
    float* x;
    float* y;
    float* z;
  };
  void generate(const rt::Accel& accel, std::size_t cache, const glm::vec3& position, const glm::vec3& normal,
                std::span<rt::Ray> rays, const Directions* directions = nullptr) const;
  // The same rays as a fan (one origin, the directions written to `directions`), for
  // Accel::intersectFan: what link generation traces.
  rt::RayFan fan(const rt::Accel& accel, std::size_t cache, const glm::vec3& position, const glm::vec3& normal,
                 const Directions& directions) const;

 private:
  // Computes the directions (into `directions` when given, all rows at once; else row by row
  // on the stack) and hands each row to sink(origin, x, y, z, first ray, rays in the row);
  // returns the origin.
  template <typename RowSink>
  glm::vec3 forEachRow(const rt::Accel& accel, std::size_t cache, const glm::vec3& position,
                       const glm::vec3& normal, const Directions* directions, RowSink&& sink) const;

  std::uint32_t strata_;
  std::uint64_t seed_;
  // The base pattern, per ray: the polar jitter in [0, 1) inside its stratum, and the
  // azimuth's cos and sin.
  LineVector<float> base_jitter_, base_cos_, base_sin_;
  LineVector<float> base_stratum_;  // per ray: its polar stratum (i % strata) as a float
};

// Zonal SH coefficients z_l (l < bands) of the indicator of a spherical cap of solid angle
// `omega` (sr) around +z, divided by pi: the runtime-projection link shape. Rotated to
// direction d, coefficient (l, m) is z_l * sqrt(4 pi / (2l + 1)) * Y_lm(d).
void capZonal(float omega, int bands, float* z);
// Projects one runtime-form link (direction, omega/pi) into `bands`^2 SH coefficients.
void projectRuntimeLink(const glm::vec3& direction, float omega_over_pi, int bands, float* coeffs);

// Octahedral direction encoding, 2 x snorm16 (max angular error ~0.003 degrees). The map
// divides by the L1 norm, so `dir` may have any non-zero length.
std::uint32_t encodeOctahedral(const glm::vec3& dir);
glm::vec3 decodeOctahedral(std::uint32_t packed);
// encodeOctahedral of (x[i], y[i], z[i]) for i < count into out[i], bit for bit, eight
// directions per step where the CPU has vectors (what link generation calls per cache).
void encodeOctahedral(const float* x, const float* y, const float* z, std::uint32_t count, std::uint32_t* out);

}  // namespace lightlink::links
