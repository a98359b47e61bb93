// Memory for the big arrays a stage fills once (link generation's output).
//
// Filling fresh memory costs one page fault per 4 KiB page the first time it is touched. On
// the virtual machines we build and measure on that is expensive: 13 us of kernel time per
// fault on one (a KVM guest with paravirtualised page tables); avoiding most of link
// generation's took its stage from 0.47 to 0.31 s on CornellBox-Original (docs/results.md,
// issue 4, tenth pass). Transparent huge pages take one fault per 2 MiB instead; where the kernel only
// gives them to regions that ask (THP "madvise", Debian's default), these helpers ask.
// A hint only covers the whole 2 MiB pages inside a block, and a block from malloc starts
// anywhere: HugeVector's blocks of 2 MiB or more start on a 2 MiB boundary, so all of the
// block can have huge pages (`lightlink precompute` of CornellBox-Original: 9,391-9,399
// page faults before, 7,146-7,258 after, `/usr/bin/time`; docs/results.md, issue 4
// sixteenth pass).
// They are hints: nothing changes but the time where the kernel says no.
//
// Freed huge blocks are kept (up to kHugeBlockCacheBytes in all) and handed to the next
// allocation of their size (in whole huge pages), pages already in place. Fresh memory costs more than the
// zeroing of its pages on the VMs we measure on: a process's first touch of 37 MiB took
// 3.8-4.5 ms in huge pages in most processes and 9-82 ms in the others, 15-34 ms in small
// pages (docs/data/precompute/session20_zen4/first_touch_throwaway.txt; why some processes
// get slow memory was not measured). A process that generates links more than once
// (precompute_bench's pairs, `lightlink compare`, the accuracy study) paid that for every
// run: with the cache, precompute_bench's link runs after the first spent 1.0-2.0 % of their
// wall time outside link generation's phases, against 19.0-25.7 % without
// (CornellBox-Original, four alternated rounds; docs/results.md, issue 4 nineteenth pass). A
// one-shot `lightlink precompute` still pays for its output's first touch.
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
