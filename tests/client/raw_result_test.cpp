// decodeRawResult (clients/client/raw_result.h) against protobuf's own parser: the same
// bytes, split into gRPC slices at every place, must give the same header or chunk fields;
// anything the decoder accepts, protobuf accepts with the same values; truncated and
// corrupted messages are refused.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "clients/client/raw_result.h"
#include "clients/client/textures.h"
#include "proto/lightlink.pb.h"

namespace lightlink::client {
namespace {

// `bytes` as a ByteBuffer of slices cut at `cuts` (ascending offsets).
grpc::ByteBuffer sliced(const std::string& bytes, const std::vector<std::size_t>& cuts) {
  std::vector<grpc::Slice> slices;
  std::size_t at = 0;
  for (std::size_t c : cuts) {
    slices.emplace_back(bytes.data() + at, c - at);
    at = c;
  }
  slices.emplace_back(bytes.data() + at, bytes.size() - at);
  return grpc::ByteBuffer(slices.data(), slices.size());
}

std::string dataOf(const RawResult& r) {
  std::string s;
  for (const auto& p : r.data) s.append(reinterpret_cast<const char*>(p.data()), p.size());
  return s;
}

// Decoded fields equal protobuf's parse of the same bytes.
void expectSameAsProtobuf(const RawResult& r, const v1::ResultMessage& m) {
  if (m.has_header()) {
    ASSERT_EQ(r.kind, RawResult::Kind::kHeader);
    EXPECT_EQ(r.header.SerializeAsString(), m.header().SerializeAsString());
  } else if (m.has_chunk()) {
    ASSERT_EQ(r.kind, RawResult::Kind::kChunk);
    EXPECT_EQ(r.payload, int(m.chunk().payload()));
    EXPECT_EQ(r.offset, m.chunk().offset());
    EXPECT_EQ(r.tile, m.chunk().tile());
    EXPECT_EQ(dataOf(r), m.chunk().data());
    EXPECT_EQ(r.dataSize(), m.chunk().data().size());
  } else {
    EXPECT_EQ(r.kind, RawResult::Kind::kNone);
  }
}

v1::ResultMessage chunkMessage(std::size_t size, std::uint32_t seed) {
  v1::ResultMessage m;
  auto* c = m.mutable_chunk();
  c->set_payload(v1::PAYLOAD_LIGHTMAP_SH);
  c->set_offset(1u << 20);
  c->set_tile(300);
  std::string data(size, '\0');
  std::mt19937 rng(seed);
  for (auto& ch : data) ch = char(rng() & 0xff);
  c->set_data(data);
  return m;
}

v1::ResultMessage headerMessage() {
  v1::ResultMessage m;
  auto* h = m.mutable_header();
  h->mutable_scene()->set_scene_id("scene-\xc3\xa9");
  h->set_version(123456789012345ull);
  h->set_bands(3);
  h->mutable_lightmap()->set_width(128);
  h->mutable_lightmap()->set_height(64);
  h->add_changed_tiles(7);
  h->add_changed_tiles(9);
  h->set_payload_bytes(999);
  h->set_relight_ms(4.5);
  return m;
}

TEST(ClientRawResult, EverySliceSplitDecodesLikeProtobuf) {
  for (const v1::ResultMessage& m : {headerMessage(), chunkMessage(40, 1)}) {
    const std::string bytes = m.SerializeAsString();
    RawResult r;
    for (std::size_t a = 0; a <= bytes.size(); ++a)
      for (std::size_t b = a; b <= bytes.size(); b += 3) {
        ASSERT_TRUE(decodeRawResult(sliced(bytes, {a, b}), r)) << "cuts " << a << ", " << b;
        expectSameAsProtobuf(r, m);
      }
  }
}

TEST(ClientRawResult, LargeChunkDataStaysInTheReceivedSlices) {
  const v1::ResultMessage m = chunkMessage(1 << 20, 2);
  const std::string bytes = m.SerializeAsString();
  const grpc::ByteBuffer buffer = sliced(bytes, {5000, 300000, 700000});
  RawResult r;
  ASSERT_TRUE(decodeRawResult(buffer, r));
  expectSameAsProtobuf(r, m);
  EXPECT_EQ(r.data.size(), 4u);  // one piece per slice the data crosses: no gathering copy
}

TEST(ClientRawResult, UnknownFieldsAreSkippedAndLastValuesWin) {
  // A chunk with fields this client does not know (every wire type) and repeated scalars,
  // then an unknown top-level field: what a newer daemon might send.
  v1::ResultMessage m = chunkMessage(10, 3);
  std::string chunk = m.chunk().SerializeAsString();
  chunk += std::string("\x28\x96\x01", 3);                   // field 5, varint 150
  chunk += std::string("\x31", 1) + std::string(8, '\x11');  // field 6, fixed64
  chunk += std::string("\x3d", 1) + std::string(4, '\x22');  // field 7, fixed32
  chunk += std::string("\x42\x03xyz", 5);                    // field 8, 3 bytes
  chunk += std::string("\x10\x05", 2);                       // offset again: 5 wins
  std::string bytes = std::string("\x12", 1);                // field 2 (chunk), LEN
  bytes += char(chunk.size());
  ASSERT_LT(chunk.size(), 128u);
  bytes += chunk;
  bytes += std::string("\x18\x01", 2);  // top-level field 3, varint
  v1::ResultMessage parsed;
  ASSERT_TRUE(parsed.ParseFromString(bytes));
  EXPECT_EQ(parsed.chunk().offset(), 5u);
  RawResult r;
  ASSERT_TRUE(decodeRawResult(sliced(bytes, {7}), r));
  expectSameAsProtobuf(r, parsed);
}

TEST(ClientRawResult, TruncatedAndCorruptedMessagesAreRefusedOrMatchProtobuf) {
  const std::string full = chunkMessage(64, 4).SerializeAsString();
  RawResult r;
  // Every prefix: whatever the decoder accepts, protobuf accepts with the same fields. A
  // prefix that cuts through a field is refused.
  std::size_t refused = 0;
  for (std::size_t n = 0; n < full.size(); ++n) {
    const std::string prefix = full.substr(0, n);
    const Status s = decodeRawResult(sliced(prefix, {n / 2}), r);
    v1::ResultMessage m;
    const bool pb = m.ParseFromString(prefix);
    if (s) {
      ASSERT_TRUE(pb) << "prefix " << n;
      expectSameAsProtobuf(r, m);
    } else {
      ++refused;
      EXPECT_FALSE(pb) << "prefix " << n << ": " << s.message();
    }
  }
  EXPECT_GT(refused, full.size() / 2);
  // Random byte corruption, many times.
  std::mt19937 rng(5);
  std::size_t accepted = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::string bad = full;
    for (int k = 0; k < 1 + int(rng() % 3); ++k) bad[rng() % bad.size()] = char(rng() & 0xff);
    v1::ResultMessage m;
    const bool pb = m.ParseFromString(bad);
    if (decodeRawResult(sliced(bad, {rng() % bad.size()}), r)) {
      ++accepted;
      ASSERT_TRUE(pb) << "trial " << trial;
      expectSameAsProtobuf(r, m);
    }
  }
  EXPECT_GT(accepted, 0u);  // most corruptions only change values, which is still a message
}

TEST(ClientRawResult, AssemblerTakesRawMessagesLikeParsedOnes) {
  // A 2x2 lightmap, 1 band, half: 2 * 3 * 4 = 24 bytes of SH and 4 validity bytes.
  v1::ResultMessage h;
  h.mutable_header()->set_version(3);
  h.mutable_header()->set_bands(1);
  h.mutable_header()->mutable_lightmap()->set_width(2);
  h.mutable_header()->mutable_lightmap()->set_height(2);
  h.mutable_header()->set_payload_bytes(28);
  v1::ResultMessage sh;
  sh.mutable_chunk()->set_payload(v1::PAYLOAD_LIGHTMAP_SH);
  sh.mutable_chunk()->set_data(std::string(24, '\x3c'));
  v1::ResultMessage valid;
  valid.mutable_chunk()->set_payload(v1::PAYLOAD_LIGHTMAP_VALID);
  valid.mutable_chunk()->set_data(std::string(4, '\x01'));
  ResultAssembler raw, parsed;
  RawResult r;
  for (const auto* m : {&h, &sh, &valid}) {
    const std::string bytes = m->SerializeAsString();
    ASSERT_TRUE(decodeRawResult(sliced(bytes, {bytes.size() / 2}), r));
    ASSERT_TRUE(raw.add(r));
    ASSERT_TRUE(parsed.add(*m));
  }
  auto a = raw.take();
  auto b = parsed.take();
  ASSERT_TRUE(a) << a.status().toString();
  ASSERT_TRUE(b);
  EXPECT_EQ(a->payloads, b->payloads);
  EXPECT_EQ(a->info.version, 3u);
  // An empty message is neither header nor chunk.
  ASSERT_TRUE(decodeRawResult(sliced(std::string(), {}), r));
  EXPECT_FALSE(raw.add(r));
}

}  // namespace
}  // namespace lightlink::client
