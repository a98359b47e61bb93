// Memory hints for the big arrays a stage fills once (link coefficients, lightmaps).
//
// Filling fresh memory costs one page fault per 4 KiB page the first time it is touched. On
// the virtual machines we build and measure on that is expensive: 13 us of kernel time per
// fault on one (a KVM guest with paravirtualised page tables); avoiding most of link
// generation's took its stage from 0.47 to 0.31 s on CornellBox-Original (docs/results.md,
// issue 4, tenth pass). Transparent huge pages take one fault per 2 MiB instead; where the kernel only
// gives them to regions that ask (THP "madvise", Debian's default), these helpers ask.
// They are hints: nothing changes but the time where the kernel says no.
#pragma once

#include <cstddef>
#include <vector>

namespace lightlink {

// Asks for huge pages over the whole 2 MiB pages inside [p, p + bytes). Call it before the
// memory is first written: pages already faulted in stay small.
void adviseHugePages(const void* p, std::size_t bytes);

// v.reserve(n), then the hint over the reserved storage (when the reserve allocated).
template <typename T>
void reserveHuge(std::vector<T>& v, std::size_t n) {
  if (n <= v.capacity()) return;
  v.reserve(n);
  adviseHugePages(v.data(), v.capacity() * sizeof(T));
}

}  // namespace lightlink
