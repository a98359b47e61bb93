#include "core/common/memory.h"

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace lightlink {

void copyStreaming(void* dst, const void* src, std::size_t bytes) noexcept {
#if defined(__SSE2__)
  // Below a few lines the fence costs more than the reads saved.
  constexpr std::size_t kMin = 256;
  if (bytes < kMin) {
    std::memcpy(dst, src, bytes);
    return;
  }
  auto* d = static_cast<unsigned char*>(dst);
  const auto* s = static_cast<const unsigned char*>(src);
  const std::size_t head = (16 - (reinterpret_cast<std::uintptr_t>(d) & 15)) & 15;
  std::memcpy(d, s, head);
  d += head, s += head, bytes -= head;
  for (; bytes >= 64; d += 64, s += 64, bytes -= 64) {
    const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(s));
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(s + 16));
    const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(s + 32));
    const __m128i e = _mm_loadu_si128(reinterpret_cast<const __m128i*>(s + 48));
    _mm_stream_si128(reinterpret_cast<__m128i*>(d), a);
    _mm_stream_si128(reinterpret_cast<__m128i*>(d + 16), b);
    _mm_stream_si128(reinterpret_cast<__m128i*>(d + 32), c);
    _mm_stream_si128(reinterpret_cast<__m128i*>(d + 48), e);
  }
  for (; bytes >= 16; d += 16, s += 16, bytes -= 16)
    _mm_stream_si128(reinterpret_cast<__m128i*>(d), _mm_loadu_si128(reinterpret_cast<const __m128i*>(s)));
  std::memcpy(d, s, bytes);
  _mm_sfence();
#else
  std::memcpy(dst, src, bytes);
#endif
}

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

namespace {

std::size_t roundedToHugePages(std::size_t bytes) { return (bytes + kHugePageBytes - 1) & ~(kHugePageBytes - 1); }

// Freed huge blocks kept for the next allocation of about their size (the header says why).
struct BlockCache {
  std::mutex mutex;
  std::vector<std::pair<void*, std::size_t>> blocks;  // block, rounded bytes
  std::size_t bytes = 0;
  int scopes = 0;  // open HugeBlockCacheScopes: blocks are kept only while one is

  // A kept block of exactly `rounded` bytes (the most recently kept one), or null. Only
  // equal sizes: the block comes back through freeHuge with the size asked of it, which is
  // then its true size, so the cap counts what is really kept.
  void* take(std::size_t rounded) {
    const std::lock_guard lock(mutex);
    for (std::size_t i = blocks.size(); i-- > 0;) {
      if (blocks[i].second != rounded) continue;
      void* p = blocks[i].first;
      bytes -= rounded;
      blocks.erase(blocks.begin() + static_cast<std::ptrdiff_t>(i));
      return p;
    }
    return nullptr;
  }
  // Keeps the block if it fits under the cap; false: the caller frees it.
  bool keep(void* p, std::size_t rounded) {
    const std::lock_guard lock(mutex);
    if (scopes == 0 || rounded > kHugeBlockCacheBytes - bytes) return false;
    try {
      blocks.push_back({p, rounded});
    } catch (const std::bad_alloc&) {
      return false;
    }
    bytes += rounded;
    return true;
  }
  void release() {
    const std::lock_guard lock(mutex);
    releaseLocked();
  }
  void releaseLocked() {
    for (const auto& [p, size] : blocks) std::free(p);
    blocks.clear();
    bytes = 0;
  }
  void open() {
    const std::lock_guard lock(mutex);
    ++scopes;
  }
  void close() {
    const std::lock_guard lock(mutex);
    if (--scopes == 0) releaseLocked();
  }
};

// Never destroyed: a HugeVector may be freed during static or thread-local destruction.
BlockCache& blockCache() {
  static BlockCache* const cache = new BlockCache;
  return *cache;
}

}  // namespace

void* allocateHuge(std::size_t bytes) {
  if (bytes < kHugePageBytes) return ::operator new(bytes);
  if (bytes > std::size_t(-1) - kHugePageBytes) throw std::bad_alloc();
  const std::size_t rounded = roundedToHugePages(bytes);
  if (void* kept = blockCache().take(rounded)) return kept;
  void* p = std::aligned_alloc(kHugePageBytes, rounded);
  if (p == nullptr) throw std::bad_alloc();
  adviseHugePages(p, rounded);
  return p;
}

void freeHuge(void* p, std::size_t bytes) noexcept {
  if (bytes < kHugePageBytes)
    ::operator delete(p);
  else if (!blockCache().keep(p, roundedToHugePages(bytes)))
    std::free(p);
}

std::size_t cachedHugeBytes() {
  BlockCache& cache = blockCache();
  const std::lock_guard lock(cache.mutex);
  return cache.bytes;
}

void releaseCachedHugeBlocks() { blockCache().release(); }

HugeBlockCacheScope::HugeBlockCacheScope() { blockCache().open(); }
HugeBlockCacheScope::~HugeBlockCacheScope() { blockCache().close(); }

}  // namespace lightlink
