// Direct light at a set of points, and lightmap texels from per-point values (internal to
// core/relight): what the Relighter and the DirectLayer share. The points are surfels,
// lightmap caches or the direct layer's texels; each helper is deterministic for any TBB
// thread count (fixed chunks, disjoint writes).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/caches/caches.h"
#include "core/relight/emitter_direct.h"
#include "core/relight/light_set.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::relight::detail {

// Surfels / caches per TBB task: large enough that a task amortises its shadow-ray batch,
// small enough to balance on 2..16 cores. Fixed, so results do not depend on the split.
constexpr std::size_t kChunk = 256;
constexpr std::size_t kCacheChunk = 64;

// Runs body(chunk, begin, end) over fixed chunks [chunk * size, min(n, (chunk + 1) * size)) in
// parallel. Chunk boundaries do not depend on the thread count, so per-chunk partial sums
// combined in chunk order are deterministic (TBB's own range splitting is not aligned).
template <typename F>
void forChunks(std::size_t n, std::size_t size, F&& body) {
  const std::size_t chunks = (n + size - 1) / size;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t c = r.begin(); c < r.end(); ++c) body(c, c * size, std::min(n, (c + 1) * size));
  });
}

bool sameEmissive(const std::vector<EmissiveOverride>& a, const std::vector<EmissiveOverride>& b);
bool lightEmits(const scene::Light& l);
// Can `light` give non-zero irradiance at p? Geometric only (range sphere, spot cone); the
// incremental relight re-lights exactly the surfels for which this holds before or after.
bool reaches(const scene::Light& l, const glm::vec3& p);

// The shadow ray from surface point pos (geometric normal nrm) to `light`.
rt::Ray shadowRay(const rt::Accel& accel, const scene::Light& light, glm::vec3 pos, glm::vec3 nrm);

// Where the shadow rays of a point start. Every point tests its centre; with a footprint, a
// point whose centre's visibility differs from a neighbour's (a shadow edge runs near it)
// then tests `rays` points spread over the disk of area area[k] around it (a surfel's
// footprint), and their visible fraction scales its light. A surfel lit from its centre alone
// switches between lit and dark at once as a shadow edge sweeps over it, and the indirect
// light it sends pops (docs/quality.md, "Temporal stability"); over its footprint it fades.
// The neighbours (footprintNeighbours) lie all around a point, further than its footprint's
// radius, so an edge reaches the footprint only after it has passed between two centres.
struct Footprint {
  std::span<const float> area;  // empty: every ray from the centre
  int rays = 1;
  std::span<const std::uint32_t> neighbour_begin, neighbour;  // CSR over the points
};

// Up to 24 nearest points within 4 disk radii (sqrt(area / pi)) of each point, as CSR.
void footprintNeighbours(std::span<const glm::vec3> position, std::span<const float> area,
                         std::vector<std::uint32_t>& begin, std::vector<std::uint32_t>& neighbour);

// Shadowed direct irradiance of one light at a set of points (surfels or lightmap caches):
// irradianceFrom() times the visible fraction of the footprint's shadow rays, batched per
// chunk. `valid` (optional) masks points that get no light; `subset` (optional) restricts
// the work to those indices.
void shadowedLight(const rt::Accel& accel, const scene::Light& light, std::span<const glm::vec3> position,
                   std::span<const glm::vec3> normal, std::span<const std::uint8_t> valid,
                   const std::vector<std::uint32_t>* subset, std::vector<glm::vec3>& out, std::size_t& rays,
                   rt::Coherence coherence, Footprint footprint = {});

// The emitters' direct irradiance at every valid point (0 at invalid ones) per sampler layer
// (RGB at layers[3 * (point * layers + layer)]), `samples` shadow rays each, seeded by the
// point's texel or'ed with `salt` (so a texel's noise depends on neither the point order nor
// the split, and the direct layer's texels differ from the caches'); adds the rays traced
// to `rays`.
void sampleEmitters(const EmitterSampler& sampler, const caches::LightmapCaches& points, int samples,
                    std::uint64_t salt, std::vector<float>& layers, std::size_t& rays);

// The SH (`bands` bands, 3 * bands^2 floats per point and layer) of the radiance the emitters
// send each valid grid cache over the whole sphere (0 at invalid ones), per sampler layer,
// `samples` shadow rays each, seeded by the cache's index. Adds the rays traced to `rays`.
void sampleEmittersSh(const EmitterSampler& sampler, const caches::GridCaches& grid, int bands, int samples,
                      std::vector<float>& layers, std::size_t& rays);

// Per point: 1 when it holds a value after `fill` (valid, or a fill target with sources).
std::vector<std::uint8_t> hasValue(const std::vector<std::uint8_t>& valid, const caches::FillPlan& fill);

// Applies a fill plan to `data` (stride floats per entry), front to back: a target may read
// targets filled before it (the plan's order).
void applyFill(const caches::FillPlan& plan, float* data, std::size_t stride);

// Which points each texel of a width x height atlas reads, and with what weight: its own
// point, or for a dilated texel the points its dilation sources average to (flattened once,
// so writing texels is one parallel gather). Texels without an entry are empty.
struct TexelMap {
  std::vector<std::uint32_t> begin;  // texels + 1 offsets
  std::vector<std::uint32_t> point;
  std::vector<float> weight;
};
TexelMap buildTexelMap(const std::vector<std::int32_t>& point_of_texel, const std::vector<std::uint8_t>& has_value,
                       const caches::FillPlan& dilation);

}  // namespace lightlink::relight::detail
