// Cache quota: bounds the disk the daemon's cache takes.
//
// The evictable files are the artifacts (`<cache-dir>/<key>.llk`) and the stored inline
// scenes (`<cache-dir>/inline/*`); sessions.json and temp files are never touched. Their
// modification time is their last use (touchLastUse at open and close; atime is unreliable
// under relatime/noatime), and eviction removes the least recently used first until the
// files plus `incoming` bytes fit the quota. Files in `keep` (those of resident scenes)
// are never removed, so a quota smaller than the resident set is exceeded rather than
// breaking a scene. Only regular files count: a FIFO or symlink is neither read nor removed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace lightlink::service {

struct EvictionReport {
  int files_removed = 0;
  std::uint64_t bytes_removed = 0;
  std::uint64_t bytes_after = 0;  // evictable + kept bytes left in the cache
  std::vector<std::string> removed;
};

// Removes least recently used evictable files of `cache_dir` not in `keep` until their total
// plus `incoming` is at most `quota` (0: no limit, nothing removed).
EvictionReport enforceCacheQuota(const std::string& cache_dir, std::uint64_t quota, std::uint64_t incoming,
                                 const std::vector<std::string>& keep);

// Marks a cache file as used now (its modification time); missing files are ignored.
void touchLastUse(const std::string& path);

}  // namespace lightlink::service
