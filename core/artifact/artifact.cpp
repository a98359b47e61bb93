#include "core/artifact/artifact.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstring>
#include <utility>
#include <chrono>
#include <filesystem>

#include <fmt/format.h>
#include <xxhash.h>

#include "core/common/private_files.h"

namespace lightlink::artifact {
namespace {

constexpr std::uint32_t kEndianCheck = 0x01020304u;

std::size_t alignUp(std::size_t v, std::size_t a) { return (v + a - 1) / a * a; }

std::string errnoText() { return std::strerror(errno); }

// Writes all of `bytes`, retrying on short writes and EINTR.
bool writeAll(int fd, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::write(fd, p, bytes);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += n;
    bytes -= static_cast<std::size_t>(n);
  }
  return true;
}

class FdCloser {
 public:
  explicit FdCloser(int fd) : fd_(fd) {}
  ~FdCloser() {
    if (fd_ >= 0) ::close(fd_);
  }
  FdCloser(const FdCloser&) = delete;
  FdCloser& operator=(const FdCloser&) = delete;
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

}  // namespace

std::uint64_t hashBytes(const void* data, std::size_t bytes, std::uint64_t seed) {
  return XXH3_64bits_withSeed(data, bytes, seed);
}

std::uint64_t cacheKey(std::span<const std::byte> scene_bytes, std::string_view parameters) {
  XXH3_state_t* state = XXH3_createState();
  XXH3_64bits_reset(state);
  const std::uint32_t version = kFormatVersion;
  XXH3_64bits_update(state, &version, sizeof(version));
  const std::uint64_t scene_len = scene_bytes.size();
  XXH3_64bits_update(state, &scene_len, sizeof(scene_len));
  XXH3_64bits_update(state, scene_bytes.data(), scene_bytes.size());
  XXH3_64bits_update(state, parameters.data(), parameters.size());
  const std::uint64_t key = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  return key;
}

std::string cacheKeyHex(std::uint64_t key) { return fmt::format("{:016x}", key); }

Status Writer::addSection(std::string_view name, std::span<const std::byte> payload,
                          std::uint32_t element_bytes) {
  if (name.empty() || name.size() > kMaxSectionName)
    return invalidInput("artifact section name '{}' must have 1..{} characters", name, kMaxSectionName);
  if (element_bytes == 0 || payload.size() % element_bytes != 0)
    return invalidInput("artifact section '{}': {} bytes is not a whole number of {}-byte elements",
                        name, payload.size(), element_bytes);
  for (const auto& s : sections_)
    if (s.name == name) return invalidInput("artifact section '{}' added twice", name);
  sections_.push_back({std::string(name), payload, element_bytes});
  return {};
}

Status Writer::write(const std::string& path) const {
  // Lay out the file first so the header can carry the final size and checksums.
  std::vector<SectionEntry> table(sections_.size());
  std::size_t offset = alignUp(sizeof(FileHeader) + table.size() * sizeof(SectionEntry), kSectionAlignment);
  for (std::size_t i = 0; i < sections_.size(); ++i) {
    SectionEntry& e = table[i];
    std::memset(&e, 0, sizeof(e));
    std::memcpy(e.name, sections_[i].name.data(), sections_[i].name.size());
    e.offset = offset;
    e.bytes = sections_[i].payload.size();
    e.element_bytes = sections_[i].element_bytes;
    e.checksum = hashBytes(sections_[i].payload.data(), sections_[i].payload.size());
    offset = alignUp(offset + e.bytes, kSectionAlignment);
  }
  FileHeader h;
  std::memset(&h, 0, sizeof(h));
  std::memcpy(h.magic, kind_ == FileKind::kArtifact ? kMagic : kPartMagic, sizeof(kMagic));
  h.format_version = kFormatVersion;
  h.endian_check = kEndianCheck;
  h.file_bytes = offset;
  h.cache_key = cache_key_;
  h.section_count = static_cast<std::uint32_t>(table.size());
  h.table_checksum = hashBytes(table.data(), table.size() * sizeof(SectionEntry));
  h.header_checksum = hashBytes(&h, offsetof(FileHeader, header_checksum));

  namespace fs = std::filesystem;
  const fs::path final_path(path);
  const fs::path dir = final_path.has_parent_path() ? final_path.parent_path() : fs::path(".");
  static std::atomic<unsigned> counter{0};
  const fs::path temp = dir / fmt::format(".{}.tmp.{}.{}", final_path.filename().string(), ::getpid(),
                                          counter++);
  int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, kPrivateFileMode);
  if (fd < 0) return ioError("cannot create {}: {}", temp.string(), errnoText());
  FdCloser closer(fd);
  ::fchmod(fd, kPrivateFileMode);  // whatever the umask: artifacts hold scene data
  auto fail = [&](const std::string& what) {
    const std::string err = errnoText();
    ::unlink(temp.c_str());
    return ioError("writing artifact {}: {}: {}", path, what, err);
  };
  static const std::byte kZeros[kSectionAlignment] = {};
  std::size_t written = 0;
  auto pad_to = [&](std::size_t target) {
    while (written < target) {
      const std::size_t n = std::min(target - written, sizeof(kZeros));
      if (!writeAll(fd, kZeros, n)) return false;
      written += n;
    }
    return true;
  };
  if (!writeAll(fd, &h, sizeof(h)) || !writeAll(fd, table.data(), table.size() * sizeof(SectionEntry)))
    return fail("header");
  written = sizeof(h) + table.size() * sizeof(SectionEntry);
  for (std::size_t i = 0; i < sections_.size(); ++i) {
    if (!pad_to(table[i].offset)) return fail("padding");
    if (!writeAll(fd, sections_[i].payload.data(), sections_[i].payload.size()))
      return fail(fmt::format("section '{}'", sections_[i].name));
    written += sections_[i].payload.size();
  }
  if (!pad_to(h.file_bytes)) return fail("padding");
  if (::fsync(fd) != 0) return fail("fsync");
  if (::close(closer.release()) != 0) return fail("close");
  if (::rename(temp.c_str(), final_path.c_str()) != 0) return fail("rename");
  // The rename is durable only once the directory entry is.
  const int dir_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd >= 0) {
    ::fsync(dir_fd);
    ::close(dir_fd);
  }
  return {};
}

Expected<Artifact> Artifact::open(const std::string& path, const OpenOptions& options) {
  // Never blocks: a FIFO or device named like an artifact is refused, not read.
  auto opened = openRegularFileForReading(path, "artifact");
  if (!opened) return opened.status();
  const int fd = *opened;
  FdCloser closer(fd);
  struct stat st {};
  if (::fstat(fd, &st) != 0) return ioError("cannot stat artifact {}: {}", path, errnoText());
  const auto size = static_cast<std::size_t>(st.st_size);
  if (size < sizeof(FileHeader))
    return invalidInput("artifact {} is truncated: {} bytes, smaller than its 64-byte header", path, size);
  void* map = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
  if (map == MAP_FAILED) return ioError("cannot map artifact {}: {}", path, errnoText());

  Artifact a;
  a.path_ = path;
  a.base_ = static_cast<const std::byte*>(map);
  a.size_ = size;
  const FileHeader& h = a.header();
  const bool whole = std::memcmp(h.magic, kMagic, sizeof(kMagic)) == 0;
  const bool part = std::memcmp(h.magic, kPartMagic, sizeof(kPartMagic)) == 0;
  if (options.kind == FileKind::kArtifact && part)
    return invalidInput("{} is one shard's part of a precomputation, not an artifact: assemble the parts with "
                        "`lightlink merge`", path);
  if (options.kind == FileKind::kShardPart && whole)
    return invalidInput("{} is a whole artifact, not a shard part (`lightlink precompute --shard I/N` writes parts)",
                        path);
  if (!(options.kind == FileKind::kArtifact ? whole : part))
    return invalidInput("{} is not a lightlink {} (bad magic)", path,
                        options.kind == FileKind::kArtifact ? "artifact" : "shard part");
  if (h.endian_check != kEndianCheck)
    return unsupported("artifact {} was written with another byte order", path);
  if (h.format_version != kFormatVersion)
    return unsupported("artifact {} has format version {}, this build reads version {}; recompute it",
                       path, h.format_version, kFormatVersion);
  if (h.header_checksum != hashBytes(&h, offsetof(FileHeader, header_checksum)))
    return invalidInput("artifact {} is corrupt: header checksum mismatch", path);
  if (h.file_bytes != size)
    return invalidInput("artifact {} is {}: {} bytes on disk, header says {}", path,
                        size < h.file_bytes ? "truncated" : "oversized", size, h.file_bytes);
  const std::size_t table_end = sizeof(FileHeader) + std::size_t(h.section_count) * sizeof(SectionEntry);
  if (h.section_count > 4096 || table_end > size)
    return invalidInput("artifact {} is corrupt: section table ({} entries) exceeds the file", path,
                        h.section_count);
  const auto table = a.sections();
  if (h.table_checksum != hashBytes(table.data(), table.size_bytes()))
    return invalidInput("artifact {} is corrupt: section table checksum mismatch", path);
  for (const auto& e : table) {
    const std::string_view name(e.name, strnlen(e.name, sizeof(e.name)));
    if (e.offset % kSectionAlignment != 0 || e.offset < table_end || e.offset > size ||
        e.bytes > size - e.offset)
      return invalidInput("artifact {} is corrupt: section '{}' lies outside the file", path, name);
    if (options.verify_payloads && hashBytes(a.base_ + e.offset, e.bytes) != e.checksum)
      return invalidInput("artifact {} is corrupt: checksum mismatch in section '{}'", path, name);
  }
  return a;
}

Artifact::Artifact(Artifact&& other) noexcept
    : path_(std::move(other.path_)),
      base_(std::exchange(other.base_, nullptr)),
      size_(std::exchange(other.size_, 0)) {}

Artifact& Artifact::operator=(Artifact&& other) noexcept {
  if (this != &other) {
    if (base_ != nullptr) ::munmap(const_cast<std::byte*>(base_), size_);
    path_ = std::move(other.path_);
    base_ = std::exchange(other.base_, nullptr);
    size_ = std::exchange(other.size_, 0);
  }
  return *this;
}

Artifact::~Artifact() {
  if (base_ != nullptr) ::munmap(const_cast<std::byte*>(base_), size_);
}

std::span<const SectionEntry> Artifact::sections() const {
  return {reinterpret_cast<const SectionEntry*>(base_ + sizeof(FileHeader)), header().section_count};
}

const SectionEntry* Artifact::find(std::string_view name) const {
  for (const auto& e : sections())
    if (std::string_view(e.name, strnlen(e.name, sizeof(e.name))) == name) return &e;
  return nullptr;
}

Status Artifact::missing(std::string_view name) const {
  return invalidInput("artifact {} has no section '{}'", path_, name);
}

Status Artifact::typeMismatch(std::string_view name, std::uint32_t stored, std::size_t wanted) const {
  return invalidInput("artifact {} section '{}' holds {}-byte elements, reader expects {}", path_, name,
                      stored, wanted);
}

Expected<std::span<const std::byte>> Artifact::bytes(std::string_view name) const {
  const SectionEntry* e = find(name);
  if (e == nullptr) return missing(name);
  return std::span<const std::byte>(base_ + e->offset, e->bytes);
}

Expected<std::string> Artifact::string(std::string_view name) const {
  auto b = bytes(name);
  if (!b) return b.status();
  return std::string(reinterpret_cast<const char*>(b->data()), b->size());
}

Status Artifact::verify(std::string_view name) const {
  const SectionEntry* e = find(name);
  if (e == nullptr) return missing(name);
  if (hashBytes(base_ + e->offset, e->bytes) != e->checksum)
    return invalidInput("artifact {} is corrupt: checksum mismatch in section '{}'", path_, name);
  return {};
}

}  // namespace lightlink::artifact
