// Vectors whose storage starts on a 64-byte boundary (one cache line, one AVX-512 register).
//
// Link generation's per-thread scratch arrays are read and written 16 floats at a time by
// its AVX-512 loops. Plain std::vector blocks are only 16-byte aligned, so most such arrays
// start partway into a line and every 64-byte access touches two lines; aligned, the hit
// credit and sky phases are cheaper (precompute_bench's phase ticks and own work per unit of
// tracing on the small Cornell-type scenes). The bits are the same: only where the arrays
// start changes.
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
