#include "clients/client/shared_result.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/slice.h>

#include "clients/client/raw_result.h"

namespace lightlink::client {
namespace {

// The file, mapped; unmapped and closed on every way out.
class Mapping {
 public:
  ~Mapping() {
    if (data_ != nullptr) ::munmap(data_, size_);
    if (fd_ >= 0) ::close(fd_);
  }
  Status open(const std::string& path, std::uint64_t expected) {
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) return notFound("shared result {}: cannot open: {}", path, std::strerror(errno));
    struct stat st {};
    if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode))
      return invalidInput("shared result {}: not a regular file", path);
    if (static_cast<std::uint64_t>(st.st_size) != expected)
      return invalidInput("shared result {}: {} bytes, the header names {}", path, st.st_size, expected);
    size_ = static_cast<std::size_t>(st.st_size);
    if (size_ == 0) return invalidInput("shared result {}: empty", path);
    void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0);
    if (p == MAP_FAILED) return invalidInput("shared result {}: cannot map: {}", path, std::strerror(errno));
    data_ = p;
    return {};
  }
  const std::uint8_t* bytes() const { return static_cast<const std::uint8_t*>(data_); }
  std::size_t size() const { return size_; }

 private:
  int fd_ = -1;
  void* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace

Status readSharedResult(const v1::SharedResult& shared, ResultAssembler& assembler) {
  const std::string& path = shared.path();
  if (path.empty()) return invalidInput("shared result: no path");
  Mapping m;
  if (Status s = m.open(path, shared.bytes()); !s) return s;
  const std::uint8_t* p = m.bytes();
  const std::size_t size = m.size();
  if (size < sizeof v1::kSharedResultMagic || std::memcmp(p, v1::kSharedResultMagic, sizeof v1::kSharedResultMagic) != 0)
    return invalidInput("shared result {}: not a lightlink shared result of format version 1 (magic)", path);
  std::size_t at = sizeof v1::kSharedResultMagic;
  RawResult decoded;
  for (std::size_t record = 0; at < size; ++record) {
    std::uint32_t length = 0;
    if (size - at < sizeof length)
      return invalidInput("shared result {}: record {} truncated in its length", path, record);
    std::memcpy(&length, p + at, sizeof length);  // little-endian on every supported host
    at += sizeof length;
    if (length > size - at)
      return invalidInput("shared result {}: record {} claims {} bytes, {} left", path, record, length, size - at);
    // A slice over the mapping (no copy); the mapping outlives every use of it below.
    const grpc::Slice slice(p + at, length, grpc::Slice::STATIC_SLICE);
    const grpc::ByteBuffer message(&slice, 1);
    at += length;
    if (Status s = decodeRawResult(message, decoded); !s)
      return invalidInput("shared result {}: record {}: {}", path, record, s.message());
    if (decoded.kind != RawResult::Kind::kChunk)
      return invalidInput("shared result {}: record {} is not a chunk", path, record);
    if (Status s = assembler.add(decoded); !s) return invalidInput("shared result {}: {}", path, s.message());
  }
  return {};
}

}  // namespace lightlink::client
