#include "clients/client/raw_result.h"

#include <string>

namespace lightlink::client {
namespace {

// Reads protobuf wire data spread over slices; callers bound each (sub)message by comparing
// position() with its end.
class SliceReader {
 public:
  explicit SliceReader(const std::vector<grpc::Slice>& slices) : slices_(slices) {
    for (const auto& s : slices) total_ += s.size();
  }
  std::size_t position() const { return pos_; }
  std::size_t total() const { return total_; }

  bool byte(std::uint8_t& b) {
    while (slice_ < slices_.size() && at_ == slices_[slice_].size()) next();
    if (slice_ >= slices_.size()) return false;
    b = slices_[slice_].begin()[at_++];
    ++pos_;
    return true;
  }
  // A base-128 varint of at most 10 bytes.
  bool varint(std::uint64_t& v) {
    v = 0;
    for (int shift = 0; shift < 70; shift += 7) {
      std::uint8_t b = 0;
      if (!byte(b)) return false;
      if (shift == 63 && b > 1) return false;  // beyond 64 bits
      v |= std::uint64_t(b & 0x7f) << shift;
      if ((b & 0x80) == 0) return true;
    }
    return false;
  }
  // The next n bytes as pieces of the slices (no copy); false when fewer remain.
  bool pieces(std::size_t n, std::vector<std::span<const std::uint8_t>>* out) {
    if (n > total_ - pos_) return false;
    while (n > 0) {
      while (at_ == slices_[slice_].size()) next();
      const std::size_t take = std::min(n, slices_[slice_].size() - at_);
      if (out) out->emplace_back(slices_[slice_].begin() + at_, take);
      at_ += take;
      pos_ += take;
      n -= take;
    }
    return true;
  }

 private:
  void next() {
    ++slice_;
    at_ = 0;
  }
  const std::vector<grpc::Slice>& slices_;
  std::size_t slice_ = 0, at_ = 0, pos_ = 0, total_ = 0;
};

enum WireType : std::uint32_t { kVarint = 0, kFixed64 = 1, kLen = 2, kFixed32 = 5 };

// Skips a field of an unknown number (groups, wire types 3 and 4, are not proto3).
Status skipField(SliceReader& r, std::uint32_t wire_type, std::size_t end, const char* where) {
  std::uint64_t v = 0;
  switch (wire_type) {
    case kVarint:
      if (!r.varint(v)) return invalidInput("{}: truncated varint", where);
      break;
    case kFixed64:
      if (!r.pieces(8, nullptr)) return invalidInput("{}: truncated fixed64", where);
      break;
    case kFixed32:
      if (!r.pieces(4, nullptr)) return invalidInput("{}: truncated fixed32", where);
      break;
    case kLen:
      if (!r.varint(v) || v > end - r.position() || !r.pieces(v, nullptr))
        return invalidInput("{}: length-delimited field runs past the message", where);
      break;
    default: return invalidInput("{}: wire type {} is not valid here", where, wire_type);
  }
  if (r.position() > end) return invalidInput("{}: field runs past the message", where);
  return {};
}

Status readTag(SliceReader& r, std::uint32_t& field, std::uint32_t& wire_type, const char* where) {
  std::uint64_t tag = 0;
  if (!r.varint(tag) || tag > 0xffffffffu) return invalidInput("{}: bad field tag", where);
  field = static_cast<std::uint32_t>(tag >> 3);
  wire_type = static_cast<std::uint32_t>(tag & 7);
  if (field == 0) return invalidInput("{}: field number 0", where);
  return {};
}

Status decodeChunk(SliceReader& r, std::size_t end, RawResult& out) {
  // A repeated occurrence of the chunk field merges into the earlier one (protobuf rules):
  // scalars and `data` are replaced by the last occurrence.
  while (r.position() < end) {
    std::uint32_t field = 0, wire_type = 0;
    if (Status s = readTag(r, field, wire_type, "chunk"); !s) return s;
    std::uint64_t v = 0;
    if (field >= 1 && field <= 3 && wire_type == kVarint) {
      if (!r.varint(v) || r.position() > end) return invalidInput("chunk: truncated varint in field {}", field);
      if (field == 1) out.payload = static_cast<int>(static_cast<std::int32_t>(v));
      if (field == 2) out.offset = v;
      if (field == 3) out.tile = static_cast<std::uint32_t>(v);
    } else if (field == 4 && wire_type == kLen) {
      if (!r.varint(v) || v > end - r.position()) return invalidInput("chunk.data: length runs past the message");
      out.data.clear();
      r.pieces(v, &out.data);
    } else if (Status s = skipField(r, wire_type, end, "chunk"); !s) {
      return s;
    }
  }
  return {};
}

}  // namespace

std::size_t RawResult::dataSize() const {
  std::size_t n = 0;
  for (const auto& p : data) n += p.size();
  return n;
}

Status decodeRawResult(const grpc::ByteBuffer& bytes, RawResult& out) {
  out.kind = RawResult::Kind::kNone;
  out.header.Clear();
  out.payload = 0;
  out.offset = 0;
  out.tile = 0;
  out.data.clear();
  out.slices.clear();
  if (!bytes.Valid()) return invalidInput("result message: empty buffer");
  if (grpc::Status s = bytes.Dump(&out.slices); !s.ok()) return invalidInput("result message: {}", s.error_message());
  SliceReader r(out.slices);
  const std::size_t end = r.total();
  std::string header_bytes;
  while (r.position() < end) {
    std::uint32_t field = 0, wire_type = 0;
    if (Status s = readTag(r, field, wire_type, "result message"); !s) return s;
    if ((field == 1 || field == 2) && wire_type == kLen) {
      std::uint64_t len = 0;
      if (!r.varint(len) || len > end - r.position())
        return invalidInput("result message: {} length runs past the message", field == 1 ? "header" : "chunk");
      const std::size_t sub_end = r.position() + len;
      if (field == 1) {
        // oneof: a header after a chunk replaces it; repeated headers merge.
        std::vector<std::span<const std::uint8_t>> pieces;
        r.pieces(len, &pieces);
        header_bytes.clear();
        for (const auto& p : pieces) header_bytes.append(reinterpret_cast<const char*>(p.data()), p.size());
        if (out.kind != RawResult::Kind::kHeader) out.header.Clear();
        if (!out.header.MergeFromString(header_bytes)) return invalidInput("result header: not a valid ResultHeader");
        out.kind = RawResult::Kind::kHeader;
      } else {
        if (out.kind != RawResult::Kind::kChunk) {
          out.payload = 0;
          out.offset = 0;
          out.tile = 0;
          out.data.clear();
        }
        if (Status s = decodeChunk(r, sub_end, out); !s) return s;
        out.kind = RawResult::Kind::kChunk;
      }
    } else if (Status s = skipField(r, wire_type, end, "result message"); !s) {
      return s;
    }
  }
  return {};
}

}  // namespace lightlink::client
