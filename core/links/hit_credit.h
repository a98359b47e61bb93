// Hit credit: the step of link generation between the trace and the sort. Every ray of a
// cache's fan is classed as escaped (sky), blocked (the back of a single-sided surface) or a
// front hit, and each front hit is credited to the surfel that owns the hit point
// (SurfelLocator) as a Sample (owner, ray), appended in ray order.
//
// Two kernels give the same bits: a scalar one, and on x86-64 CPUs with AVX-512 (F, BW, VL,
// DQ) one that classes 16 rays per step and reads the raster tables and owners with gathers.
// Where Embree's own AVX-512 kernels make tracing fast, this step is a visible share of link
// generation and the AVX-512 kernel takes less of it (precompute_bench --hit-credit
// scalar|best).
// The kernel is chosen once per process from what the CPU reports unless LinkOptions names
// one; the tests compare every kernel the CPU can run with the ray-by-ray definition.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/links/cut.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::links {

class SurfelLocator;  // surfel_locator.h

struct HitCredit {
  std::uint32_t sampled = 0;    // front hits credited (samples written)
  std::uint32_t escaped = 0;    // rays that hit nothing
  std::uint32_t back_hits = 0;  // rays blocked by the back of a single-sided surface
  std::uint32_t unowned = 0;    // front hits no surfel owns
};

enum class HitCreditKernel { kBest, kScalar, kAvx512 };

// The kernel creditHits runs when asked for `requested`: kAvx512 or kScalar.
HitCreditKernel hitCreditKernelRun(HitCreditKernel requested);

// Samples the kernels may write past the last credited one (whole vectors are stored).
inline constexpr std::size_t kHitCreditSlack = 16;

// Per mesh of the scene, whether back faces are visible (a double-sided material): what
// creditHits reads as `double_sided`. One load per hit instead of a walk through the mesh
// and material records; a word, so the AVX-512 kernel can gather it.
std::vector<std::uint32_t> doubleSidedByMesh(const scene::Scene& scene);

// Credits the fan's hits: `samples` receives (owner, ray) for every credited hit in ray
// order (it must hold fan.count + kHitCreditSlack) and `escaped` 1.0 for a ray that
// escaped, else 0.0 (both fan.count long). `double_sided` holds one word per mesh, non-zero
// where back faces are visible. `slots` is scratch of fan.count words. kAvx512 on a CPU
// without it runs the scalar kernel. (Which surfels were seen, link generation marks in its
// sort, which reads every sample anyway.)
HitCredit creditHits(const rt::RayFan& fan, const rt::HitArrays& hits, const std::uint32_t* double_sided,
                     const SurfelLocator& locator, std::uint32_t* slots, float* escaped, Sample* samples,
                     HitCreditKernel kernel = HitCreditKernel::kBest);

}  // namespace lightlink::links
