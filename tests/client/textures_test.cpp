// Result assembly (chunks -> payloads), half decoding and tile deltas, without a daemon:
// the messages are built here the way proto/lightlink.proto lays them out.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "clients/client/textures.h"
#include "core/common/half.h"
#include "proto/lightlink.pb.h"

namespace lightlink::client {
namespace {

// A header for a w x h lightmap with `bands` bands, half precision, no grid.
v1::ResultMessage header(std::uint64_t version, int w, int h, int bands, std::uint64_t payload_bytes,
                         bool delta = false, int tile = 4) {
  v1::ResultMessage m;
  auto* hd = m.mutable_header();
  hd->set_version(version);
  hd->set_bands(bands);
  hd->set_precision(v1::PRECISION_HALF);
  hd->mutable_lightmap()->set_width(w);
  hd->mutable_lightmap()->set_height(h);
  hd->mutable_lightmap()->set_tile_size(tile);
  hd->set_payload_bytes(payload_bytes);
  hd->set_delta(delta);
  return m;
}

v1::ResultMessage chunk(v1::Payload p, std::uint64_t offset, const std::vector<std::uint8_t>& data,
                        std::uint32_t tile = 0) {
  v1::ResultMessage m;
  auto* c = m.mutable_chunk();
  c->set_payload(p);
  c->set_offset(offset);
  c->set_tile(tile);
  c->set_data(std::string(data.begin(), data.end()));
  return m;
}

std::vector<std::uint8_t> halves(const std::vector<float>& v) {
  std::vector<std::uint8_t> b(v.size() * 2);
  for (std::size_t i = 0; i < v.size(); ++i) {
    const half_bits h = toHalf(v[i]);
    b[2 * i] = std::uint8_t(h & 0xff);
    b[2 * i + 1] = std::uint8_t(h >> 8);
  }
  return b;
}

TEST(ClientHalfDecode, ExactValuesLittleEndian) {
  // 1.0 = 0x3C00, -2.0 = 0xC000, 65504 = 0x7BFF, smallest subnormal 0x0001 = 2^-24,
  // +inf = 0x7C00, NaN = 0x7E00, -0 = 0x8000.
  const std::vector<std::uint8_t> bytes = {0x00, 0x3C, 0x00, 0xC0, 0xFF, 0x7B, 0x01, 0x00,
                                           0x00, 0x7C, 0x00, 0x7E, 0x00, 0x80};
  std::vector<float> out;
  decodeHalf(bytes, out);
  ASSERT_EQ(out.size(), 7u);
  EXPECT_EQ(out[0], 1.0f);
  EXPECT_EQ(out[1], -2.0f);
  EXPECT_EQ(out[2], 65504.0f);
  EXPECT_EQ(out[3], std::ldexp(1.0f, -24));
  EXPECT_TRUE(std::isinf(out[4]) && out[4] > 0);
  EXPECT_TRUE(std::isnan(out[5]));
  EXPECT_TRUE(out[6] == 0.0f && std::signbit(out[6]));
}

TEST(ClientHalfDecode, EveryHalfRoundTrips) {
  // Every finite half decodes to a float that encodes back to the same bits.
  std::vector<std::uint8_t> bytes(65536 * 2);
  for (std::uint32_t h = 0; h < 65536; ++h) {
    bytes[2 * h] = std::uint8_t(h & 0xff);
    bytes[2 * h + 1] = std::uint8_t(h >> 8);
  }
  std::vector<float> out;
  decodeHalf(bytes, out);
  ASSERT_EQ(out.size(), 65536u);
  for (std::uint32_t h = 0; h < 65536; ++h) {
    if ((h & 0x7C00) == 0x7C00) continue;  // inf / NaN
    ASSERT_EQ(toHalf(out[h]), half_bits(h)) << "half 0x" << std::hex << h << " decoded to " << out[h];
  }
}

TEST(ClientFloatDecode, LittleEndian) {
  const float v[3] = {1.5f, -0.0f, 3.0e38f};
  std::vector<std::uint8_t> bytes(12);
  std::memcpy(bytes.data(), v, 12);  // the test host is little-endian (x86, arm64)
  std::vector<float> out;
  decodeFloat(bytes, out);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0], 1.5f);
  EXPECT_TRUE(std::signbit(out[1]));
  EXPECT_EQ(out[2], 3.0e38f);
}

// A 5 x 3 lightmap, 1 band: SH payload = 15 texels * 3 values * 2 bytes = 90 bytes, validity
// 15 bytes. Sent in uneven chunks.
TEST(ClientResultAssembler, FullResultFromChunks) {
  std::vector<float> sh(45);
  for (std::size_t i = 0; i < sh.size(); ++i) sh[i] = 0.25f * float(i);
  const auto sh_bytes = halves(sh);
  std::vector<std::uint8_t> valid(15, 1);
  valid[7] = 0;
  ResultAssembler a;
  ASSERT_TRUE(a.add(header(7, 5, 3, 1, 90 + 15)));
  EXPECT_FALSE(a.complete());
  ASSERT_TRUE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 0, {sh_bytes.begin(), sh_bytes.begin() + 33})));
  ASSERT_TRUE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 33, {sh_bytes.begin() + 33, sh_bytes.end()})));
  ASSERT_TRUE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_VALID, 0, valid)));
  ASSERT_TRUE(a.complete());
  auto t = a.take();
  ASSERT_TRUE(t) << t.status().toString();
  EXPECT_EQ(t->info.version, 7u);
  EXPECT_EQ(t->floats(Payload::kLightmapSh), sh);
  EXPECT_EQ(t->floats(Payload::kLightmapValid)[7], 0.0f);
  EXPECT_FALSE(t->has(Payload::kLightmapDirect));
}

TEST(ClientResultAssembler, RejectsTornAndInconsistentStreams) {
  const auto sh_bytes = halves(std::vector<float>(45, 1.0f));
  {
    ResultAssembler a;  // chunk before header
    EXPECT_FALSE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 0, sh_bytes)));
  }
  {
    ResultAssembler a;  // out-of-order offset
    ASSERT_TRUE(a.add(header(1, 5, 3, 1, 90)));
    const Status s = a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 10, sh_bytes));
    EXPECT_FALSE(s);
    EXPECT_NE(s.message().find("chunk.offset"), std::string::npos) << s.message();
  }
  {
    ResultAssembler a;  // stream ends early: take() refuses a partial result
    ASSERT_TRUE(a.add(header(1, 5, 3, 1, 90)));
    ASSERT_TRUE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 0, {sh_bytes.begin(), sh_bytes.begin() + 40})));
    auto t = a.take();
    ASSERT_FALSE(t);
    EXPECT_NE(t.status().message().find("40 of 90"), std::string::npos) << t.status().message();
  }
  {
    ResultAssembler a;  // more bytes than the header announced
    ASSERT_TRUE(a.add(header(1, 5, 3, 1, 20)));
    EXPECT_FALSE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 0, sh_bytes)));
  }
  {
    ResultAssembler a;  // a grid payload without a grid in the header
    ASSERT_TRUE(a.add(header(1, 5, 3, 1, 90)));
    const Status s = a.add(chunk(v1::PAYLOAD_GRID_SH, 0, sh_bytes));
    EXPECT_FALSE(s);
    EXPECT_NE(s.message().find("no grid"), std::string::npos) << s.message();
  }
  {
    ResultAssembler a;  // payload larger than width x height implies
    ASSERT_TRUE(a.add(header(1, 5, 3, 1, 92)));
    auto big = sh_bytes;
    big.push_back(0);
    big.push_back(0);
    EXPECT_FALSE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 0, big)));
  }
}

TEST(ClientResultAssembler, NotModifiedIsJustAHeader) {
  ResultAssembler a;
  auto h = header(9, 0, 0, 0, 0);
  h.mutable_header()->set_not_modified(true);
  ASSERT_TRUE(a.add(h));
  ASSERT_TRUE(a.complete());
  auto t = a.take();
  ASSERT_TRUE(t);
  EXPECT_TRUE(t->info.not_modified);
  EXPECT_EQ(t->totalBytes(), 0u);
}

TEST(ClientResultInfo, KindSaysWhetherTheResultIsTheInstantPreview) {
  v1::ResultHeader h;
  EXPECT_EQ(ResultInfo::fromProto(h).kind, ResultKind::kLinked) << "unset (an older daemon): linked";
  h.set_kind(v1::RESULT_KIND_INSTANT_PREVIEW);
  h.set_preview(true);
  const ResultInfo info = ResultInfo::fromProto(h);
  EXPECT_EQ(info.kind, ResultKind::kInstantPreview);
  EXPECT_TRUE(info.preview);
  h.set_kind(v1::RESULT_KIND_LINKED);
  EXPECT_EQ(ResultInfo::fromProto(h).kind, ResultKind::kLinked);
}

TEST(ClientTileRect, EdgeTilesAreClipped) {
  ResultInfo info;
  info.width = 10;
  info.height = 7;
  info.tile_size = 4;
  EXPECT_EQ(info.tilesX(), 3);
  EXPECT_EQ(info.tilesY(), 2);
  const TileRect r = tileRect(info, 5);  // tx 2, ty 1
  EXPECT_EQ(r.x0, 8);
  EXPECT_EQ(r.y0, 4);
  EXPECT_EQ(r.w, 2);
  EXPECT_EQ(r.h, 3);
}

// A 10 x 7 lightmap in 4 x 4 tiles (3 x 2 tiles, edges clipped). The base holds the texel
// index in every value; a delta changes tiles 1 and 5 (an interior-edge and a corner tile).
// After applying, changed texels hold the new values and every other texel is untouched.
TEST(ClientResultAssembler, DeltaTilesApplyToThePreviousResult) {
  const int w = 10, h = 7, bands = 1, nc = 1;
  const std::size_t per_texel = 3 * nc;
  std::vector<float> base_sh(std::size_t(w) * h * per_texel);
  for (std::size_t i = 0; i < base_sh.size(); ++i) base_sh[i] = float(i / per_texel);
  const auto base_bytes = halves(base_sh);
  std::vector<std::uint8_t> valid(std::size_t(w) * h, 1);
  ResultAssembler a;
  ASSERT_TRUE(a.add(header(1, w, h, bands, base_bytes.size() + valid.size(), false)));
  ASSERT_TRUE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 0, base_bytes)));
  ASSERT_TRUE(a.add(chunk(v1::PAYLOAD_LIGHTMAP_VALID, 0, valid)));
  auto base = a.take();
  ASSERT_TRUE(base) << base.status().toString();

  ResultInfo geom = base->info;
  std::vector<std::uint32_t> tiles = {1, 5};
  std::vector<v1::ResultMessage> msgs;
  std::uint64_t bytes = 0;
  for (std::uint32_t tile : tiles) {
    const TileRect r = tileRect(geom, tile);
    std::vector<float> v(std::size_t(r.w) * r.h * per_texel, 1000.0f + float(tile));
    auto hb = halves(v);
    // Split each tile's SH in two chunks to exercise in-tile offsets.
    const std::size_t half = hb.size() / 2;
    msgs.push_back(chunk(v1::PAYLOAD_LIGHTMAP_SH, 0, {hb.begin(), hb.begin() + half}, tile));
    msgs.push_back(chunk(v1::PAYLOAD_LIGHTMAP_SH, half, {hb.begin() + half, hb.end()}, tile));
    msgs.push_back(chunk(v1::PAYLOAD_LIGHTMAP_VALID, 0, std::vector<std::uint8_t>(std::size_t(r.w) * r.h, 0), tile));
    bytes += hb.size() + std::size_t(r.w) * r.h;
  }
  auto hd = header(2, w, h, bands, bytes, true);
  for (auto t : tiles) hd.mutable_header()->add_changed_tiles(t);
  ASSERT_TRUE(a.add(hd));
  for (const auto& m : msgs) ASSERT_TRUE(a.add(m));
  ASSERT_TRUE(a.complete());
  Textures prev = std::move(base).value();
  auto next = a.take(&prev);
  ASSERT_TRUE(next) << next.status().toString();
  EXPECT_EQ(next->info.version, 2u);
  const auto sh = next->floats(Payload::kLightmapSh);
  const auto vd = next->floats(Payload::kLightmapValid);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::uint32_t tile = std::uint32_t((y / 4) * 3 + x / 4);
      const bool changed = tile == 1 || tile == 5;
      const std::size_t t = std::size_t(y) * w + x;
      const float expect = changed ? 1000.0f + float(tile) : float(t);
      ASSERT_EQ(sh[t * per_texel], expect) << "texel (" << x << "," << y << ")";
      ASSERT_EQ(vd[t], changed ? 0.0f : 1.0f) << "texel (" << x << "," << y << ")";
    }
  }
}

TEST(ClientResultAssembler, DeltaNeedsAMatchingBase) {
  ResultAssembler a;
  auto hd = header(3, 10, 7, 1, 0, true);
  ASSERT_TRUE(a.add(hd));
  auto t = a.take(nullptr);
  ASSERT_FALSE(t);
  EXPECT_NE(t.status().message().find("without a previous full result"), std::string::npos);

  Textures other;
  other.info.width = 8;
  other.info.height = 7;
  other.info.bands = 1;
  other.info.tile_size = 4;
  ASSERT_TRUE(a.add(hd));
  auto u = a.take(&other);
  ASSERT_FALSE(u);
  EXPECT_NE(u.status().message().find("does not match"), std::string::npos) << u.status().message();
}

TEST(ClientResultAssembler, DeltaRejectsTilesOutsideTheHeaderList) {
  ResultAssembler a;
  auto hd = header(3, 10, 7, 1, 6, true);
  hd.mutable_header()->add_changed_tiles(0);
  ASSERT_TRUE(a.add(hd));
  const Status s = a.add(chunk(v1::PAYLOAD_LIGHTMAP_SH, 0, std::vector<std::uint8_t>(6), 4));
  EXPECT_FALSE(s);
  EXPECT_NE(s.message().find("chunk.tile"), std::string::npos) << s.message();
}

TEST(ClientApplyTile, WrongSizeIsAnError) {
  ResultInfo info;
  info.width = 10;
  info.height = 7;
  info.tile_size = 4;
  std::vector<std::uint8_t> image(70);
  EXPECT_TRUE(applyTile(info, 5, 1, std::vector<std::uint8_t>(6), image));
  EXPECT_FALSE(applyTile(info, 5, 1, std::vector<std::uint8_t>(7), image));
  EXPECT_FALSE(applyTile(info, 6, 1, std::vector<std::uint8_t>(6), image));  // no tile 6
}

}  // namespace
}  // namespace lightlink::client
