#include "core/links/hit_credit.h"

#include <algorithm>
#include <bit>

#include <glm/glm.hpp>

#include "core/common/avx512.h"
#include "core/links/surfel_locator.h"

namespace lightlink::links {
namespace {

// What a ray needs instead of a raster load: it escaped, it is blocked, or the locator's full
// lookup must find its owner.
constexpr std::uint32_t kEscaped = 0xffffffffu, kBlocked = 0xfffffffeu, kAskLocator = 0xfffffffdu;

// Pass 1 of the scalar kernel over rays [i0, i1): each ray's class or raster slot, and the
// raster loads started (the rasters are MiBs and every hit lands on another line, so the
// loads must overlap: precompute_bench's "credit" phase on the Cornell box and zdm2).
void classify(const rt::RayFan& fan, const rt::HitArrays& hits, const std::uint32_t* double_sided,
              const SurfelLocator& locator, std::uint32_t i0, std::uint32_t i1, std::uint32_t* slot, float* escaped) {
  for (std::uint32_t i = i0; i < i1; ++i) {
    const std::uint32_t mesh = hits.mesh[i];
    escaped[i] = mesh != rt::kNoHit ? 0.0f : 1.0f;
    if (mesh == rt::kNoHit) {
      slot[i] = kEscaped;
      continue;
    }
    const bool back = rt::backFacing(glm::vec3(hits.ng_x[i], hits.ng_y[i], hits.ng_z[i]),
                                     glm::vec3(fan.dir_x[i], fan.dir_y[i], fan.dir_z[i]));
    if (back && !double_sided[mesh]) {
      slot[i] = kBlocked;
      continue;
    }
    const std::uint32_t k = locator.rasterSlot(locator.sideMesh(mesh, back), hits.triangle[i], hits.u[i], hits.v[i]);
    slot[i] = k == kNoSurfel ? kAskLocator : k;
    if (k != kNoSurfel) __builtin_prefetch(locator.slotAddress(k));
  }
}

// Pass 2 over the same rays: the owners, appended in ray order.
void credit(const rt::RayFan& fan, const rt::HitArrays& hits, const SurfelLocator& locator, std::uint32_t i0,
            std::uint32_t i1, const std::uint32_t* slot, Sample* samples, HitCredit& c) {
  std::uint32_t sampled = c.sampled, escaped = 0, back_hits = 0, unowned = 0;
  for (std::uint32_t i = i0; i < i1; ++i) {
    if (slot[i] == kEscaped) {
      ++escaped;
      continue;
    }
    if (slot[i] == kBlocked) {
      ++back_hits;
      continue;
    }
    std::uint32_t owner = slot[i] == kAskLocator ? kNoSurfel : locator.slotOwner(slot[i]);
    if (owner == kNoSurfel) {
      // Stray hits (a raster cell beyond a hypotenuse, a triangle without a surfel to stand
      // for it): the full lookup. The visible side's normal faces the cache (left
      // unnormalised: the locator only needs it when it falls back to its grid).
      const glm::vec3 dir(fan.dir_x[i], fan.dir_y[i], fan.dir_z[i]);
      const glm::vec3 ng(hits.ng_x[i], hits.ng_y[i], hits.ng_z[i]);
      const bool back = rt::backFacing(ng, dir);
      owner = locator.ownerOfHit(locator.sideMesh(hits.mesh[i], back), hits.triangle[i], hits.u[i], hits.v[i],
                                 fan.origin + hits.t[i] * dir, back ? -ng : ng);
    }
    if (owner == kNoSurfel) {
      ++unowned;
      continue;
    }
    samples[sampled++] = makeSample(owner, i);
  }
  c.sampled = sampled;
  c.escaped += escaped;
  c.back_hits += back_hits;
  c.unowned += unowned;
}

HitCredit creditScalar(const rt::RayFan& fan, const rt::HitArrays& hits, const std::uint32_t* double_sided,
                       const SurfelLocator& locator, std::uint32_t* slots, float* escaped, Sample* samples) {
  const auto n = static_cast<std::uint32_t>(fan.count);
  HitCredit c;
  classify(fan, hits, double_sided, locator, 0, n, slots, escaped);
  credit(fan, hits, locator, 0, n, slots, samples, c);
  return c;
}

#if LL_AVX512
// 16 rays per step, in three passes over the fan. The table reads are gathers, and each
// pass makes at most one gather per step that depends on another pass's data: pass 1 the
// triangle's global index (from the mesh), pass 2 its raster reference and the slot (and it
// starts the owner loads), pass 3 the owners. In one pass each step would wait on a chain
// of four dependent gathers (mesh, triangle, reference, owner) and steps would hardly
// overlap; three passes let them (`precompute_bench --hit-credit best|scalar` on
// CornellBox-Original compares this kernel with the scalar one). A step with a stray hit
// (the locator's full lookup) finishes in the scalar credit() over its 16 rays, which keeps
// the samples in ray order.
// RasterRef's axis() for 16 lanes: w * size clamped to [0, size - 1] (NaN -> size - 1), then
// truncated. A function of its own, not a lambda: clang gives a lambda no target attribute.
LL_AVX512_FN inline __m512i rasterAxis(const float* w, __mmask16 lanes, __m512 size_f, __m512 max_f) {
  __m512 x = _mm512_mul_ps(_mm512_maskz_loadu_ps(lanes, w), size_f);
  x = _mm512_mask_blend_ps(_mm512_cmp_ps_mask(x, max_f, _CMP_LT_OQ), max_f, x);  // NaN -> max_f
  x = _mm512_mask_blend_ps(_mm512_cmp_ps_mask(x, _mm512_setzero_ps(), _CMP_GT_OQ), _mm512_setzero_ps(), x);
  return _mm512_cvttps_epu32(x);
}

LL_AVX512_FN HitCredit creditAvx512(const rt::RayFan& fan, const rt::HitArrays& hits,
                                    const std::uint32_t* double_sided, const SurfelLocator& locator,
                                    std::uint32_t* slots, float* escaped, Sample* samples) {
  const SurfelLocator::RasterTables tab = locator.rasterTables();
  const auto n = static_cast<std::uint32_t>(fan.count);
  const std::uint32_t mesh_limit = tab.mesh_first_count == 0 ? 0u : tab.mesh_first_count - 1;
  const std::uint32_t triangles = tab.mesh_first_count == 0 ? 0u : tab.mesh_first[tab.mesh_first_count - 1];
  const auto* ds = reinterpret_cast<const int*>(double_sided);
  const auto* mesh_first = reinterpret_cast<const int*>(tab.mesh_first);
  // With up to 16 meshes their first triangles fit one register: a permute instead of a gather.
  const bool few_meshes = mesh_limit <= 16;
  const __m512i mesh_first_table =
      few_meshes ? _mm512_maskz_loadu_epi32(firstLanes(mesh_limit), mesh_first)
                 : _mm512_setzero_si512();
  const auto* ref64 = reinterpret_cast<const long long*>(tab.raster_ref);
  const __m512i even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
  const __m512i odd = _mm512_add_epi32(even, _mm512_set1_epi32(1));
  const __m512i zero = _mm512_setzero_si512();
  const __m512i none = _mm512_set1_epi32(static_cast<int>(kNoSurfel));
  const __m512 zero_f = _mm512_setzero_ps(), one_f = _mm512_set1_ps(1.0f);
  const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  HitCredit c;
  std::uint32_t escaped_count = 0, back_hits = 0;
  for (std::uint32_t i0 = 0; i0 < n; i0 += 16) {
    const __mmask16 lanes = firstLanes(n - i0);
    const __m512i mesh = _mm512_maskz_loadu_epi32(lanes, hits.mesh + i0);
    const __mmask16 hit = _mm512_mask_cmpneq_epu32_mask(lanes, mesh, _mm512_set1_epi32(static_cast<int>(rt::kNoHit)));
    _mm512_mask_storeu_ps(escaped + i0, lanes, _mm512_mask_blend_ps(hit, one_f, zero_f));
    // rt::backFacing: dot(ng, dir) > 0, summed in glm's order (x + y) + z.
    const __m512 dot = _mm512_add_ps(
        _mm512_add_ps(_mm512_mul_ps(_mm512_maskz_loadu_ps(hit, hits.ng_x + i0), _mm512_maskz_loadu_ps(hit, fan.dir_x + i0)),
                      _mm512_mul_ps(_mm512_maskz_loadu_ps(hit, hits.ng_y + i0), _mm512_maskz_loadu_ps(hit, fan.dir_y + i0))),
        _mm512_mul_ps(_mm512_maskz_loadu_ps(hit, hits.ng_z + i0), _mm512_maskz_loadu_ps(hit, fan.dir_z + i0)));
    const __mmask16 back = _mm512_mask_cmp_ps_mask(hit, dot, zero_f, _CMP_GT_OQ);
    __mmask16 blocked = 0;
    if (back != 0) blocked = _mm512_mask_cmpeq_epi32_mask(back, _mm512_mask_i32gather_epi32(zero, back, mesh, ds, 4), zero);
    const __mmask16 live = hit & static_cast<__mmask16>(~blocked);
    // A live back hit is on a double-sided mesh: its back side's tables (SurfelLocator::sideMesh).
    const __m512i side = _mm512_mask_add_epi32(mesh, back & live, mesh, _mm512_set1_epi32(static_cast<int>(tab.mesh_count)));
    const __mmask16 mesh_ok = _mm512_mask_cmplt_epu32_mask(live, side, _mm512_set1_epi32(static_cast<int>(mesh_limit)));
    const __m512i base = few_meshes ? _mm512_maskz_permutexvar_epi32(mesh_ok, side, mesh_first_table)
                                    : _mm512_mask_i32gather_epi32(zero, mesh_ok, side, mesh_first, 4);
    const __m512i tri = _mm512_add_epi32(base, _mm512_maskz_loadu_epi32(mesh_ok, hits.triangle + i0));
    const __mmask16 tri_ok = _mm512_mask_cmplt_epu32_mask(mesh_ok, tri, _mm512_set1_epi32(static_cast<int>(triangles)));
    __m512i code = _mm512_mask_blend_epi32(tri_ok, _mm512_set1_epi32(static_cast<int>(kAskLocator)), tri);
    code = _mm512_mask_blend_epi32(blocked, code, _mm512_set1_epi32(static_cast<int>(kBlocked)));
    code = _mm512_mask_blend_epi32(static_cast<__mmask16>(lanes & ~hit), code, _mm512_set1_epi32(static_cast<int>(kEscaped)));
    _mm512_mask_storeu_epi32(slots + i0, lanes, code);
  }
  // Pass 2: the raster slots, and the owner loads started. A lane holds a global triangle
  // (below every code: there are fewer than 2^32 - 3 triangles) or pass 1's code.
  for (std::uint32_t i0 = 0; i0 < n; i0 += 16) {
    const __mmask16 lanes = firstLanes(n - i0);
    const __m512i tri = _mm512_maskz_loadu_epi32(lanes, slots + i0);
    const __mmask16 tri_ok = _mm512_mask_cmplt_epu32_mask(lanes, tri, _mm512_set1_epi32(static_cast<int>(kAskLocator)));
    // Each triangle's (first, size) as one 8-byte word (RasterRef is 16 bytes): two gathers
    // of 8 words, 16 loads, where one gather per field made 32.
    const __m512i t2 = _mm512_slli_epi32(tri, 1);
    const __m512i empty = _mm512_set1_epi64(static_cast<long long>(kNoSurfel));  // first none, size 0
    const __m512i ref_lo = _mm512_mask_i32gather_epi64(empty, static_cast<__mmask8>(tri_ok), _mm512_castsi512_si256(t2),
                                                       ref64, 8);
    const __m512i ref_hi = _mm512_mask_i32gather_epi64(empty, static_cast<__mmask8>(tri_ok >> 8),
                                                       _mm512_extracti64x4_epi64(t2, 1), ref64, 8);
    const __m512i first = _mm512_permutex2var_epi32(ref_lo, even, ref_hi);
    const __m512i size = _mm512_permutex2var_epi32(ref_lo, odd, ref_hi);
    const __mmask16 rastered = _mm512_mask_cmpneq_epu32_mask(tri_ok, first, none);
    // RasterRef's size_f and max_f, which are these conversions (exact: sizes are < 2^24).
    const __m512 size_f = _mm512_cvtepu32_ps(size);
    const __m512 max_f = _mm512_cvtepu32_ps(_mm512_sub_epi32(size, _mm512_set1_epi32(1)));
    __m512i slot = _mm512_add_epi32(_mm512_add_epi32(first, _mm512_mullo_epi32(rasterAxis(hits.v + i0, rastered, size_f, max_f), size)),
                                    rasterAxis(hits.u + i0, rastered, size_f, max_f));
    slot = _mm512_mask_blend_epi32(rastered, _mm512_mask_blend_epi32(tri_ok, tri, _mm512_set1_epi32(static_cast<int>(kAskLocator))), slot);
    _mm512_mask_storeu_epi32(slots + i0, lanes, slot);
    // The raster loads started for all 16 lanes (slot 0 for a lane without one): a loop over
    // the set lanes only would end on a data-dependent branch.
    alignas(64) std::uint32_t pf[16];
    _mm512_store_si512(pf, _mm512_maskz_mov_epi32(rastered, slot));
    for (int l = 0; l < 16; ++l) __builtin_prefetch(locator.slotAddress(pf[l]));
  }
  // Pass 3: the owners.
  for (std::uint32_t i0 = 0; i0 < n; i0 += 16) {
    const __mmask16 lanes = firstLanes(n - i0);
    const __m512i slot = _mm512_maskz_loadu_epi32(lanes, slots + i0);
    const __mmask16 escaped_lanes = _mm512_mask_cmpeq_epi32_mask(lanes, slot, _mm512_set1_epi32(static_cast<int>(kEscaped)));
    const __mmask16 blocked = _mm512_mask_cmpeq_epi32_mask(lanes, slot, _mm512_set1_epi32(static_cast<int>(kBlocked)));
    const __mmask16 ask = _mm512_mask_cmpeq_epi32_mask(lanes, slot, _mm512_set1_epi32(static_cast<int>(kAskLocator)));
    const __mmask16 live = lanes & static_cast<__mmask16>(~(escaped_lanes | blocked));
    const __mmask16 rastered = live & static_cast<__mmask16>(~ask);
    __m512i owner;
    if (tab.raster16 != nullptr) {
      owner = _mm512_and_si512(_mm512_mask_i32gather_epi32(zero, rastered, slot, tab.raster16, 2),
                               _mm512_set1_epi32(0xffff));
      owner = _mm512_mask_blend_epi32(_mm512_cmpeq_epi32_mask(owner, _mm512_set1_epi32(0xffff)), owner, none);
    } else {
      owner = _mm512_mask_i32gather_epi32(none, rastered, slot, tab.raster32, 4);
    }
    const __mmask16 stray = ask | _mm512_mask_cmpeq_epi32_mask(rastered, owner, none);
    if (stray != 0) {
      credit(fan, hits, locator, i0, std::min(n, i0 + 16), slots, samples, c);
      continue;
    }
    escaped_count += static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(escaped_lanes)));
    back_hits += static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(blocked)));
    // Samples (owner << 32 | ray), the live lanes' packed in lane (= ray) order.
    const __m512i ray = _mm512_add_epi32(_mm512_set1_epi32(static_cast<int>(i0)), iota);
    const __m512i lo = _mm512_or_si512(_mm512_slli_epi64(_mm512_cvtepu32_epi64(_mm512_castsi512_si256(owner)), 32),
                                       _mm512_cvtepu32_epi64(_mm512_castsi512_si256(ray)));
    const __m512i hi = _mm512_or_si512(_mm512_slli_epi64(_mm512_cvtepu32_epi64(_mm512_extracti64x4_epi64(owner, 1)), 32),
                                       _mm512_cvtepu32_epi64(_mm512_extracti64x4_epi64(ray, 1)));
    const auto live_lo = static_cast<__mmask8>(live & 0xff), live_hi = static_cast<__mmask8>(live >> 8);
    // Packed in a register and stored whole (the slack): a compressing store to memory is
    // microcoded on Zen 4/5.
    _mm512_storeu_si512(samples + c.sampled, _mm512_maskz_compress_epi64(live_lo, lo));
    c.sampled += static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(live_lo)));
    _mm512_storeu_si512(samples + c.sampled, _mm512_maskz_compress_epi64(live_hi, hi));
    c.sampled += static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(live_hi)));
  }
  c.escaped += escaped_count;
  c.back_hits += back_hits;
  return c;
}
#endif

}  // namespace

std::vector<std::uint32_t> doubleSidedByMesh(const scene::Scene& scene) {
  std::vector<std::uint32_t> double_sided(scene.meshes.size());
  for (std::size_t m = 0; m < scene.meshes.size(); ++m)
    double_sided[m] = scene.materialOf(scene.meshes[m]).double_sided ? 1 : 0;
  return double_sided;
}

HitCreditKernel hitCreditKernelRun(HitCreditKernel requested) {
  return requested != HitCreditKernel::kScalar && isaAtLeast(Isa::kAvx512) ? HitCreditKernel::kAvx512
                                                                        : HitCreditKernel::kScalar;
}

HitCredit creditHits(const rt::RayFan& fan, const rt::HitArrays& hits, const std::uint32_t* double_sided,
                     const SurfelLocator& locator, std::uint32_t* slots, float* escaped, Sample* samples,
                     HitCreditKernel kernel) {
#if LL_AVX512
  if (hitCreditKernelRun(kernel) == HitCreditKernel::kAvx512)
    return creditAvx512(fan, hits, double_sided, locator, slots, escaped, samples);
#else
  (void)kernel;
#endif
  return creditScalar(fan, hits, double_sided, locator, slots, escaped, samples);
}

}  // namespace lightlink::links
