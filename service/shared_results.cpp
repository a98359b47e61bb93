#include "service/shared_results.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <limits>
#include <vector>

#include <fmt/format.h>
#include <grpcpp/impl/codegen/proto_utils.h>

#include "proto/lightlink.pb.h"
#include "service/auth.h"

namespace lightlink::service {
namespace {

namespace fs = std::filesystem;

constexpr std::string_view kDirPrefix = "lightlinkd-";

// Writes every byte of `parts` (iovecs) to fd, across short writes.
Status writeAllV(int fd, std::vector<iovec> parts, const std::string& path) {
  std::size_t first = 0;
  while (first < parts.size()) {
    const int count = static_cast<int>(std::min<std::size_t>(parts.size() - first, IOV_MAX));
    const ssize_t n = ::writev(fd, parts.data() + first, count);
    if (n < 0) {
      if (errno == EINTR) continue;
      return ioError("{}: write failed: {}", path, std::strerror(errno));
    }
    auto left = static_cast<std::size_t>(n);
    while (first < parts.size() && left >= parts[first].iov_len) left -= parts[first++].iov_len;
    if (first < parts.size()) {
      parts[first].iov_base = static_cast<char*>(parts[first].iov_base) + left;
      parts[first].iov_len -= left;
    }
  }
  return Status();
}

}  // namespace

int removeStaleSharedDirs(const std::string& base) {
  std::error_code ec;
  if (base.empty() || !fs::is_directory(base, ec)) return 0;
  int removed = 0;
  for (const auto& entry : fs::directory_iterator(base, ec)) {
    const std::string name = entry.path().filename().string();
    if (!name.starts_with(kDirPrefix)) continue;
    // lightlinkd-<pid>-<suffix>
    const std::string rest = name.substr(kDirPrefix.size());
    const auto dash = rest.find('-');
    if (dash == std::string::npos || dash == 0) continue;
    const std::string digits = rest.substr(0, dash);
    if (!std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }) || digits.size() > 9)
      continue;
    const auto pid = static_cast<pid_t>(std::stol(digits));
    struct stat st {};
    if (::lstat(entry.path().c_str(), &st) != 0 || !S_ISDIR(st.st_mode) || st.st_uid != ::geteuid()) continue;
    if (pid == ::getpid() || ::kill(pid, 0) == 0 || errno != ESRCH) continue;  // alive (or not ours to judge)
    std::error_code rm;
    fs::remove_all(entry.path(), rm);
    if (!rm) ++removed;
  }
  return removed;
}

SharedResults::SharedResults(std::string base) : base_(std::move(base)) {}

SharedResults::~SharedResults() {
  std::lock_guard lock(mutex_);
  if (dir_.empty()) return;
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

std::string SharedResults::directory() const {
  std::lock_guard lock(mutex_);
  return dir_;
}

std::size_t SharedResults::fileCount() const {
  std::lock_guard lock(mutex_);
  std::size_t n = 0;
  for (const auto& [scene, files] : by_scene_) n += files.size();
  return n;
}

std::uint64_t SharedResults::byteCount() const {
  std::lock_guard lock(mutex_);
  std::uint64_t n = 0;
  for (const auto& [scene, files] : by_scene_)
    for (const Entry& e : files) n += e.bytes;
  return n;
}

Status SharedResults::ensureDirectory() {
  if (!dir_.empty()) return Status();
  std::string pattern = fmt::format("{}/{}{}-XXXXXX", base_, kDirPrefix, ::getpid());
  if (::mkdtemp(pattern.data()) == nullptr)  // mode 0700
    return ioError("shared memory: cannot create a directory under {}: {}", base_, std::strerror(errno));
  dir_ = pattern;
  return Status();
}

Expected<SharedResults::Entry> SharedResults::write(const Snapshot& snap, const SpecKey& spec, std::size_t chunk_bytes,
                                                    const WireResult& wire) {
  if (wire.messages.empty()) return internalError("shared memory: a result without a header");
  if (Status s = ensureDirectory(); !s) return s;
  const std::uint64_t id = ++counter_;
  Entry e;
  e.sequence = snap.sequence;
  e.spec = spec;
  e.chunk_bytes = chunk_bytes;
  e.path = fmt::format("{}/r{}.llr", dir_, id);
  const std::string temp = fmt::format("{}/.r{}.tmp", dir_, id);

  // The chunk messages as records: a little-endian uint32 length, then the bytes.
  std::vector<std::vector<grpc::Slice>> slices(wire.messages.size());
  std::vector<std::uint32_t> lengths(wire.messages.size());
  std::vector<iovec> parts;
  parts.push_back({const_cast<char*>(v1::kSharedResultMagic), sizeof v1::kSharedResultMagic});
  std::uint64_t bytes = sizeof v1::kSharedResultMagic;
  for (std::size_t m = 1; m < wire.messages.size(); ++m) {
    const std::size_t length = wire.messages[m].Length();
    if (length > std::numeric_limits<std::uint32_t>::max()) return internalError("shared memory: a message over 4 GiB");
    if (!wire.messages[m].Dump(&slices[m]).ok()) return internalError("shared memory: cannot read a result message");
    lengths[m] = static_cast<std::uint32_t>(length);  // x86-64 and aarch64: already little-endian
    parts.push_back({&lengths[m], sizeof(std::uint32_t)});
    for (const grpc::Slice& s : slices[m])
      parts.push_back({const_cast<std::uint8_t*>(s.begin()), s.size()});
    bytes += sizeof(std::uint32_t) + length;
  }

  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) return ioError("shared memory: cannot create {}: {}", temp, std::strerror(errno));
  Status written = writeAllV(fd, std::move(parts), temp);
  if (::close(fd) != 0 && written) written = ioError("{}: close failed: {}", temp, std::strerror(errno));
  // Renamed only when complete: a client never sees a partial file under the name it is given.
  if (written && ::rename(temp.c_str(), e.path.c_str()) != 0)
    written = ioError("shared memory: cannot rename {}: {}", temp, std::strerror(errno));
  if (!written) {
    ::unlink(temp.c_str());
    return written;
  }

  // The stream's header, with `shared` naming the file.
  grpc::ByteBuffer header_copy = wire.messages[0];  // references the same slices
  v1::ResultMessage header;
  if (!grpc::SerializationTraits<v1::ResultMessage>::Deserialize(&header_copy, &header).ok() || !header.has_header()) {
    ::unlink(e.path.c_str());
    return internalError("shared memory: the result's first message is not a header");
  }
  header.mutable_header()->mutable_shared()->set_path(e.path);
  header.mutable_header()->mutable_shared()->set_bytes(bytes);
  e.bytes = bytes;
  auto serialized = std::make_shared<grpc::ByteBuffer>();
  bool own = false;
  if (!grpc::SerializationTraits<v1::ResultMessage>::Serialize(header, serialized.get(), &own).ok()) {
    ::unlink(e.path.c_str());
    return internalError("shared memory: cannot serialize the header");
  }
  e.header = std::move(serialized);
  return e;
}

std::size_t SharedResults::distinctResults(const std::deque<Entry>& files) {
  std::vector<std::uint64_t> seqs;
  for (const auto& e : files) seqs.push_back(e.sequence);
  std::sort(seqs.begin(), seqs.end());
  return static_cast<std::size_t>(std::unique(seqs.begin(), seqs.end()) - seqs.begin());
}

bool SharedResults::olderThanKept(const std::deque<Entry>& files, std::uint64_t sequence) {
  return distinctResults(files) >= kKeepResults &&
         std::all_of(files.begin(), files.end(), [&](const Entry& e) { return e.sequence > sequence; });
}

void SharedResults::trim(std::deque<Entry>& files) {
  while (!files.empty() && (files.size() > kMaxFilesPerScene || distinctResults(files) > kKeepResults)) {
    // The oldest result goes first; within it, the file written first.
    auto oldest = std::min_element(files.begin(), files.end(),
                                   [](const Entry& a, const Entry& b) { return a.sequence < b.sequence; });
    ::unlink(oldest->path.c_str());
    files.erase(oldest);
  }
}

Expected<std::shared_ptr<const grpc::ByteBuffer>> SharedResults::header(const Snapshot& snap, const SpecKey& spec,
                                                                        std::size_t chunk_bytes,
                                                                        const WireResult& wire) {
  if (!enabled()) return unsupported("shared memory delivery is off (--no-shared-memory)");
  // Under one lock: the clients woken by one result wait for one write instead of each
  // writing the same file (as Snapshot::wire builds the wire form once).
  std::lock_guard lock(mutex_);
  std::deque<Entry>& files = by_scene_[snap.scene_id];
  for (const Entry& e : files)
    if (e.sequence == snap.sequence && e.spec == spec && e.chunk_bytes == chunk_bytes) return e.header;
  if (olderThanKept(files, snap.sequence))  // its file would be the first to go: not written
    return unsupported("shared memory: result {} is older than the {} kept", snap.sequence, kKeepResults);
  auto e = write(snap, spec, chunk_bytes, wire);
  if (!e) return e.status();
  const std::string path = e->path;
  auto header = e->header;
  files.push_back(std::move(e).value());
  trim(files);
  // Past the file cap the oldest result's files go, and that may be this one.
  if (std::none_of(files.begin(), files.end(), [&](const Entry& f) { return f.path == path; }))
    return unsupported("shared memory: result {} is older than the {} files kept", snap.sequence, kMaxFilesPerScene);
  return header;
}

void SharedResults::dropScene(const std::string& scene_id) {
  std::lock_guard lock(mutex_);
  auto it = by_scene_.find(scene_id);
  if (it == by_scene_.end()) return;
  for (const Entry& e : it->second) ::unlink(e.path.c_str());
  by_scene_.erase(it);
}

}  // namespace lightlink::service
