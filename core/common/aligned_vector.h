// Vectors whose storage starts on a 64-byte boundary (one cache line, one AVX-512 register).
//
// Link generation's per-thread scratch arrays are read and written 16 floats at a time by
// its AVX-512 loops. Plain std::vector blocks are only 16-byte aligned: of the 186 such
// arrays one precompute_bench run made, 127 started 16, 32 or 48 bytes past a line, and
// every 64-byte access to those touches two lines. Aligned, hit credit took 5.3-6.4k TSC ticks per
// cache instead of 5.9-6.9k and the sky pass 2.0-2.4k instead of 2.2-2.4k, and link
// generation's own work per unit of tracing went 0.542 -> 0.534 (CornellBox-Original),
// 0.506 -> 0.490 (EmissiveStrengthTest), 0.490 -> 0.464 (bundled box): medians of 4-6
// alternated rounds on a 2-core Intel Xeon VM (docs/results.md, issue 4 twenty-fifth pass).
// The bits are the same: only where the arrays start changes.
#pragma once

#include <cstddef>
#include <new>
#include <vector>

namespace lightlink {

inline constexpr std::size_t kCacheLineBytes = 64;

template <typename T>
struct CacheLineAllocator {
  using value_type = T;
  CacheLineAllocator() = default;
  template <typename U>
  CacheLineAllocator(const CacheLineAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    if (n > std::size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t{kCacheLineBytes}));
  }
  void deallocate(T* p, std::size_t) noexcept { ::operator delete(p, std::align_val_t{kCacheLineBytes}); }
  template <typename U>
  bool operator==(const CacheLineAllocator<U>&) const noexcept {
    return true;
  }
};

template <typename T>
using LineVector = std::vector<T, CacheLineAllocator<T>>;

}  // namespace lightlink
