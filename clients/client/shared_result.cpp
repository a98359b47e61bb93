#include "clients/client/shared_result.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <limits>
#include <span>
#include <vector>


namespace lightlink::client {
namespace {

// The file's bytes, read into a buffer each thread reuses: one copy out of the page cache.
// Mapping the file instead costs a munmap per result, and with the client's threads on
// several cores every munmap is a TLB shootdown (service_bench with 50 shared-memory clients).
Expected<std::span<const std::uint8_t>> readWhole(const std::string& path, std::uint64_t expected) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return notFound("shared result {}: cannot open: {}", path, std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) return invalidInput("shared result {}: not a regular file", path);
  if (static_cast<std::uint64_t>(st.st_size) != expected)
    return invalidInput("shared result {}: {} bytes, the header names {}", path, st.st_size, expected);
  thread_local std::vector<std::uint8_t> buffer;
  const auto size = static_cast<std::size_t>(st.st_size);
  if (buffer.size() < size) buffer.resize(size);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd, buffer.data() + done, size - done, static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return invalidInput("shared result {}: read failed: {}", path, std::strerror(errno));
    if (n == 0) return invalidInput("shared result {}: ended after {} of {} bytes", path, done, size);
    done += static_cast<std::size_t>(n);
  }
  return std::span<const std::uint8_t>(buffer.data(), size);
}

}  // namespace

Status readSharedResult(const v1::SharedResult& shared, ResultAssembler& assembler) {
  const std::string& path = shared.path();
  if (path.empty()) return invalidInput("shared result: no path");
  auto whole = readWhole(path, shared.bytes());
  if (!whole) return whole.status();
  const std::uint8_t* p = whole->data();
  const std::size_t size = whole->size();
  if (size < sizeof v1::kSharedResultMagic || std::memcmp(p, v1::kSharedResultMagic, sizeof v1::kSharedResultMagic) != 0)
    return invalidInput("shared result {}: not a lightlink shared result of format version 1 (magic)", path);
  std::size_t at = sizeof v1::kSharedResultMagic;
  v1::ResultMessage decoded;
  for (std::size_t record = 0; at < size; ++record) {
    std::uint32_t length = 0;
    if (size - at < sizeof length)
      return invalidInput("shared result {}: record {} truncated in its length", path, record);
    std::memcpy(&length, p + at, sizeof length);  // little-endian on every supported host
    at += sizeof length;
    if (length > size - at || length > static_cast<std::uint32_t>(std::numeric_limits<int>::max()))
      return invalidInput("shared result {}: record {} claims {} bytes, {} left", path, record, length, size - at);
    const bool parsed = decoded.ParseFromArray(p + at, static_cast<int>(length));
    at += length;
    if (!parsed) return invalidInput("shared result {}: record {}: not a valid ResultMessage", path, record);
    if (!decoded.has_chunk()) return invalidInput("shared result {}: record {} is not a chunk", path, record);
    if (Status s = assembler.add(decoded); !s) return invalidInput("shared result {}: {}", path, s.message());
  }
  return {};
}

}  // namespace lightlink::client
