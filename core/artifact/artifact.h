// The on-disk form of a precomputation: one versioned, checksummed, mmap-able file.
//
// Layout (all little-endian, see docs/artifact.md):
//   FileHeader (64 bytes) | SectionEntry[section_count] | padding | section payloads
// Each payload starts at a 64-byte aligned offset so the big arrays (surfels, tree nodes,
// links) can be used in place through std::span straight out of the mapping, with no
// copy. Every section carries an XXH3-64 checksum, and the header and table carry one
// too; Artifact::open verifies them (optionally skipping payloads for a fast reopen) and
// rejects wrong magic, unknown versions, truncation and corruption with a message naming
// the file and the section. Writes are atomic: temp file in the same directory, fsync,
// rename, fsync of the directory, so a crash never leaves a half-written artifact under
// the final name.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "core/common/status.h"

namespace lightlink::artifact {

inline constexpr char kMagic[8] = {'L', 'L', 'N', 'K', 'A', 'R', 'T', '\0'};
// A shard's part of a precomputation (`precompute --shard i/N`, assembled by `lightlink
// merge`; docs/farm.md) is the same container under its own magic, so that a part is never
// opened as an artifact (it lacks most links) nor an artifact merged as a part.
inline constexpr char kPartMagic[8] = {'L', 'L', 'N', 'K', 'P', 'R', 'T', '\0'};
enum class FileKind { kArtifact, kShardPart };
// Bump whenever the layout of any section changes; readers reject other versions.
inline constexpr std::uint32_t kFormatVersion = 3;  // 2: surfel.seen. 3: the direct layer's texels (dt.*)
inline constexpr std::size_t kSectionAlignment = 64;
inline constexpr std::size_t kMaxSectionName = 23;

struct FileHeader {
  char magic[8];
  std::uint32_t format_version;
  std::uint32_t endian_check;  // 0x01020304 as written by a little-endian machine
  std::uint64_t file_bytes;    // the whole file; a shorter file is truncated
  std::uint64_t cache_key;     // hash(scene bytes, parameters, format version)
  std::uint32_t section_count;
  std::uint32_t reserved0;
  std::uint64_t table_checksum;  // XXH3-64 of the section table
  std::uint64_t reserved1;
  std::uint64_t header_checksum;  // XXH3-64 of the 56 bytes above
};
static_assert(sizeof(FileHeader) == 64);

struct SectionEntry {
  char name[kMaxSectionName + 1];  // NUL-terminated
  std::uint64_t offset;            // from file start, multiple of kSectionAlignment
  std::uint64_t bytes;
  std::uint32_t element_bytes;     // size of one element, for a typed view check
  std::uint32_t reserved;
  std::uint64_t checksum;          // XXH3-64 of the payload
};
static_assert(sizeof(SectionEntry) == 56);

std::uint64_t hashBytes(const void* data, std::size_t bytes, std::uint64_t seed = 0);

// Key of the artifact cache: the scene's bytes, the canonical parameter string (the
// caller serialises its parameters deterministically) and the format version.
std::uint64_t cacheKey(std::span<const std::byte> scene_bytes, std::string_view parameters);
std::string cacheKeyHex(std::uint64_t key);

class Writer {
 public:
  explicit Writer(std::uint64_t cache_key, FileKind kind = FileKind::kArtifact) : cache_key_(cache_key), kind_(kind) {}

  // Copies nothing: the span must stay alive until write() returns.
  Status addSection(std::string_view name, std::span<const std::byte> payload,
                    std::uint32_t element_bytes = 1);
  template <typename T>
  Status addArray(std::string_view name, std::span<const T> values) {
    static_assert(std::is_trivially_copyable_v<T>);
    return addSection(name, std::as_bytes(values), sizeof(T));
  }
  Status addString(std::string_view name, std::string_view text) {
    return addSection(name, std::as_bytes(std::span<const char>(text.data(), text.size())), 1);
  }

  // Writes atomically to `path` (temp + fsync + rename + directory fsync).
  Status write(const std::string& path) const;

 private:
  struct Pending {
    std::string name;
    std::span<const std::byte> payload;
    std::uint32_t element_bytes;
  };
  std::uint64_t cache_key_;
  FileKind kind_;
  std::vector<Pending> sections_;
};

struct OpenOptions {
  bool verify_payloads = true;  // false: check header + table only (payloads on demand)
  FileKind kind = FileKind::kArtifact;  // the other kind is refused, naming what the file is
};

// A read-only mapping of an artifact. Movable, not copyable; unmaps on destruction.
class Artifact {
 public:
  static Expected<Artifact> open(const std::string& path, const OpenOptions& options = {});

  Artifact(Artifact&& other) noexcept;
  Artifact& operator=(Artifact&& other) noexcept;
  Artifact(const Artifact&) = delete;
  Artifact& operator=(const Artifact&) = delete;
  ~Artifact();

  std::uint64_t cacheKey() const { return header().cache_key; }
  std::uint64_t fileBytes() const { return size_; }
  const std::string& path() const { return path_; }
  std::span<const SectionEntry> sections() const;
  bool has(std::string_view name) const { return find(name) != nullptr; }

  // The payload of a section, or a Status naming the missing section.
  Expected<std::span<const std::byte>> bytes(std::string_view name) const;
  template <typename T>
  Expected<std::span<const T>> array(std::string_view name) const {
    static_assert(std::is_trivially_copyable_v<T>);
    const SectionEntry* e = find(name);
    if (e == nullptr) return missing(name);
    if (e->element_bytes != sizeof(T) || e->bytes % sizeof(T) != 0)
      return typeMismatch(name, e->element_bytes, sizeof(T));
    return std::span<const T>(reinterpret_cast<const T*>(base_ + e->offset), e->bytes / sizeof(T));
  }
  Expected<std::string> string(std::string_view name) const;
  // Recomputes the checksum of one section (for callers that opened without payloads).
  Status verify(std::string_view name) const;

 private:
  Artifact() = default;
  const FileHeader& header() const { return *reinterpret_cast<const FileHeader*>(base_); }
  const SectionEntry* find(std::string_view name) const;
  Status missing(std::string_view name) const;
  Status typeMismatch(std::string_view name, std::uint32_t stored, std::size_t wanted) const;

  std::string path_;
  const std::byte* base_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace lightlink::artifact
