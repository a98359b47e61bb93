#include "core/links/sample_sort.h"
#include "read_samples_throwaway.h"
#include <cstdio>
#include <vector>
#include <chrono>
#include <algorithm>
#include <cstring>
#include <x86intrin.h>
using namespace lightlink::links;
// u32 variant of the same radix sort
namespace {
constexpr std::uint32_t kSortPassBits = 11;
constexpr std::uint32_t ceilDiv(std::uint32_t a, std::uint32_t b) { return (a + b - 1) / b; }
__attribute__((target("avx512f"))) void bucketStarts(std::uint32_t* a, std::uint32_t* b, std::uint32_t buckets) {
  std::uint32_t sum = 0;
  for (std::uint32_t i = 0; i < buckets; ++i) { const std::uint32_t x = a[i], y = b[i]; a[i] = sum; b[i] = sum + x; sum += x + y; }
}
std::uint32_t* sort32(std::uint32_t* keys, std::uint32_t* buffer, std::size_t n, std::uint32_t surfel_bits, std::uint32_t ray_bits, std::uint8_t* seen) {
  const std::uint32_t passes = std::max<std::uint32_t>(1, ceilDiv(surfel_bits, kSortPassBits));
  const std::uint32_t bits = ceilDiv(surfel_bits, passes);
  alignas(64) std::uint32_t count_a[1u << kSortPassBits], count_b[1u << kSortPassBits];
  const std::size_t half = n / 2;
  const std::uint32_t low_bits = surfel_bits - bits;
  for (std::uint32_t pass = 0, done = 0; pass < passes; ++pass) {
    const std::uint32_t pass_bits = pass + 1 == passes ? bits : ceilDiv(low_bits - done, passes - 1 - pass);
    const std::uint32_t shift = ray_bits + done;
    const std::uint32_t buckets = 1u << pass_bits;
    done += pass_bits;
    auto bucket = [&](std::uint32_t k) { return (k >> shift) & (buckets - 1); };
    std::fill(count_a, count_a + buckets, 0u);
    std::fill(count_b, count_b + buckets, 0u);
    for (std::size_t i = 0; i < half; ++i) {
      ++count_a[bucket(keys[i])]; ++count_b[bucket(keys[half + i])];
      if (pass == 0) seen[keys[i] >> ray_bits] = seen[keys[half + i] >> ray_bits] = 1;
    }
    if (n > 2 * half) { ++count_b[bucket(keys[n - 1])]; if (pass == 0) seen[keys[n-1] >> ray_bits] = 1; }
    bucketStarts(count_a, count_b, buckets);
    for (std::size_t i = 0; i < half; ++i) {
      const std::uint32_t ka = keys[i], kb = keys[half + i];
      buffer[count_a[bucket(ka)]++] = ka;
      buffer[count_b[bucket(kb)]++] = kb;
    }
    if (n > 2 * half) buffer[count_b[bucket(keys[n - 1])]++] = keys[n - 1];
    std::swap(keys, buffer);
  }
  return keys;
}
}
int main() {
  const auto caches = readSamples("/tmp/samples_rayorder.bin");
  std::vector<std::uint8_t> seen(1 << 16);
  std::vector<Sample> a(2048), b(2048);
  std::vector<std::uint32_t> a32(2048), b32(2048);
  for (int round = 0; round < 3; ++round) {
    std::uint64_t t64 = 0, t32 = 0, chk = 0;
    for (auto& c : caches) {
      std::copy(c.begin(), c.end(), a.begin());
      auto t0 = __rdtsc();
      Sample* s = sortSamples(a.data(), b.data(), c.size(), 15, seen.data());
      t64 += __rdtsc() - t0;
      for (std::size_t i = 0; i < c.size(); ++i) a32[i] = (surfelOf(c[i]) << 10) | rayOf(c[i]);
      t0 = __rdtsc();
      std::uint32_t* s32 = sort32(a32.data(), b32.data(), c.size(), 15, 10, seen.data());
      t32 += __rdtsc() - t0;
      for (std::size_t i = 0; i < c.size(); ++i) if (s32[i] != ((surfelOf(s[i]) << 10) | rayOf(s[i]))) { printf("mismatch\n"); return 1; }
    }
    printf("u64 sort %.0f ticks/cache, u32 sort %.0f ticks/cache\n", double(t64)/caches.size(), double(t32)/caches.size());
  }
}
