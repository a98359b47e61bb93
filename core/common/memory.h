// Memory for the big arrays a stage fills once (link generation's output).
//
// The first touch of fresh memory costs a page fault per 4 KiB page, which is expensive on
// virtual machines. Blocks of 2 MiB or more are aligned to 2 MiB and advised to take
// transparent huge pages (one fault per 2 MiB) where the kernel gives them on request (THP
// "madvise", Debian's default). Hints only: where the kernel says no, only the time changes
// (bench/precompute measures it).
//
// Freed huge blocks are kept for the next allocation of their size while a
// HugeBlockCacheScope is open (a precompute, a benchmark's repeated runs), and handed back to
// the system when the last scope closes: fresh memory's first touch costs more than reusing
// pages in place (bench/precompute's link runs), but an idle process (the daemon between
// opens) keeps nothing.
#pragma once

#include <cstddef>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace lightlink {

// A huge page of x86-64 Linux (THP).
inline constexpr std::size_t kHugePageBytes = std::size_t(2) << 20;

// Asks for huge pages over the whole 2 MiB pages inside [p, p + bytes). Call it before the
// memory is first written: pages already faulted in stay small.
void adviseHugePages(const void* p, std::size_t bytes);

// Blocks for HugePageAllocator: from 2 MiB up, aligned to 2 MiB, with the length rounded up
// to whole 2 MiB pages and the hint given; smaller ones from operator new. Throws
// std::bad_alloc.
void* allocateHuge(std::size_t bytes);
void freeHuge(void* p, std::size_t bytes) noexcept;

// The most bytes of freed huge blocks kept for reuse; a block that does not fit under it is
// returned to the system. A kept block is reused for a request of its size in whole huge
// pages.
inline constexpr std::size_t kHugeBlockCacheBytes = std::size_t(512) << 20;
// Bytes of freed huge blocks kept now; releases them all to the system.
std::size_t cachedHugeBytes();
void releaseCachedHugeBlocks();

// While one is open (any thread), freed huge blocks are kept; when the last one closes they
// are all released. Scopes nest.
class HugeBlockCacheScope {
 public:
  HugeBlockCacheScope();
  ~HugeBlockCacheScope();
  HugeBlockCacheScope(const HugeBlockCacheScope&) = delete;
  HugeBlockCacheScope& operator=(const HugeBlockCacheScope&) = delete;
};

// memcpy for a destination that will not be read soon (link generation's output, written
// once behind the chunks that produced it): non-temporal stores where the CPU has them, so
// the destination's lines are not read from memory first (a plain copy reads every line
// it writes). Ordered before the caller's later stores (a store fence). dst and src must
// not overlap.
void copyStreaming(void* dst, const void* src, std::size_t bytes) noexcept;

template <typename T>
struct HugePageAllocator {
  using value_type = T;
  static_assert(alignof(T) <= __STDCPP_DEFAULT_NEW_ALIGNMENT__);
  HugePageAllocator() = default;
  template <typename U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    if (n > std::size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
    return static_cast<T*>(allocateHuge(n * sizeof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept { freeHuge(p, n * sizeof(T)); }
  // Elements made without a value are default-initialised, not zeroed: resize(n) writes
  // nothing, so a stage can size an array for its worst case and pay page faults only for
  // what it fills (link generation's output).
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <typename U>
  bool operator==(const HugePageAllocator<U>&) const noexcept {
    return true;
  }
};

// A vector whose big buffers are huge-page blocks: reserve (or resize: no zeroing) the final
// size once, then fill. HugeVector<T>(n) and resize(n) leave trivial elements unset.
template <typename T>
using HugeVector = std::vector<T, HugePageAllocator<T>>;

}  // namespace lightlink
