#include "core/links/sample_sort.h"

#include <algorithm>
#include <cstring>
#include <type_traits>
#include <utility>

#include "core/common/isa.h"

namespace lightlink::links {
namespace {

// A pass sorts at most this many bits (2^11 buckets).
constexpr std::uint32_t kSortPassBits = 11;

constexpr std::uint32_t ceilDiv(std::uint32_t a, std::uint32_t b) { return (a + b - 1) / b; }

// Sixteen bucket counters as one GCC vector, for bucketStarts below.
typedef std::uint32_t Counts16 __attribute__((vector_size(64)));

// The radix sort's bucket starts from its two counter sets (below): bucket b of the first
// half's keys starts after all keys of the buckets before b, the second half's after the
// first half's bucket b. An exclusive prefix sum, 16 buckets per step (a scan in the
// register, then the running total added): the bucket-by-bucket loop made each bucket wait
// on the last one's sum, 2 x 256 steps per cache.
LL_ISA_INLINE void bucketStartsImpl(std::uint32_t* __restrict count_a, std::uint32_t* __restrict count_b,
                                  std::uint32_t buckets) {
  std::uint32_t b = 0;
  if (buckets >= 16) {
    const Counts16 zero = {};
    Counts16 total = {};
    for (; b < buckets; b += 16) {
      Counts16 a, c;
      std::memcpy(&a, count_a + b, sizeof a);
      std::memcpy(&c, count_b + b, sizeof c);
      const Counts16 t = a + c;
      // Inclusive scan: lane i gets the sum of lanes 0..i (shifted copies added in 4 steps).
      Counts16 scan = t;
      scan += __builtin_shufflevector(zero, scan, 0, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30);
      scan += __builtin_shufflevector(zero, scan, 0, 0, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29);
      scan += __builtin_shufflevector(zero, scan, 0, 0, 0, 0, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27);
      scan += __builtin_shufflevector(zero, scan, 0, 0, 0, 0, 0, 0, 0, 0, 16, 17, 18, 19, 20, 21, 22, 23);
      const Counts16 start = total + scan - t;
      const Counts16 start_b = start + a;
      std::memcpy(count_a + b, &start, sizeof start);
      std::memcpy(count_b + b, &start_b, sizeof start_b);
      total += __builtin_shufflevector(scan, scan, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15);
    }
    return;
  }
  std::uint32_t sum = 0;
  for (; b < buckets; ++b) {
    const std::uint32_t a = count_a[b], c = count_b[b];
    count_a[b] = sum;
    count_b[b] = sum + a;
    sum += a + c;
  }
}
LL_ISA_CLONES(void, bucketStarts, (std::uint32_t* __restrict count_a, std::uint32_t* __restrict count_b, std::uint32_t buckets), (count_a, count_b, buckets), bucketStartsImpl)

}  // namespace

// Stable LSD radix sort of the samples by surfel: they are appended in ray order, so the
// result equals a sort by (surfel, ray). Two or three passes over ~1k keys beat a comparison
// sort by 4-5x here (the sort runs once per cache). A pass has no more buckets than its bits
// of the surfel need, and the last pass the most (15 bits: 128 then 256): a cache's hits
// cluster in a few regions of the surfel order, so the high bits' pass meets long runs of
// one bucket, whose increments wait on each other; finer buckets there shorten them
// (precompute_bench's "sort" phase on CornellBox-Original). The first pass's count also sets
// seen[surfel] for every key, which it reads anyway (cheaper than a pass of its own in hit
// credit). Each pass counts and scatters the two halves of the keys with counters of their
// own (the second half's bucket b starts where the first half's ends: the same stable
// order). Neighbouring rays hit nearby surfels (cut_bench prints how often consecutive hits
// share one), so with one set of counters increments of one bucket would wait on each
// other; two halves make two chains that overlap (precompute_bench's "sort" phase).
Sample* sortSamples(Sample* keys, Sample* buffer, std::size_t n, std::uint32_t surfel_bits, std::uint8_t* seen) {
  const std::uint32_t passes = std::max<std::uint32_t>(1, ceilDiv(surfel_bits, kSortPassBits));
  const std::uint32_t bits = ceilDiv(surfel_bits, passes);
  alignas(64) std::uint32_t count_a[1u << kSortPassBits], count_b[1u << kSortPassBits];
  const std::size_t half = n / 2;  // the second half, [half, n), has the odd key
  const std::uint32_t low_bits = surfel_bits - bits;  // the last pass sorts the most bits
  for (std::uint32_t pass = 0, done = 0; pass < passes; ++pass) {
    // The passes before the last share low_bits as evenly as they can.
    const std::uint32_t pass_bits = pass + 1 == passes ? bits : ceilDiv(low_bits - done, passes - 1 - pass);
    const std::uint32_t shift = 32 + done;
    const std::uint32_t buckets = 1u << pass_bits;
    done += pass_bits;
    auto bucket = [&](Sample k) { return static_cast<std::uint32_t>(k >> shift) & (buckets - 1); };
    std::fill(count_a, count_a + buckets, 0u);
    std::fill(count_b, count_b + buckets, 0u);
    // The first pass's count marks the seen surfels too (a constant, so the other passes'
    // loop has no test for it).
    auto count = [&](auto mark_seen) {
      for (std::size_t i = 0; i < half; ++i) {
        ++count_a[bucket(keys[i])];
        ++count_b[bucket(keys[half + i])];
        if constexpr (mark_seen) seen[surfelOf(keys[i])] = seen[surfelOf(keys[half + i])] = 1;
      }
      if (n > 2 * half) {
        ++count_b[bucket(keys[n - 1])];
        if constexpr (mark_seen) seen[surfelOf(keys[n - 1])] = 1;
      }
    };
    if (pass == 0)
      count(std::true_type{});
    else
      count(std::false_type{});
    bucketStarts(count_a, count_b, buckets);
    for (std::size_t i = 0; i < half; ++i) {
      const Sample ka = keys[i], kb = keys[half + i];
      buffer[count_a[bucket(ka)]++] = ka;
      buffer[count_b[bucket(kb)]++] = kb;
    }
    if (n > 2 * half) buffer[count_b[bucket(keys[n - 1])]++] = keys[n - 1];
    std::swap(keys, buffer);
  }
  return keys;
}

}  // namespace lightlink::links
