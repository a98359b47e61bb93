#include "core/common/memory.h"

#include <cstdint>
#include <fstream>
#include <vector>

#if defined(__linux__)
#include <unistd.h>
#endif

#include <gtest/gtest.h>

namespace lightlink {
namespace {

// A HugeVector fills and reads back like any vector, at sizes below, at and past a 2 MiB
// page, across reallocations; its blocks of 2 MiB or more start on a 2 MiB boundary (the
// point of it: the whole block can be given huge pages).
TEST(Memory, HugeVectorKeepsTheVectorsContractAndAlignsBigBlocks) {
  for (const std::size_t n : {std::size_t(0), std::size_t(1000), std::size_t(1) << 19, (std::size_t(3) << 20) + 7}) {
    HugeVector<std::uint32_t> v = {7, 8, 9};
    v.reserve(n);
    EXPECT_GE(v.capacity(), n);
    ASSERT_EQ(v.size(), 3u);
    EXPECT_EQ(v[0], 7u);
    EXPECT_EQ(v[2], 9u);
    if (v.capacity() * sizeof(std::uint32_t) >= kHugePageBytes) {
      EXPECT_EQ(reinterpret_cast<std::uintptr_t>(v.data()) % kHugePageBytes, 0u) << n << " words";
    }
    const std::uint32_t* before = v.data();
    for (std::size_t i = 3; i < n; ++i) v.push_back(static_cast<std::uint32_t>(i * 2654435761u));
    if (n > 3) {
      EXPECT_EQ(v.data(), before) << "filling within the reserve must not reallocate";
    }
    for (std::size_t i = 3; i < n; ++i) ASSERT_EQ(v[i], static_cast<std::uint32_t>(i * 2654435761u));
    // Growing past the reserve moves the contents into a new block (of either kind).
    const std::size_t size = v.size();
    v.resize(2 * size + 1000, 5u);
    for (std::size_t i = 3; i < size; ++i) ASSERT_EQ(v[i], static_cast<std::uint32_t>(i * 2654435761u));
    EXPECT_EQ(v.back(), 5u);
    HugeVector<std::uint32_t> copy = v;
    EXPECT_EQ(copy, v);
  }
}

#if defined(__linux__)
// Resident memory in bytes (/proc/self/statm, second field, in pages).
std::size_t residentBytes() {
  std::ifstream statm("/proc/self/statm");
  std::size_t size = 0, resident = 0;
  statm >> size >> resident;
  return resident * static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
}

// Sizing a HugeVector writes nothing (link generation sizes its output for the worst case
// and pays page faults only for the links it writes): resizing one to 256 MiB adds less
// than 32 MiB to resident memory (zeroing would add all of it), and a value given to resize
// is still written.
TEST(Memory, HugeVectorSizingWritesNothing) {
  const std::size_t bytes = std::size_t(256) << 20;
  HugeVector<std::uint8_t> v;
  const std::size_t before = residentBytes();
  v.resize(bytes);
  ASSERT_EQ(v.size(), bytes);
  EXPECT_LT(residentBytes(), before + (std::size_t(32) << 20));
  v[bytes - 1] = 3;
  EXPECT_EQ(v[bytes - 1], 3);
  HugeVector<std::uint32_t> filled;
  filled.resize(1000, 7u);
  EXPECT_EQ(filled.front(), 7u);
  EXPECT_EQ(filled.back(), 7u);
}
#endif

// Inside a HugeBlockCacheScope, a freed huge block is kept and handed to the next request of
// its size in whole huge pages (link generation run again in one process writes into pages
// already in place); a request of another size gets a block of its own; and no more than
// kHugeBlockCacheBytes are ever kept.
TEST(Memory, FreedHugeBlocksAreReusedUnderACap) {
  const HugeBlockCacheScope scope;
  releaseCachedHugeBlocks();
  ASSERT_EQ(cachedHugeBytes(), 0u);
  const std::size_t bytes = (std::size_t(6) << 20) + 123;
  void* a = allocateHuge(bytes);
  static_cast<char*>(a)[bytes - 1] = 1;
  freeHuge(a, bytes);
  EXPECT_EQ(cachedHugeBytes(), std::size_t(8) << 20);  // rounded up to whole huge pages
  void* small = allocateHuge(std::size_t(2) << 20);    // another size: a new block
  EXPECT_NE(small, a);
  void* b = allocateHuge(std::size_t(7) << 20);  // 8 MiB in huge pages, as the kept block
  EXPECT_EQ(b, a);
  EXPECT_EQ(cachedHugeBytes(), 0u);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(b) % kHugePageBytes, 0u);
  freeHuge(small, std::size_t(2) << 20);
  freeHuge(b, std::size_t(7) << 20);
  EXPECT_EQ(cachedHugeBytes(), std::size_t(10) << 20);
  // Past the cap, freed blocks go back to the system.
  std::vector<void*> blocks;
  const std::size_t each = std::size_t(64) << 20;  // never written: no memory is touched
  for (std::size_t k = 0; k < kHugeBlockCacheBytes / each + 2; ++k) blocks.push_back(allocateHuge(each));
  for (void* p : blocks) freeHuge(p, each);
  EXPECT_LE(cachedHugeBytes(), kHugeBlockCacheBytes);
  EXPECT_GT(cachedHugeBytes(), kHugeBlockCacheBytes - each);
  // A vector released and made again gets the same block.
  releaseCachedHugeBlocks();
  const std::uint32_t* first = nullptr;
  {
    HugeVector<std::uint32_t> v(std::size_t(1) << 20);
    first = v.data();
  }
  HugeVector<std::uint32_t> again(std::size_t(1) << 20);
  EXPECT_EQ(again.data(), first);
  releaseCachedHugeBlocks();
  EXPECT_EQ(cachedHugeBytes(), 0u);
}

// Outside any scope nothing is kept (an idle daemon holds no freed memory), and the last
// scope to close hands back what was kept under it; scopes nest.
TEST(Memory, FreedHugeBlocksAreReleasedWhenTheLastScopeCloses) {
  const std::size_t bytes = std::size_t(4) << 20;
  freeHuge(allocateHuge(bytes), bytes);
  EXPECT_EQ(cachedHugeBytes(), 0u) << "kept with no scope open";
  {
    const HugeBlockCacheScope outer;
    {
      const HugeBlockCacheScope inner;
      freeHuge(allocateHuge(bytes), bytes);
      EXPECT_EQ(cachedHugeBytes(), bytes);
    }
    EXPECT_EQ(cachedHugeBytes(), bytes) << "released while a scope is still open";
  }
  EXPECT_EQ(cachedHugeBytes(), 0u) << "not released when the last scope closed";
}

// The streaming copy writes exactly [dst, dst + bytes) with src's bytes, whatever the
// destination's alignment (its head, the 64-byte loop, the 16-byte steps and the tail) and
// below the size where it falls back to memcpy, and nothing around it.
TEST(Memory, StreamingCopyCopiesExactlyTheBytesAtAnyAlignment) {
  std::vector<unsigned char> src(5000);
  for (std::size_t i = 0; i < src.size(); ++i) src[i] = static_cast<unsigned char>(i * 131 + 7);
  for (const std::size_t bytes : {std::size_t(0), std::size_t(1), std::size_t(255), std::size_t(256),
                                  std::size_t(257), std::size_t(1000), std::size_t(4093)})
    for (std::size_t dst_at = 0; dst_at < 19; ++dst_at)
      for (const std::size_t src_at : {std::size_t(0), std::size_t(3)}) {
        std::vector<unsigned char> dst(bytes + 64, 0xAB);
        copyStreaming(dst.data() + dst_at, src.data() + src_at, bytes);
        for (std::size_t i = 0; i < dst.size(); ++i) {
          const bool inside = i >= dst_at && i < dst_at + bytes;
          const unsigned char want = inside ? src[src_at + i - dst_at] : 0xAB;
          ASSERT_EQ(dst[i], want) << bytes << " bytes to offset " << dst_at << " from " << src_at << ", byte " << i;
        }
      }
}

TEST(Memory, AdviceOnAnyRangeIsHarmless) {
  std::vector<char> small(100, 'x');
  adviseHugePages(small.data(), small.size());  // nothing inside it is a whole 2 MiB page
  adviseHugePages(nullptr, 0);
  EXPECT_EQ(small[99], 'x');
}

}  // namespace
}  // namespace lightlink
