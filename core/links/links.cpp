#include "core/links/links.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstddef>
#include <cmath>
#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#include <x86intrin.h>
#endif
#include <numbers>
#include <mutex>
#include <shared_mutex>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include <tbb/concurrent_queue.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include "core/common/aligned_vector.h"
#include "core/common/check.h"
#include "core/common/memory.h"
#include "core/common/isa.h"
#include "core/common/sampling.h"
#include "core/links/cut.h"
#include "core/links/hit_credit.h"
#include "core/links/sample_sort.h"
#include "core/links/surfel_locator.h"
#include "core/sh/sh.h"

// The row kernel, the sky pass, the link sums and the octahedral codes are LL_ISA_CLONES
// (core/common/isa.h: one version per tier, the same bits). The row kernel
// is plain loops the compiler vectorises; without contraction every lane rounds exactly as the
// scalar code does, so the rays are bit-identical on every machine (the artifact depends on them).

namespace lightlink::links {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
// Caches per parallel work item. Fixed (not derived from the thread count) so results are
// concatenated in the same order whatever the scheduling.
constexpr std::size_t kChunk = 32;

// Rays per cache form a strata x strata stratified grid.
std::uint32_t strataFor(const LinkOptions& options) {
  return static_cast<std::uint32_t>(std::max(1.0, std::floor(std::sqrt(double(options.rays)))));
}

// Per-thread scratch, reused across caches so the hot loop never allocates.
struct Scratch {
  // The fan's hits, one array per field (rt::HitArrays).
  LineVector<std::uint32_t> hit_mesh, hit_triangle;
  LineVector<float> hit_u, hit_v, hit_t, hit_ng_x, hit_ng_y, hit_ng_z;
  LineVector<Sample> samples;
  LineVector<Sample> sort_buffer;
  std::vector<CutEntry> cut;
  CutScratch cut_scratch;
  LineVector<std::uint32_t> slots;     // per ray: owner raster slot or ray class
  LineVector<float> dir_x, dir_y, dir_z;  // per ray, padded to a multiple of kSkyLanes
  LineVector<float> escaped;           // per ray: 1 escaped, 0 not (0 in the padding)
  LineVector<float> poly;              // per ray (padded), polyRows(bands) rows of 8: the basis polynomials q >= 1
  LineVector<float> link_sums;         // a spare, then per link of the cache polyRows(bands) rows of 8: sums of those
  LineVector<float> coeff_values;      // per link of the cache: its SH in float, then fp16
  LineVector<float> solid_values;
  LineVector<float> link_x, link_y, link_z;  // per link of the cache: the direction to encode
};

// The link arrays are HugeVectors for their allocator's default-initialising resize: each
// cache's links are written right after they are sized, so zeroing them first would be wasted.
struct ChunkResult {
  std::vector<std::uint32_t> count;  // links per cache
  HugeVector<std::uint32_t> node;
  HugeVector<half_bits> coeffs;
  HugeVector<std::uint32_t> direction;
  HugeVector<half_bits> solid_angle;
  std::vector<float> sky;
  LinkStats stats;
  // Empty again, capacity kept: ring slots are reused chunk after chunk.
  void clear() {
    count.clear();
    node.clear();
    coeffs.clear();
    direction.clear();
    solid_angle.clear();
    sky.clear();
    stats = {};
  }
};

// Sky visibility: sums of the basis polynomials over the escaped rays (escaped[i] is 1 or 0),
// in kSkyLanes interleaved partial sums added in a fixed order at the end. Every lane adds in
// ray order, so every LL_ISA_CLONES build of this loop (and the scalar one) gives the same
// bits; a plain reduction would not vectorise without reassociating. Most rays of an open
// scene escape, so this pass is a large share of its link time (precompute_bench's "sky"
// phase on ShadowsDirectional).
// The same pass keeps every ray's polynomials (q >= 1) for the links' projection, which sums
// them over each link's hits instead of evaluating them again per hit. They are kept ray by
// ray (polyRows rows of 8 floats per ray, transposed from the pass's 8-ray vectors in
// registers), so that adding a hit to its link is one 8-float load and add per row, not one
// scalar load and add per coefficient (precompute_bench's "project" phase).
constexpr std::uint32_t kSkyLanes = 8;
// Rays rounded up to whole groups of lanes: the length of the sky pass's arrays.
constexpr std::uint32_t skyPadded(std::uint32_t rays) { return (rays + kSkyLanes - 1) / kSkyLanes * kSkyLanes; }
// Rows of 8 floats that hold one ray's polynomials q = 1 .. bands^2 - 1 (the last row padded
// with zeros): 0, 1, 1, 2 for 1..4 bands.
constexpr int polyRows(int bands) { return (bands * bands - 1 + 7) / 8; }

// Eight floats as one GCC vector: the sky pass below is written on it so that it stays
// vectorised while it also stores every ray's polynomials (written on scalars with those
// stores, GCC 12 compiles it to scalar code; precompute_bench's "sky" phase shows it).
typedef float Lanes8 __attribute__((vector_size(32)));
typedef std::int32_t Ints8 __attribute__((vector_size(32)));
static_assert(kSkyLanes == 8);

// r[j] lane i -> dst[i * stride + j]: the 8x8 transpose in three rounds of two-input
// shuffles (unpack, shufps, 128-bit moves under AVX2), each row stored as it is formed (GCC
// spills an array of the rows to the stack and copies it back). Moves bits only, so every
// build agrees.
__attribute__((always_inline)) inline void transpose8(const Lanes8* r, float* dst, std::size_t stride) {
#define LL_LO(a, b) __builtin_shufflevector(a, b, 0, 8, 1, 9, 4, 12, 5, 13)
#define LL_HI(a, b) __builtin_shufflevector(a, b, 2, 10, 3, 11, 6, 14, 7, 15)
#define LL_PAIRS_LO(a, b) __builtin_shufflevector(a, b, 0, 1, 8, 9, 4, 5, 12, 13)
#define LL_PAIRS_HI(a, b) __builtin_shufflevector(a, b, 2, 3, 10, 11, 6, 7, 14, 15)
#define LL_HALVES_LO(a, b) __builtin_shufflevector(a, b, 0, 1, 2, 3, 8, 9, 10, 11)
#define LL_HALVES_HI(a, b) __builtin_shufflevector(a, b, 4, 5, 6, 7, 12, 13, 14, 15)
  const Lanes8 t0 = LL_LO(r[0], r[1]), t1 = LL_HI(r[0], r[1]);
  const Lanes8 t2 = LL_LO(r[2], r[3]), t3 = LL_HI(r[2], r[3]);
  const Lanes8 t4 = LL_LO(r[4], r[5]), t5 = LL_HI(r[4], r[5]);
  const Lanes8 t6 = LL_LO(r[6], r[7]), t7 = LL_HI(r[6], r[7]);
  const Lanes8 u0 = LL_PAIRS_LO(t0, t2), u1 = LL_PAIRS_HI(t0, t2);
  const Lanes8 u2 = LL_PAIRS_LO(t1, t3), u3 = LL_PAIRS_HI(t1, t3);
  const Lanes8 u4 = LL_PAIRS_LO(t4, t6), u5 = LL_PAIRS_HI(t4, t6);
  const Lanes8 u6 = LL_PAIRS_LO(t5, t7), u7 = LL_PAIRS_HI(t5, t7);
  const Lanes8 o[8] = {LL_HALVES_LO(u0, u4), LL_HALVES_LO(u1, u5), LL_HALVES_LO(u2, u6), LL_HALVES_LO(u3, u7),
                       LL_HALVES_HI(u0, u4), LL_HALVES_HI(u1, u5), LL_HALVES_HI(u2, u6), LL_HALVES_HI(u3, u7)};
#undef LL_LO
#undef LL_HI
#undef LL_PAIRS_LO
#undef LL_PAIRS_HI
#undef LL_HALVES_LO
#undef LL_HALVES_HI
  std::memcpy(dst + 0 * stride, &o[0], sizeof(Lanes8));
  std::memcpy(dst + 1 * stride, &o[1], sizeof(Lanes8));
  std::memcpy(dst + 2 * stride, &o[2], sizeof(Lanes8));
  std::memcpy(dst + 3 * stride, &o[3], sizeof(Lanes8));
  std::memcpy(dst + 4 * stride, &o[4], sizeof(Lanes8));
  std::memcpy(dst + 5 * stride, &o[5], sizeof(Lanes8));
  std::memcpy(dst + 6 * stride, &o[6], sizeof(Lanes8));
  std::memcpy(dst + 7 * stride, &o[7], sizeof(Lanes8));
}

template <int Bands>
__attribute__((always_inline)) inline void skyPolynomialsImpl(const float* __restrict escaped, const float* __restrict x,
                                                              const float* __restrict y, const float* __restrict z,
                                                              std::uint32_t count, float* __restrict sums,
                                                              float* __restrict poly_out) {
  constexpr int kCoeffs = Bands * Bands;
  constexpr int kRows = polyRows(Bands);
  Lanes8 acc[kCoeffs] = {};
  for (std::uint32_t i0 = 0; i0 < count; i0 += kSkyLanes) {
    Lanes8 e, vx, vy, vz;  // unaligned loads (memcpy: no vector-typed function returns)
    std::memcpy(&e, escaped + i0, sizeof e);
    std::memcpy(&vx, x + i0, sizeof vx);
    std::memcpy(&vy, y + i0, sizeof vy);
    std::memcpy(&vz, z + i0, sizeof vz);
    Lanes8 poly[kCoeffs];
    sh::evalBasisPolynomialOf<Bands, Lanes8>(vx, vy, vz, poly);
    for (int q = 1; q < kCoeffs; ++q) acc[q] += e * poly[q];
    for (int row = 0; row < kRows; ++row) {
      Lanes8 in[8];
      for (int j = 0; j < 8; ++j) {
        const int q = 1 + 8 * row + j;
        in[j] = q < kCoeffs ? poly[std::min(q, kCoeffs - 1)] : Lanes8{};  // (min: a valid index in every branch)
      }
      transpose8(in, poly_out + (std::size_t(i0) * kRows + row) * 8, std::size_t(kRows) * 8);
    }
  }
  for (int q = 1; q < kCoeffs; ++q) {
    float sum = 0.0f;
    for (std::uint32_t l = 0; l < kSkyLanes; ++l) sum += acc[q][l];
    sums[q] = sum;
  }
}

// One LL_ISA_CLONES entry per band count (the clones are plain functions, not templates).
// `count` is a multiple of kSkyLanes (the arrays are padded, escaped = 0 there); `poly`
// holds count * polyRows(bands) * 8 floats.
using SkyFn = void (*)(const float*, const float*, const float*, const float*, std::uint32_t, float*, float*);
#define LL_SKY_ENTRY(B)                                                                                   \
  LL_ISA_CLONES(void, sky##B,                                                                             \
                (const float* e, const float* x, const float* y, const float* z, std::uint32_t n, float* s,   \
                 float* poly),                                                                                \
                (e, x, y, z, n, s, poly), skyPolynomialsImpl<B>)
LL_SKY_ENTRY(1)
LL_SKY_ENTRY(2)
LL_SKY_ENTRY(3)
LL_SKY_ENTRY(4)
#undef LL_SKY_ENTRY
template <int Bands>
constexpr SkyFn skyPolynomials = Bands == 1 ? sky1 : Bands == 2 ? sky2 : Bands == 3 ? sky3 : sky4;

// The links' polynomial sums: link l's row r at sums[((l + 1) * polyRows + r) * 8] (the first
// row set is a spare), each the sum of its hits' rows in sample order, from zero: the same
// additions in the same order as a loop per link, so the same bits. One flat loop over the
// samples instead, with no branch: the sample that starts a link (kLinkStart set in its ray
// word) moves the output to the next link and clears the running sums; every sample stores
// them, the link's last one leaving its total. A loop per link ended on a data-dependent
// branch for each of ~125 links per cache. The samples are walked as kSumChains chains,
// chain j from first[j] (the first sample of link link_first[j]; first[0] = 0) to the next
// chain's first sample (the last to n), one step of each in turn, so that one chain's adds
// do not wait on another's.
// Ray indices stay below 2^20 (generateLinks rejects more rays), so the top bit is free.
constexpr std::uint32_t kLinkStart = 0x80000000u;
constexpr int kSumChains = 4;
template <int Bands>
__attribute__((always_inline)) inline void linkSumsImpl(const Sample* __restrict sorted, std::uint32_t n,
                                                        const std::uint32_t* first, const std::uint32_t* link_first,
                                                        const float* __restrict poly, float* __restrict sums) {
  constexpr int kRows = polyRows(Bands);
  constexpr std::size_t kStride = std::size_t(kRows) * 8;
  // The mask that keeps the running sums, and the one that clears them (a load, where
  // broadcasting the start flag took three instructions).
  alignas(32) static constexpr std::int32_t kKeep[2][8] = {{-1, -1, -1, -1, -1, -1, -1, -1}, {}};
  struct Chain {
    Lanes8 acc[kRows];
    float* out;  // the current link's sums
  };
  auto step = [&](Chain& c, std::uint32_t k) {
    const auto word = static_cast<std::uint32_t>(sorted[k]);
    const std::uint32_t start = word >> 31;
    c.out += start * kStride;
    Ints8 keep;
    std::memcpy(&keep, kKeep[start], sizeof keep);
    const float* row = poly + std::size_t(word & ~kLinkStart) * kStride;
    for (int r = 0; r < kRows; ++r) {
      Lanes8 v;
      std::memcpy(&v, row + r * 8, sizeof v);
      c.acc[r] = reinterpret_cast<Lanes8>(reinterpret_cast<Ints8>(c.acc[r]) & keep) + v;
      std::memcpy(c.out + r * 8, &c.acc[r], sizeof(Lanes8));
    }
  };
  // The first sample of each chain's range starts a link, which moves the chain onto it.
  Chain c[kSumChains];
  std::uint32_t at[kSumChains], end[kSumChains], common = n;
  for (int j = 0; j < kSumChains; ++j) {
    c[j] = {{}, sums + std::size_t(link_first[j]) * kStride};
    at[j] = first[j];
    end[j] = j + 1 < kSumChains ? first[j + 1] : n;
    common = std::min(common, end[j] - at[j]);
  }
  for (std::uint32_t i = 0; i < common; ++i)
    for (int j = 0; j < kSumChains; ++j) step(c[j], at[j] + i);
  for (int j = 0; j < kSumChains; ++j)
    for (std::uint32_t k = at[j] + common; k < end[j]; ++k) step(c[j], k);
}
using LinkSumsFn = void (*)(const Sample*, std::uint32_t, const std::uint32_t*, const std::uint32_t*, const float*,
                            float*);
#define LL_SUMS_ENTRY(B)                                                                                   \
  LL_ISA_CLONES(void, linkSums##B,                                                                        \
                (const Sample* sorted, std::uint32_t n, const std::uint32_t* first,                          \
                 const std::uint32_t* link_first, const float* poly, float* sums),                           \
                (sorted, n, first, link_first, poly, sums), linkSumsImpl<B>)
LL_SUMS_ENTRY(2)
LL_SUMS_ENTRY(3)
LL_SUMS_ENTRY(4)
#undef LL_SUMS_ENTRY
template <int Bands>
constexpr LinkSumsFn linkSums = Bands == 2 ? linkSums2 : Bands == 3 ? linkSums3 : linkSums4;

// One octahedral code (encodeOctahedral's formula: the same operations in the same order,
// so the same bits).
inline std::uint32_t octahedralCode(float x, float y, float z) {
  const float inv = 1.0f / (std::abs(x) + std::abs(y) + std::abs(z));
  const float ox = x * inv, oy = y * inv;
  const float fx = (1.0f - std::abs(oy)) * (ox >= 0.0f ? 1.0f : -1.0f);
  const float fy = (1.0f - std::abs(ox)) * (oy >= 0.0f ? 1.0f : -1.0f);
  const float u = z < 0.0f ? fx : ox, v = z < 0.0f ? fy : oy;
  // Round to nearest (even on ties: lrint is one instruction, where lround was a libm call
  // per link).
  auto q = [](float c) {
    return static_cast<std::uint32_t>(static_cast<std::uint16_t>(
        static_cast<std::int16_t>(std::lrint(std::clamp(c, -1.0f, 1.0f) * 32767.0f))));
  };
  return q(u) | (q(v) << 16);
}

// Laps of linkCache's phases into LinkStats::phase_ticks (benchmark builds, kPhaseProbes);
// elsewhere every lap compiles to nothing.
class PhaseClock {
 public:
  explicit PhaseClock(std::array<std::uint64_t, kLinkPhases>& ticks)
      : ticks_(ticks), last_(kPhaseProbes ? now() : 0) {}
  void lap(LinkPhase phase) {
    if constexpr (!kPhaseProbes) return;
    const std::uint64_t t = now();
    ticks_[phase] += t - last_;
    last_ = t;
  }
  static std::uint64_t now() {
#if defined(__x86_64__) || defined(__i386__)
    return __rdtsc();
#else
    return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                          std::chrono::steady_clock::now().time_since_epoch())
                                          .count());
#endif
  }

 private:
  std::array<std::uint64_t, kLinkPhases>& ticks_;
  std::uint64_t last_;
};

template <int Bands>
void linkCache(std::size_t cache, const glm::vec3& p, const glm::vec3& normal, const std::uint32_t* double_sided,
               const rt::Accel& accel, const CutTree& cut_tree, const SurfelLocator& locator,
               const LinkOptions& options, const LinkRays& pattern, std::uint32_t surfel_bits, Scratch& s,
               std::uint8_t* seen, ChunkResult& out) {
  constexpr int kCoeffs = Bands * Bands;
  PhaseClock clock(out.stats.phase_ticks);
  const bool hemisphere = glm::dot(normal, normal) > 0.0f;
  const std::uint32_t count = pattern.count();
  const glm::vec3 n = hemisphere ? glm::normalize(normal) : glm::vec3(0, 0, 1);
  const LinkRays::Directions dirs{s.dir_x.data(), s.dir_y.data(), s.dir_z.data()};
  // Traced as a fan: directions and hits stay in arrays from the generator through Embree's
  // packets to the loops below (docs/precompute.md, "Tracing a fan").
  const rt::RayFan fan = pattern.fan(accel, cache, p, normal, dirs);
  const rt::HitArrays hits{s.hit_mesh.data(), s.hit_triangle.data(), s.hit_u.data(), s.hit_v.data(),
                           s.hit_t.data(),    s.hit_ng_x.data(),     s.hit_ng_y.data(), s.hit_ng_z.data()};
  clock.lap(kPhaseRays);
  accel.intersectFan(fan, hits);
  clock.lap(kPhaseTrace);

  const float omega = hemisphere ? 2.0f * kPi : 4.0f * kPi;
  const float w = omega / static_cast<float>(count) / kPi;  // per-ray weight of V/pi
  float* escaped_mask = s.escaped.data();  // 1 for a ray that escaped, else 0
  // The sky pass reads whole groups of kSkyLanes: the padding counts nothing.
  const std::uint32_t padded = skyPadded(count);
  for (std::uint32_t i = count; i < padded; ++i) escaped_mask[i] = dirs.x[i] = dirs.y[i] = dirs.z[i] = 0.0f;
  const HitCredit credited = creditHits(fan, hits, double_sided, locator, s.slots.data(), escaped_mask,
                                       s.samples.data(), options.hit_credit);
  const std::size_t sampled = credited.sampled;
  const std::uint32_t escaped = credited.escaped;
  clock.lap(kPhaseCredit);
  out.stats.rays += count;
  out.stats.escaped += escaped;
  out.stats.back_hits += credited.back_hits;
  out.stats.unowned += credited.unowned;
  out.stats.front_hits += sampled;
  float sky_poly[kCoeffs];  // sums of the basis polynomials over the escaped rays
  float* const poly = s.poly.data();  // ray i's Y_q polynomial at [i * polyRows * 8 + q - 1]
  skyPolynomials<Bands>(escaped_mask, dirs.x, dirs.y, dirs.z, padded, sky_poly, poly);
  sky_poly[0] = static_cast<float>(escaped);
  float sky[kCoeffs];
  for (int q = 0; q < kCoeffs; ++q) sky[q] = w * sh::kBasisScale[q] * sky_poly[q];
  clock.lap(kPhaseSky);
  Sample* const sorted = sortSamples(s.samples.data(), s.sort_buffer.data(), sampled, surfel_bits, seen);
  clock.lap(kPhaseSort);
  chooseCut(cut_tree, std::span<const Sample>(sorted, sampled), options.max_links, s.cut_scratch, s.cut);
  clock.lap(kPhaseCut);

  // Each link's SH is w * sum over its hits of Y_q(dir) = w * kBasisScale[q] * (sum of the
  // basis polynomials): a few multiplies per hit instead of one per coefficient. Values go
  // to scratch first and to fp16 in two batches (8 per instruction with F16C).
  float* coeff_values = s.coeff_values.data();
  float* solid_values = s.solid_values.data();
  const std::size_t links = s.cut.size();
  // link l's polynomial q at [(l + 1) * polyRows * 8 + q - 1], after linkSums's spare row set
  float* const link_sums = s.link_sums.data();
  if constexpr (Bands >= 2) {
    if (links > 0) {
      // The sorted keys are scratch: a link's first sample carries the start flag from here.
      for (const CutEntry& e : s.cut) sorted[e.first] |= kLinkStart;
      std::uint32_t first[kSumChains], link_first[kSumChains];
      for (int j = 0; j < kSumChains; ++j) {
        link_first[j] = static_cast<std::uint32_t>(links * std::size_t(j) / kSumChains);
        first[j] = s.cut[link_first[j]].first;
      }
      linkSums<Bands>(sorted, static_cast<std::uint32_t>(sampled), first, link_first, poly, link_sums);
    }
  }
  float scale[kCoeffs];
  for (int q = 0; q < kCoeffs; ++q) scale[q] = w * sh::kBasisScale[q];
  constexpr std::size_t kRowFloats = std::size_t(polyRows(Bands)) * 8;
  const std::size_t node_at = out.node.size();
  out.node.resize(node_at + links);
  for (std::size_t l = 0; l < links; ++l) {
    const CutEntry& e = s.cut[l];
    const float* m = link_sums + (l + 1) * kRowFloats;  // polynomial q at m[q - 1]
    glm::vec3 sum_dir(0.0f);
    if constexpr (Bands >= 2) {
      sum_dir = glm::vec3(m[2], m[0], m[1]);  // the band-1 polynomials are y, z, x
    } else {
      for (std::uint32_t k = e.first; k < e.first + e.count; ++k) {
        const std::uint32_t ray = rayOf(sorted[k]);
        sum_dir += glm::vec3(dirs.x[ray], dirs.y[ray], dirs.z[ray]);
      }
    }
    coeff_values[l * kCoeffs] = scale[0] * static_cast<float>(e.count);
    for (int q = 1; q < kCoeffs; ++q) coeff_values[l * kCoeffs + q] = scale[q] * m[q - 1];
    solid_values[l] = w * static_cast<float>(e.count);
    out.node[node_at + l] = e.node;
    // The octahedral map divides by the L1 norm, so the sum needs no normalising.
    const float l1 = std::abs(sum_dir.x) + std::abs(sum_dir.y) + std::abs(sum_dir.z);
    const glm::vec3 d = l1 > 0.0f ? sum_dir : n;
    s.link_x[l] = d.x;
    s.link_y[l] = d.y;
    s.link_z[l] = d.z;
  }
  clock.lap(kPhaseProject);
  const std::size_t direction_at = out.direction.size();
  out.direction.resize(direction_at + links);
  encodeOctahedral(s.link_x.data(), s.link_y.data(), s.link_z.data(), static_cast<std::uint32_t>(links),
                  out.direction.data() + direction_at);
  // |coefficient| <= (omega / pi) * max |Y_q| < 4: nothing comes near half's 65504.
  const std::size_t coeffs_at = out.coeffs.size(), solid_at = out.solid_angle.size();
  out.coeffs.resize(coeffs_at + links * kCoeffs);
  out.solid_angle.resize(solid_at + links);
  toHalfSaturating(std::span<const float>(coeff_values, links * kCoeffs), out.coeffs.data() + coeffs_at);
  toHalfSaturating(std::span<const float>(solid_values, links), out.solid_angle.data() + solid_at);
  out.count.push_back(static_cast<std::uint32_t>(s.cut.size()));
  out.sky.insert(out.sky.end(), sky, sky + kCoeffs);
  clock.lap(kPhaseOutput);
}

using LinkCacheFn = decltype(&linkCache<1>);
LinkCacheFn linkCacheFor(int bands) {
  switch (bands) {
    case 1: return &linkCache<1>;
    case 2: return &linkCache<2>;
    case 3: return &linkCache<3>;
    default: return &linkCache<4>;
  }
}

}  // namespace

double linkPhaseTicksPerSecond() {
#if defined(__x86_64__) || defined(__i386__)
  static const double rate = [] {
    const auto t0 = std::chrono::steady_clock::now();
    const std::uint64_t c0 = PhaseClock::now();
    std::chrono::duration<double> elapsed{};
    while ((elapsed = std::chrono::steady_clock::now() - t0).count() < 0.02) {
    }
    return double(PhaseClock::now() - c0) / elapsed.count();
  }();
  return rate;
#else
  return 1e9;
#endif
}

LinkRays::LinkRays(const LinkOptions& options) : strata_(strataFor(options)), seed_(options.seed) {
  // The base pattern: one jittered sample per stratum, seeded by the link seed alone. Its
  // azimuths' cosines and sines are computed once here, in double, so the per-cache loop
  // needs neither hashing nor trigonometry.
  // generate() builds a row on the stack; generateLinks rejects rays > 2^20 before this.
  LL_CHECK_LE(strata_, 1024u);
  const std::uint32_t count = strata_ * strata_;
  const auto pattern_seed = static_cast<std::uint32_t>(mixBits(seed_ ^ 0x5851f42d4c957f2dULL) >> 32);
  base_jitter_.resize(count);
  base_cos_.resize(count);
  base_sin_.resize(count);
  base_stratum_.resize(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    const glm::vec2 jitter = stratifiedJitter32(i, pattern_seed);
    const float azimuth = (static_cast<float>(i / strata_) + jitter.y) / static_cast<float>(strata_);
    const double phi = 2.0 * std::numbers::pi * double(azimuth);
    base_jitter_[i] = jitter.x;
    base_cos_[i] = static_cast<float>(std::cos(phi));
    base_sin_[i] = static_cast<float>(std::sin(phi));
    base_stratum_[i] = static_cast<float>(i % strata_);
  }
}

namespace {

// A cache's randomisation of the base pattern, from the hash of (seed, cache): every polar
// jitter j -> (j + jitter) mod 1, and the pattern turned about the normal by alpha.
struct Shift {
  float jitter;
  float cos_alpha, sin_alpha;
};
Shift shiftOf(std::uint64_t seed, std::size_t cache) {
  const std::uint64_t bits = mixBits(seed ^ (std::uint64_t(cache) * 0xd1b54a32d192ed03ULL));
  const double alpha = 2.0 * std::numbers::pi * double(unitFloat32(static_cast<std::uint32_t>(bits)));
  return {unitFloat32(static_cast<std::uint32_t>(bits >> 32)), static_cast<float>(std::cos(alpha)),
          static_cast<float>(std::sin(alpha))};
}

// What a row of the per-cache loop reads besides the base pattern.
struct RowSetup {
  float shift;            // added to the base pattern's polar jitter, modulo 1
  float inv;              // 1 / strata
  float z_scale;          // 1: hemisphere (z = 1 - u), 2: sphere (z = 1 - 2u)
  glm::vec3 t, b, n;      // the cache's frame, t and b already turned by the azimuth shift
};

// Directions of one row (strata rays, polar strata 0 .. strata - 1 of one azimuth stratum).
// One loop with no hashing or trigonometry that vectorises (sqrt does: the module builds
// with -fno-math-errno); a hash and a sine and cosine per ray would dominate the "rays" phase
// (precompute_bench).
// `strata` rays from bj/bc/bs (the base pattern) and bsx (each ray's polar stratum as a
// float): one row, or a whole fan at once (rows follow each other in the arrays).
LL_ISA_INLINE void rowDirectionsImpl(const RowSetup& r, const float* __restrict bj, const float* __restrict bc,
                                   const float* __restrict bs, const float* __restrict bsx, std::uint32_t strata,
                                   float* __restrict dx, float* __restrict dy, float* __restrict dz) {
  // Everything the loop reads of `r` in locals: the stores through dx/dy/dz could alias it
  // otherwise, and the reloads keep the loop from vectorising.
  const float shift = r.shift, inv = r.inv, z_scale = r.z_scale;
  const glm::vec3 t = r.t, b = r.b, n = r.n;
  for (std::uint32_t sx = 0; sx < strata; ++sx) {
    const float sum = bj[sx] + shift;
    // A select between two computed values: GCC 12 keeps the loop scalar for the forms
    // `sum >= 1 ? sum - 1 : sum` and `sum - (sum >= 1 ? 1 : 0)`. (sum - 1 is exact here.)
    const float wrapped = sum - 1.0f;
    const float jitter = wrapped < 0.0f ? sum : wrapped;
    const float u = (bsx[sx] + jitter) * inv;
    const float z = 1.0f - z_scale * u;
    // No clamp: u <= 1, so |z| <= 1 and z * z <= 1 in floats too. (sx + jitter rounds to at
    // most strata, rounding is monotone, and strata * (1 / strata) <= 1 in floats for every
    // strata <= 1024: LinkRays.DirectionsAreFiniteUnitVectorsForAnyRayCount checks it.) With
    // a second select, the clamp, GCC 12 keeps the loop scalar.
    const float q = 1.0f - z * z;
    const float rad = std::sqrt(q);
    const float a = rad * bc[sx], c = rad * bs[sx];
    dx[sx] = a * t.x + c * b.x + z * n.x;
    dy[sx] = a * t.y + c * b.y + z * n.y;
    dz[sx] = a * t.z + c * b.z + z * n.z;
  }
}
LL_ISA_CLONES(void, rowDirections, (const RowSetup& r, const float* __restrict bj, const float* __restrict bc, const float* __restrict bs, const float* __restrict bsx, std::uint32_t strata, float* __restrict dx, float* __restrict dy, float* __restrict dz), (r, bj, bc, bs, bsx, strata, dx, dy, dz), rowDirectionsImpl)

}  // namespace

namespace {

// Rays [0, count) from one origin along (x, y, z)[k], tnear 0, tfar infinity. On x86-64, four
// at a time: a 4 x 4 transpose of (x, y, z, tfar) gives each ray's second half, so a ray is
// two 16-byte stores instead of eight 4-byte ones (generate() writes records for the
// benchmarks' raw-Embree passes, precompute_bench's among them).
void storeRays(const glm::vec3& origin, const float* x, const float* y, const float* z, std::uint32_t count,
               rt::Ray* out) {
  static_assert(sizeof(rt::Ray) == 32 && offsetof(rt::Ray, tnear) == 12 && offsetof(rt::Ray, dir) == 16 &&
                offsetof(rt::Ray, tfar) == 28);
  std::uint32_t k = 0;
#if defined(__SSE2__)
  const __m128 head = _mm_setr_ps(origin.x, origin.y, origin.z, 0.0f);
  const __m128 far = _mm_set1_ps(std::numeric_limits<float>::infinity());
  float* dst = reinterpret_cast<float*>(out);
  for (; k + 4 <= count; k += 4) {
    __m128 r0 = _mm_loadu_ps(x + k), r1 = _mm_loadu_ps(y + k), r2 = _mm_loadu_ps(z + k), r3 = far;
    _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
    _mm_storeu_ps(dst + 8 * k, head);
    _mm_storeu_ps(dst + 8 * k + 4, r0);
    _mm_storeu_ps(dst + 8 * k + 8, head);
    _mm_storeu_ps(dst + 8 * k + 12, r1);
    _mm_storeu_ps(dst + 8 * k + 16, head);
    _mm_storeu_ps(dst + 8 * k + 20, r2);
    _mm_storeu_ps(dst + 8 * k + 24, head);
    _mm_storeu_ps(dst + 8 * k + 28, r3);
  }
#endif
  for (; k < count; ++k) {
    out[k].origin = origin;
    out[k].tnear = 0.0f;
    out[k].dir = glm::vec3(x[k], y[k], z[k]);
    out[k].tfar = std::numeric_limits<float>::infinity();
  }
}

}  // namespace

template <typename RowSink>
glm::vec3 LinkRays::forEachRow(const rt::Accel& accel, std::size_t cache, const glm::vec3& p, const glm::vec3& normal,
                               const Directions* directions, RowSink&& sink) const {
  const bool hemisphere = glm::dot(normal, normal) > 0.0f;
  glm::vec3 t(1, 0, 0), b(0, 1, 0), n(0, 0, 1);
  if (hemisphere) {
    n = glm::normalize(normal);
    orthonormalBasis(n, t, b);
  }
  // Every cache traces the base pattern randomised by its own (seed, cache) hash: the polar
  // jitter of every stratum shifted by one offset modulo 1 (each sample stays in its
  // stratum), and the whole pattern turned about the normal by one angle (the azimuth is
  // periodic, so turning keeps its strata too). Each jitter is then uniform in its stratum
  // for every cache, whatever the base pattern, so each cache's estimate of any integral is
  // unbiased and the errors of different caches are uncorrelated: they average away over a
  // surface. (A shared pattern only turned per cache keeps its polar error common to all
  // caches: the mean sky irradiance over a plane comes out 0.3 % off in tests/relight.
  // Shifting u itself modulo 1 breaks one polar stratum per row in two, one piece at the
  // normal and one at the horizon: 3 % error per cache at 256 rays.)
  const Shift shift = shiftOf(seed_, cache);
  const RowSetup setup{.shift = shift.jitter,
                       .inv = 1.0f / static_cast<float>(strata_),
                       .z_scale = hemisphere ? 1.0f : 2.0f,
                       .t = shift.cos_alpha * t + shift.sin_alpha * b,
                       .b = shift.cos_alpha * b - shift.sin_alpha * t,
                       .n = n};
  // Every hemisphere direction leaves on the normal's side, so one offset origin serves all.
  const glm::vec3 origin = hemisphere ? accel.offsetOrigin(p, n, n) : p;
  const std::uint32_t strata = strata_;
  if (directions != nullptr) {
    // All rows in one call, the polar stratum of each ray read from a table, then the rows
    // handed on: one call per row costs more in the "rays" phase (precompute_bench on
    // CornellBox-Original). The same bits: the table holds float(sx) exactly.
    rowDirections(setup, base_jitter_.data(), base_cos_.data(), base_sin_.data(), base_stratum_.data(),
                  strata * strata, directions->x, directions->y, directions->z);
    for (std::uint32_t first = 0; first < strata * strata; first += strata)
      sink(origin, directions->x + first, directions->y + first, directions->z + first, first, strata);
    return origin;
  }
  float x[1024], y[1024], z[1024];  // a row (strata <= 1024: rays <= 2^20)
  for (std::uint32_t first = 0; first < strata * strata; first += strata) {
    rowDirections(setup, base_jitter_.data() + first, base_cos_.data() + first, base_sin_.data() + first,
                  base_stratum_.data(), strata, x, y, z);
    sink(origin, x, y, z, first, strata);
  }
  return origin;
}

void LinkRays::generate(const rt::Accel& accel, std::size_t cache, const glm::vec3& p, const glm::vec3& normal,
                        std::span<rt::Ray> rays, const Directions* directions) const {
  forEachRow(accel, cache, p, normal, directions,
             [&](const glm::vec3& origin, const float* x, const float* y, const float* z, std::uint32_t first,
                 std::uint32_t n) { storeRays(origin, x, y, z, n, rays.data() + first); });
}

rt::RayFan LinkRays::fan(const rt::Accel& accel, std::size_t cache, const glm::vec3& p, const glm::vec3& normal,
                         const Directions& directions) const {
  rt::RayFan fan;
  fan.origin = forEachRow(accel, cache, p, normal, &directions,
                          [](const glm::vec3&, const float*, const float*, const float*, std::uint32_t, std::uint32_t) {});
  fan.dir_x = directions.x;
  fan.dir_y = directions.y;
  fan.dir_z = directions.z;
  fan.count = count();
  return fan;
}

void capZonal(float omega, int bands, float* z) {
  const float cos_half = std::clamp(1.0f - omega / (2.0f * kPi), -1.0f, 1.0f);
  const auto zonal = sh::coneZonal(std::acos(cos_half));
  for (int l = 0; l < bands; ++l) z[l] = zonal[l] / kPi;
}

void projectRuntimeLink(const glm::vec3& direction, float omega_over_pi, int bands, float* coeffs) {
  float z[sh::kMaxBands];
  capZonal(omega_over_pi * kPi, bands, z);
  sh::evalBasis(bands, direction, coeffs);
  for (int i = 0; i < bands * bands; ++i) {
    const int l = sh::bandOf(i);
    coeffs[i] *= std::sqrt(4.0f * kPi / float(2 * l + 1)) * z[l];
  }
}

std::uint32_t encodeOctahedral(const glm::vec3& d) { return octahedralCode(d.x, d.y, d.z); }

// The codes of a cache's link directions, in one loop after its link loop: called per link,
// out of line from inside the projection loop, the encoding is several times dearer
// (precompute_bench's "output" phase on the bundled Cornell box).
// Eight links at a time on GCC vectors (GCC 12 kept the scalar loop scalar: the clamp and the
// rounding are control flow to it), with octahedralCode's operations in its order: the
// clamp as two selects, and lrint (round to nearest even in the default mode) as adding and
// subtracting 1.5 * 2^23, exact for |t| <= 32767; the remainder goes through
// octahedralCode.
LL_ISA_INLINE void encodeOctahedralImpl(const float* __restrict x, const float* __restrict y, const float* __restrict z,
                                      std::uint32_t count, std::uint32_t* __restrict out) {
  const Ints8 magnitude = Ints8{} + 0x7fffffff;
  const Lanes8 one = Lanes8{} + 1.0f, minus_one = Lanes8{} + -1.0f, zero = Lanes8{};
  const Lanes8 round_magic = Lanes8{} + 12582912.0f;  // 1.5 * 2^23
  // (Macros: a vector-typed lambda or function would change the ABI of the SSE2 build.)
#define LL_ABS8(v) reinterpret_cast<Lanes8>(reinterpret_cast<Ints8>(v) & magnitude)
  std::uint32_t i = 0;
  for (; i + 8 <= count; i += 8) {
    Lanes8 vx, vy, vz;
    std::memcpy(&vx, x + i, sizeof vx);
    std::memcpy(&vy, y + i, sizeof vy);
    std::memcpy(&vz, z + i, sizeof vz);
    const Lanes8 inv = 1.0f / (LL_ABS8(vx) + LL_ABS8(vy) + LL_ABS8(vz));
    const Lanes8 ox = vx * inv, oy = vy * inv;
    const Lanes8 fx = (1.0f - LL_ABS8(oy)) * (ox >= zero ? one : minus_one);
    const Lanes8 fy = (1.0f - LL_ABS8(ox)) * (oy >= zero ? one : minus_one);
    const Lanes8 uv[2] = {vz < zero ? fx : ox, vz < zero ? fy : oy};
    Ints8 q[2];
    for (int k = 0; k < 2; ++k) {
      const Lanes8 c = uv[k];
      const Lanes8 clamped = c < minus_one ? minus_one : (one < c ? one : c);
      const Lanes8 t = clamped * 32767.0f;
      const Lanes8 rounded = (t + round_magic) - round_magic;
      q[k] = __builtin_convertvector(rounded, Ints8) & 0xffff;
    }
    const Ints8 code = q[0] | (q[1] << 16);
    std::memcpy(out + i, &code, sizeof code);
  }
#undef LL_ABS8
  for (; i < count; ++i) out[i] = octahedralCode(x[i], y[i], z[i]);
}
LL_ISA_CLONES(void, encodeOctahedral, (const float* __restrict x, const float* __restrict y, const float* __restrict z, std::uint32_t count, std::uint32_t* __restrict out), (x, y, z, count, out), encodeOctahedralImpl)

glm::vec3 decodeOctahedral(std::uint32_t packed) {
  const float x = static_cast<float>(static_cast<std::int16_t>(packed & 0xffffu)) / 32767.0f;
  const float y = static_cast<float>(static_cast<std::int16_t>(packed >> 16)) / 32767.0f;
  glm::vec3 v(x, y, 1.0f - std::abs(x) - std::abs(y));
  if (v.z < 0.0f) {
    v.x = (1.0f - std::abs(y)) * (x >= 0.0f ? 1.0f : -1.0f);
    v.y = (1.0f - std::abs(x)) * (y >= 0.0f ? 1.0f : -1.0f);
  }
  return glm::normalize(v);
}

Expected<Links> generateLinks(const scene::Scene& scene, const rt::Accel& accel, const surfels::Surfels& surfels,
                              const hierarchy::Tree& tree, const CacheQuery& caches, const LinkOptions& options,
                              Progress* progress) {
  if (tree.surfelCount() != surfels.size())
    return invalidInput("links: the tree covers {} surfels but {} were given", tree.surfelCount(), surfels.size());
  const auto start = std::chrono::steady_clock::now();
  const SurfelLocator locator(surfels, scene);
  auto links = generateLinks(scene, accel, locator, tree, caches, options, progress);
  if (links) links->stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return links;
}

Expected<Links> generateLinks(const scene::Scene& scene, const rt::Accel& accel, const SurfelLocator& locator,
                              const hierarchy::Tree& tree, const CacheQuery& caches, const LinkOptions& options,
                              Progress* progress) {
  if (options.bands < 1 || options.bands > sh::kMaxBands)
    return invalidInput("SH bands {} is out of range (1..{})", options.bands, sh::kMaxBands);
  if (options.rays < 1 || options.rays > (1 << 20))
    return invalidInput("link rays per cache {} is out of range (1..1048576)", options.rays);
  if (options.max_links < 1 || options.max_links > (1 << 16))
    return invalidInput("links per cache {} is out of range (1..65536)", options.max_links);
  if (caches.position.size() != caches.normal.size())
    return invalidInput("caches: {} positions but {} normals", caches.position.size(), caches.normal.size());
  if (tree.surfelCount() != locator.surfelCount())
    return invalidInput("links: the tree covers {} surfels but the owner lookup {}", tree.surfelCount(),
                        locator.surfelCount());

  const auto start = std::chrono::steady_clock::now();
  const LinkCacheFn link_cache = linkCacheFor(options.bands);
  const LinkRays pattern(options);
  const CutTree cut_tree = cutTree(tree);
  const std::vector<std::uint32_t> double_sided = doubleSidedByMesh(scene);
  const std::size_t surfel_count = std::max<std::size_t>(1, locator.surfelCount());
  const auto surfel_bits = std::max<std::uint32_t>(1, static_cast<std::uint32_t>(std::bit_width(surfel_count - 1)));
  const std::size_t n = caches.position.size();
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  NullProgress null_progress;
  Progress& sink = progress ? *progress : null_progress;
  sink.begin(options.progress_label, n);
  ProgressCounter counter(sink, std::max<std::size_t>(1, n / 200));
  // Seen surfels per thread, merged by OR at the end: the union does not depend on which
  // thread linked which cache.
  tbb::enumerable_thread_specific<std::vector<std::uint8_t>> seen_by_thread(
      [&] { return std::vector<std::uint8_t>(locator.surfelCount(), 0); });

  const std::size_t coeffs_per_link = static_cast<std::size_t>(options.bands * options.bands);
  Links links;
  links.bands = options.bands;
  // Chunks go through a pipeline: linked in parallel into a slot of the ring, given their
  // place in the output by a serial stage (in chunk order, so the layout does not depend on
  // the scheduling), and copied there in parallel. At most `tokens` chunks are in flight, so
  // a chunk takes a free slot when it enters and frees it when its copy is done (copies end
  // in any order), and the ring's buffers are reused, warm, for the whole run: keeping every
  // chunk's result until the end would write all links twice into fresh memory (page faults;
  // precompute_bench's link time). The copy runs in the parallel stage, so the first write
  // to each output page (a page fault) stalls one chunk's thread instead of the in-order
  // stage all chunks wait on.
  // The output arrays are sized up front for the worst case (every cache max_links links, up
  // to options.output_links_up_front) without being written (HugePageAllocator
  // default-initialises), so the part never written is never faulted in; past that they
  // grow, while no copy runs.
  const std::size_t max_links = static_cast<std::size_t>(options.max_links);
  links.offsets.resize(n + 1);  // offsets[0] = 0
  links.sky.resize(n * coeffs_per_link);
  const auto sizeOutput = [&](std::size_t link_count) {
    links.node.resize(link_count);
    links.coeffs.resize(link_count * coeffs_per_link);
    links.direction.resize(link_count);
    links.solid_angle.resize(link_count);
  };
  sizeOutput(std::min(n * max_links, std::max<std::size_t>(1, options.output_links_up_front)));
  std::shared_mutex output_mutex;  // shared: copies into the output; exclusive: growing it

  const std::size_t tokens = 4 * static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency()));
  struct Slot {
    ChunkResult result;
    std::size_t chunk = 0;
    std::size_t at = 0;  // the output index of the chunk's first link
  };
  std::vector<Slot> ring(tokens);
  tbb::concurrent_queue<Slot*> free_slots;
  for (Slot& slot : ring) free_slots.push(&slot);
  std::size_t next_chunk = 0;
  tbb::parallel_pipeline(
      tokens,
      tbb::make_filter<void, Slot*>(tbb::filter_mode::serial_in_order,
                                    [&](tbb::flow_control& fc) -> Slot* {
                                      Slot* slot = nullptr;
                                      if (next_chunk == chunks || sink.cancelled()) {
                                        fc.stop();
                                        return slot;
                                      }
                                      // Fewer than `tokens` chunks are in flight: one is free.
                                      const bool got = free_slots.try_pop(slot);
                                      LL_CHECK(got);
                                      slot->chunk = next_chunk++;
                                      return slot;
                                    }) &
          tbb::make_filter<Slot*, Slot*>(
              tbb::filter_mode::parallel,
              [&](Slot* slot) {
                const std::size_t chunk = slot->chunk;
                thread_local Scratch scratch;
                std::uint8_t* seen = seen_by_thread.local().data();
                for (auto* v : {&scratch.hit_mesh, &scratch.hit_triangle}) v->resize(pattern.count());
                for (auto* v : {&scratch.hit_u, &scratch.hit_v, &scratch.hit_t, &scratch.hit_ng_x, &scratch.hit_ng_y,
                                &scratch.hit_ng_z})
                  v->resize(pattern.count());
                scratch.slots.resize(pattern.count());
                scratch.samples.resize(pattern.count() + kHitCreditSlack);
                scratch.sort_buffer.resize(pattern.count());
                for (auto* v : {&scratch.dir_x, &scratch.dir_y, &scratch.dir_z, &scratch.escaped})
                  v->resize(skyPadded(pattern.count()));
                scratch.poly.resize(std::size_t(skyPadded(pattern.count())) * polyRows(options.bands) * 8);
                scratch.link_sums.resize((max_links + 1) * polyRows(options.bands) * 8);
                scratch.coeff_values.resize(max_links * coeffs_per_link);
                scratch.solid_values.resize(max_links);
                for (auto* v : {&scratch.link_x, &scratch.link_y, &scratch.link_z}) v->resize(max_links);
                ChunkResult& out = slot->result;
                out.clear();
                const std::size_t end = std::min(n, (chunk + 1) * kChunk);
                // Worst case up front (a no-op once the slot has held a full chunk).
                const std::size_t most = (end - chunk * kChunk) * max_links;
                out.node.reserve(most);
                out.coeffs.reserve(most * coeffs_per_link);
                out.direction.reserve(most);
                out.solid_angle.reserve(most);
                for (std::size_t c = chunk * kChunk; c < end; ++c)
                  link_cache(options.first_cache + c, caches.position[c], caches.normal[c], double_sided.data(),
                             accel, cut_tree, locator,
                             options, pattern, surfel_bits, scratch, seen, out);
                counter.add(end - chunk * kChunk);
                return slot;
              }) &
          tbb::make_filter<Slot*, Slot*>(
              tbb::filter_mode::serial_in_order,
              [&](Slot* slot) {
                const std::size_t first_cache = slot->chunk * kChunk;
                const ChunkResult& r = slot->result;
                slot->at = links.offsets[first_cache];
                for (std::size_t k = 0; k < r.count.size(); ++k)
                  links.offsets[first_cache + k + 1] = links.offsets[first_cache + k] + r.count[k];
                const std::size_t placed = links.offsets[first_cache + r.count.size()];
                if (placed > links.node.size()) {
                  const std::unique_lock grow(output_mutex);
                  sizeOutput(std::max(placed, 2 * links.node.size()));
                }
                links.stats.rays += r.stats.rays;
                links.stats.front_hits += r.stats.front_hits;
                links.stats.back_hits += r.stats.back_hits;
                links.stats.escaped += r.stats.escaped;
                links.stats.unowned += r.stats.unowned;
                for (int k = 0; k < kLinkPhases; ++k) links.stats.phase_ticks[k] += r.stats.phase_ticks[k];
                return slot;
              }) &
          tbb::make_filter<Slot*, void>(tbb::filter_mode::parallel, [&](Slot* slot) {
            const ChunkResult& r = slot->result;
            const std::size_t at = slot->at;
            {
              const std::shared_lock copying(output_mutex);
              // Streaming stores: nothing reads the output until the stage is over, and a
              // plain copy first reads every line it writes (precompute_bench's "output"
              // phase on CornellBox-Original).
              auto stream = [](auto& to, std::size_t to_at, const auto& from) {
                copyStreaming(to.data() + to_at, from.data(), from.size() * sizeof(from[0]));
              };
              stream(links.node, at, r.node);
              stream(links.coeffs, at * coeffs_per_link, r.coeffs);
              stream(links.direction, at, r.direction);
              stream(links.solid_angle, at, r.solid_angle);
              stream(links.sky, slot->chunk * kChunk * coeffs_per_link, r.sky);
            }
            free_slots.push(slot);
          }));
  if (!sink.cancelled()) sizeOutput(links.offsets[n]);
  sink.end();
  if (sink.cancelled()) return cancelled("link generation cancelled");
  links.seen.assign(locator.surfelCount(), 0);
  for (const auto& part : seen_by_thread)
    for (std::size_t i = 0; i < part.size(); ++i) links.seen[i] |= part[i];
  links.stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return links;
}

}  // namespace lightlink::links
