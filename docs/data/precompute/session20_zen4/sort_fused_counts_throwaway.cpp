#include "core/links/sample_sort.h"
#include "read_samples_throwaway.h"
#include <cstdio>
#include <vector>
#include <algorithm>
#include <cstring>
#include <x86intrin.h>
using namespace lightlink::links;
namespace {
void starts(std::uint32_t* a, std::uint32_t* b, std::uint32_t buckets) {
  std::uint32_t sum = 0;
  for (std::uint32_t i = 0; i < buckets; ++i) { const std::uint32_t x = a[i], y = b[i]; a[i] = sum; b[i] = sum + x; sum += x + y; }
}
// two passes (7 low bits, then 8 high); pass 2's counts taken in pass 1's scatter, by the half of the buffer each key lands in
Sample* sortFused(Sample* keys, Sample* buffer, std::size_t n, std::uint8_t* seen) {
  constexpr std::uint32_t b0 = 7, b1 = 8;
  alignas(64) std::uint32_t a0[1 << b0] = {}, c0[1 << b0] = {};
  alignas(64) std::uint32_t cnt[2][1 << b1] = {};
  const std::size_t half = n / 2;
  auto k0 = [](Sample k) { return std::uint32_t(k >> 32) & ((1u << b0) - 1); };
  auto k1 = [](Sample k) { return std::uint32_t(k >> (32 + b0)) & ((1u << b1) - 1); };
  for (std::size_t i = 0; i < half; ++i) {
    const Sample x = keys[i], y = keys[half + i];
    ++a0[k0(x)]; ++c0[k0(y)];
    seen[surfelOf(x)] = seen[surfelOf(y)] = 1;
  }
  if (n > 2 * half) { ++c0[k0(keys[n-1])]; seen[surfelOf(keys[n-1])] = 1; }
  starts(a0, c0, 1 << b0);
  for (std::size_t i = 0; i < half; ++i) {
    const Sample x = keys[i], y = keys[half + i];
    const std::uint32_t dx = a0[k0(x)]++, dy = c0[k0(y)]++;
    buffer[dx] = x; buffer[dy] = y;
    ++cnt[dx >= half][k1(x)]; ++cnt[dy >= half][k1(y)];
  }
  if (n > 2 * half) { const std::uint32_t d = c0[k0(keys[n-1])]++; buffer[d] = keys[n-1]; ++cnt[d >= half][k1(keys[n-1])]; }
  starts(cnt[0], cnt[1], 1 << b1);
  for (std::size_t i = 0; i < half; ++i) { const Sample x = buffer[i], y = buffer[half + i]; keys[cnt[0][k1(x)]++] = x; keys[cnt[1][k1(y)]++] = y; }
  if (n > 2 * half) keys[cnt[1][k1(buffer[n-1])]++] = buffer[n-1];
  return keys;
}
}
int main() {
  const auto caches = readSamples("/tmp/samples_rayorder.bin");
  std::vector<std::uint8_t> seen(1 << 16);
  std::vector<Sample> a(2048), b(2048), a2(2048), b2(2048);
  for (int round = 0; round < 4; ++round) {
    std::uint64_t t1 = 0, t2 = 0;
    for (auto& c : caches) {
      std::copy(c.begin(), c.end(), a.begin());
      std::copy(c.begin(), c.end(), a2.begin());
      auto t0 = __rdtsc();
      Sample* s = sortSamples(a.data(), b.data(), c.size(), 15, seen.data());
      t1 += __rdtsc() - t0;
      t0 = __rdtsc();
      Sample* s2 = sortFused(a2.data(), b2.data(), c.size(), seen.data());
      t2 += __rdtsc() - t0;
      if (!std::equal(s, s + c.size(), s2)) { printf("mismatch\n"); return 1; }
    }
    printf("current %.0f, fused count %.0f ticks/cache\n", double(t1)/caches.size(), double(t2)/caches.size());
  }
}
