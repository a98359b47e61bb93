#include "service/cache_quota.h"

#include <fcntl.h>
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <utility>

namespace lightlink::service {
namespace {

namespace fs = std::filesystem;

struct CacheFile {
  std::string path;
  std::uint64_t bytes = 0;
  timespec mtime{};
  bool kept = false;
};

using FileId = std::pair<dev_t, ino_t>;

// Regular files of `dir` whose names end with one of `suffixes` (never dot files: temps).
void collect(const fs::path& dir, std::initializer_list<const char*> suffixes, const std::set<FileId>& keep,
             std::vector<CacheFile>& out) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.empty() || name[0] == '.') continue;
    const bool match = std::any_of(suffixes.begin(), suffixes.end(), [&](const char* s) {
      const std::string suffix(s);
      return name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
    });
    if (!match) continue;
    struct stat st {};
    if (::lstat(e.path().c_str(), &st) != 0 || !S_ISREG(st.st_mode)) continue;
    CacheFile f;
    f.path = e.path().string();
    f.bytes = static_cast<std::uint64_t>(st.st_size);
    f.mtime = st.st_mtim;
    f.kept = keep.count({st.st_dev, st.st_ino}) > 0;
    out.push_back(std::move(f));
  }
}

}  // namespace

EvictionReport enforceCacheQuota(const std::string& cache_dir, std::uint64_t quota, std::uint64_t incoming,
                                 const std::vector<std::string>& keep) {
  EvictionReport report;
  std::set<FileId> kept_ids;
  for (const auto& k : keep) {
    struct stat st {};
    if (!k.empty() && ::stat(k.c_str(), &st) == 0) kept_ids.insert({st.st_dev, st.st_ino});
  }
  std::vector<CacheFile> files;
  collect(cache_dir, {".llk"}, kept_ids, files);
  collect(fs::path(cache_dir) / "inline", {".gltf", ".glb"}, kept_ids, files);
  std::uint64_t total = 0;
  for (const auto& f : files) total += f.bytes;
  report.bytes_after = total;
  if (quota == 0 || total + incoming <= quota) return report;
  std::sort(files.begin(), files.end(), [](const CacheFile& a, const CacheFile& b) {
    return a.mtime.tv_sec != b.mtime.tv_sec ? a.mtime.tv_sec < b.mtime.tv_sec : a.mtime.tv_nsec < b.mtime.tv_nsec;
  });
  for (const auto& f : files) {
    if (total + incoming <= quota) break;
    if (f.kept) continue;
    std::error_code ec;
    if (!fs::remove(f.path, ec)) continue;
    total -= f.bytes;
    ++report.files_removed;
    report.bytes_removed += f.bytes;
    report.removed.push_back(f.path);
  }
  report.bytes_after = total;
  return report;
}

void touchLastUse(const std::string& path) {
  if (path.empty()) return;
  // AT_SYMLINK_NOFOLLOW: a link planted in the cache does not move another file's time.
  (void)::utimensat(AT_FDCWD, path.c_str(), nullptr, AT_SYMLINK_NOFOLLOW);
}

}  // namespace lightlink::service
