#include "core/common/memory.h"

#include <cstdint>
#include <cstdlib>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace lightlink {

void adviseHugePages(const void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  const auto begin = (reinterpret_cast<std::uintptr_t>(p) + kHugePageBytes - 1) & ~std::uintptr_t(kHugePageBytes - 1);
  const auto end = (reinterpret_cast<std::uintptr_t>(p) + bytes) & ~std::uintptr_t(kHugePageBytes - 1);
  // A refusal (no THP in this kernel, THP "never") leaves the memory as it was: ignored.
  if (end > begin) (void)madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
#endif
}

void* allocateHuge(std::size_t bytes) {
  if (bytes < kHugePageBytes) return ::operator new(bytes);
  if (bytes > std::size_t(-1) - kHugePageBytes) throw std::bad_alloc();
  const std::size_t rounded = (bytes + kHugePageBytes - 1) & ~(kHugePageBytes - 1);
  void* p = std::aligned_alloc(kHugePageBytes, rounded);
  if (p == nullptr) throw std::bad_alloc();
  adviseHugePages(p, rounded);
  return p;
}

void freeHuge(void* p, std::size_t bytes) noexcept {
  if (bytes < kHugePageBytes)
    ::operator delete(p);
  else
    std::free(p);
}

}  // namespace lightlink
