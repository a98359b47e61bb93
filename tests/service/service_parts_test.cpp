// The daemon's parts in process: address classification, tokens, request validation,
// payload encoding and tile deltas.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "service/auth.h"
#include "service/config.h"
#include "service/result_stream.h"
#include "service/snapshot.h"
#include "service/validation.h"
#include "tests/service/test_snapshots.h"

namespace lightlink::service {
namespace {

TEST(ServiceAuth, LoopbackClassification) {
  EXPECT_TRUE(isLoopbackListen("127.0.0.1:50051"));
  EXPECT_TRUE(isLoopbackListen("127.3.2.1:0"));
  EXPECT_TRUE(isLoopbackListen("localhost:1"));
  EXPECT_TRUE(isLoopbackListen("[::1]:50051"));
  EXPECT_FALSE(isLoopbackListen("0.0.0.0:50051"));
  EXPECT_FALSE(isLoopbackListen("[::]:50051"));
  EXPECT_FALSE(isLoopbackListen("10.0.0.5:50051"));
  EXPECT_FALSE(isLoopbackListen("example.com:443"));
}

// Who may ask for shared-memory delivery (service/shared_results.h): callers on this machine.
TEST(ServiceAuth, LocalPeerClassification) {
  EXPECT_TRUE(isLocalPeer("ipv4:127.0.0.1:50412"));
  EXPECT_TRUE(isLocalPeer("ipv4:127.3.4.5:1"));
  EXPECT_TRUE(isLocalPeer("ipv6:[::1]:50412"));
  EXPECT_TRUE(isLocalPeer("ipv6:[::ffff:127.0.0.1]:9"));
  EXPECT_TRUE(isLocalPeer("unix:/run/lightlinkd.sock"));
  EXPECT_FALSE(isLocalPeer("ipv4:10.0.0.7:50412"));
  EXPECT_FALSE(isLocalPeer("ipv4:128.0.0.1:1"));
  EXPECT_FALSE(isLocalPeer("ipv6:[2001:db8::1]:50412"));
  EXPECT_FALSE(isLocalPeer("ipv6:[::2]:1"));
  EXPECT_FALSE(isLocalPeer(""));
}

TEST(ServiceAuth, BearerAndTokens) {
  EXPECT_TRUE(checkBearer("", false, "").empty()) << "no token configured: everyone passes";
  EXPECT_FALSE(checkBearer("", false, "abc").empty());
  EXPECT_FALSE(checkBearer("Bearer abd", true, "abc").empty());
  EXPECT_FALSE(checkBearer("abc", true, "abc").empty());
  EXPECT_TRUE(checkBearer("Bearer abc", true, "abc").empty());
  const std::string a = randomToken(), b = randomToken();
  EXPECT_EQ(a.size(), 32u);
  EXPECT_NE(a, b);
  EXPECT_TRUE(constantTimeEqual(a, a));
  EXPECT_FALSE(constantTimeEqual(a, b));
  EXPECT_FALSE(constantTimeEqual(a, a.substr(1)));
}

TEST(ServiceConfig, ExposedWithoutTokenIsRefused) {
  DaemonConfig c;
  c.cache_dir = "/tmp/x";
  EXPECT_TRUE(c.validate());
  c.listen = "0.0.0.0:50051";
  EXPECT_FALSE(c.validate());
  c.token = "0123456789abcdef";
  c.allow_plaintext_token = true;
  EXPECT_TRUE(c.validate());
  c.tls_cert = "cert.pem";
  EXPECT_FALSE(c.validate()) << "a certificate without its key";
}

TEST(ServiceValidation, UpdateErrorsNameTheField) {
  relight::LightSet lights;
  v1::UpdateLightsRequest r;
  auto* l = r.add_add();
  l->set_id("a");
  l->set_type(v1::LIGHT_TYPE_POINT);
  l->set_intensity(1.0f);
  auto* bad = r.add_add();
  bad->set_id("b");
  bad->set_type(v1::LIGHT_TYPE_SPOT);
  bad->mutable_direction();  // zero vector
  Status s = applyUpdate(r, 4, lights);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("add[1].direction"), std::string::npos) << s.message();

  r.clear_add();
  auto* nan_color = r.add_add();
  nan_color->set_id("c");
  nan_color->set_type(v1::LIGHT_TYPE_POINT);
  nan_color->mutable_color()->set_y(std::nanf(""));
  s = applyUpdate(r, 4, lights);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("add[0].color[1]"), std::string::npos) << s.message();

  // The wire follows the light-set file's rules (core's LightPatch): a cone angle beyond
  // pi/2 is refused on a point light too, as lights.json and the client library refuse it.
  r.clear_add();
  auto* cone = r.add_add();
  cone->set_id("d");
  cone->set_type(v1::LIGHT_TYPE_POINT);
  cone->set_outer_cone_angle(2.0f);
  s = applyUpdate(r, 4, lights);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("add[0].outer_cone_angle: 2 is outside [0, pi/2]"), std::string::npos) << s.message();

  r.clear_add();
  auto* e = r.add_emissive();
  e->set_material(9);
  e->mutable_scale()->set_x(1.0f);
  s = applyUpdate(r, 4, lights);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("emissive[0].material"), std::string::npos) << s.message();

  // Non-finite emission and sky values are refused by core's light-set rules, named as a
  // light-set file's would be.
  e->set_material(1);
  e->mutable_scale()->set_y(std::numeric_limits<float>::infinity());
  s = applyUpdate(r, 4, lights);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("emissive[0].scale[1]"), std::string::npos) << s.message();

  r.clear_emissive();
  r.mutable_sky()->add_sh();
  s = applyUpdate(r, 4, lights);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("sky.sh"), std::string::npos) << s.message();

  r.clear_sky();
  r.mutable_sky()->mutable_radiance()->set_z(std::nanf(""));
  s = applyUpdate(r, 4, lights);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("sky.radiance[2]"), std::string::npos) << s.message();

  r.clear_sky();
  for (int i = 0; i < 9; ++i) r.mutable_sky()->add_sh();
  r.mutable_sky()->mutable_sh(4)->set_x(-std::numeric_limits<float>::infinity());
  s = applyUpdate(r, 4, lights);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("sky.sh[4][0]"), std::string::npos) << s.message();
}

TEST(ServiceValidation, ModifyChangesOnlyPresentFieldsAndReplaceLights) {
  relight::LightSet lights;
  v1::UpdateLightsRequest add;
  auto* l = add.add_add();
  l->set_id("a");
  l->set_type(v1::LIGHT_TYPE_POINT);
  l->set_intensity(2.0f);
  l->mutable_position()->set_x(1.0f);
  ASSERT_TRUE(applyUpdate(add, 0, lights));
  v1::UpdateLightsRequest mod;
  auto* m = mod.add_modify();
  m->set_id("a");
  m->set_intensity(5.0f);
  ASSERT_TRUE(applyUpdate(mod, 0, lights));
  ASSERT_NE(lights.find("a"), nullptr);
  EXPECT_EQ(lights.find("a")->light.intensity, 5.0f);
  EXPECT_EQ(lights.find("a")->light.position.x, 1.0f) << "modify must keep absent fields";

  v1::UpdateLightsRequest replace;
  replace.set_replace_lights(true);
  auto* n = replace.add_add();
  n->set_id("b");
  n->set_type(v1::LIGHT_TYPE_DIRECTIONAL);
  n->mutable_direction()->set_z(-2.0f);
  ASSERT_TRUE(applyUpdate(replace, 0, lights));
  ASSERT_EQ(lights.lights().size(), 1u);
  EXPECT_EQ(lights.lights()[0].id, "b");
  EXPECT_FLOAT_EQ(lights.lights()[0].light.direction.z, -1.0f) << "directions are normalised";
}

TEST(ServiceValidation, OpenParameters) {
  v1::OpenSceneRequest r;
  r.set_preset("draft");
  r.set_rays(8);
  auto o = precomputeOptionsFrom(r);
  ASSERT_FALSE(o);
  EXPECT_NE(o.status().message().find("rays"), std::string::npos);
  r.set_rays(64);
  r.set_hierarchy("fast");
  r.set_bands(2);
  o = precomputeOptionsFrom(r);
  ASSERT_TRUE(o) << o.status().message();
  EXPECT_EQ(o->rays, 64);
  EXPECT_EQ(o->bands, 2);
  EXPECT_EQ(o->builder, hierarchy::Builder::kKdMedian);
  r.set_preset("ultra");
  EXPECT_FALSE(precomputeOptionsFrom(r));
}

using testing::fillSnapshot;

TEST(ServicePayload, BandPrefixAndPrecision) {
  Snapshot s;
  fillSnapshot(s, 0.5f);
  v1::ResultSpec spec;
  spec.set_bands(1);
  spec.set_precision(v1::PRECISION_FLOAT);
  spec.set_component(v1::COMPONENT_INDIRECT);
  const auto e = s.encoded(SpecKey::from(spec, 2));
  ASSERT_EQ(e->payloads.size(), 2u);  // SH + valid
  ASSERT_EQ(e->payloads[0].kind, v1::PAYLOAD_LIGHTMAP_SH);
  ASSERT_EQ(e->payloads[0].bytes.size(), 70u * 40 * 3 * 4);
  const float* v = reinterpret_cast<const float*>(e->payloads[0].bytes.data());
  // Texel 5, channel G, coefficient 0 is element (5 * 3 + 1) * 4 of the 2-band block.
  EXPECT_EQ(v[5 * 3 + 1], s.lightmap_sh[(5 * 3 + 1) * 4]);
  EXPECT_EQ(s.encoded(SpecKey::from(spec, 2)), e) << "encoded once per spec, then shared";
}

TEST(ServicePayload, DeltaCarriesOnlyChangedTilesAndReassembles) {
  Snapshot a, b;
  fillSnapshot(a, 0.5f);
  fillSnapshot(b, 0.5f);
  b.version = 2;
  // Change one texel in tile (2, 1): x 64..69, y 32..39.
  b.lightmap_sh[(35 * 70 + 66) * 12 + 3] = 9.0f;
  const SpecKey key = SpecKey::from(v1::ResultSpec{}, 2);
  const auto ea = a.encoded(key), eb = b.encoded(key);
  const auto tiles = changedTiles(*eb, *ea, 70, 40, 32);
  ASSERT_EQ(tiles, std::vector<std::uint32_t>{5});

  std::vector<v1::ResultMessage> sent;
  ASSERT_TRUE(sendDelta(b, *eb, *ea, {"s", 0}, 4096, [&](const v1::ResultMessage& m) {
    sent.push_back(m);
    return true;
  }));
  ASSERT_FALSE(sent.empty());
  ASSERT_TRUE(sent[0].has_header());
  EXPECT_TRUE(sent[0].header().delta());
  // Applying the tiles to a's bytes gives b's bytes.
  std::map<int, std::string> bytes;
  for (const auto& p : ea->payloads) bytes[p.kind] = p.bytes;
  std::uint64_t total = 0;
  for (std::size_t i = 1; i < sent.size(); ++i) {
    const auto& c = sent[i].chunk();
    ASSERT_EQ(c.tile(), 5u);
    total += c.data().size();
    const auto& p = *std::find_if(eb->payloads.begin(), eb->payloads.end(), [&](auto& q) { return q.kind == c.payload(); });
    const std::size_t row = 6 * p.bytes_per_element;  // tile 5 is 6 texels wide
    for (std::size_t k = 0; k < c.data().size(); ++k) {
      const std::size_t at = c.offset() + k, y = 32 + at / row, xb = at % row;
      bytes[c.payload()][(y * 70 + 64) * p.bytes_per_element + xb] = c.data()[k];
    }
  }
  EXPECT_EQ(total, sent[0].header().payload_bytes());
  for (const auto& p : eb->payloads) EXPECT_EQ(bytes[p.kind], p.bytes) << "payload " << p.kind;
}

TEST(ServicePayload, FullResultChunksCoverEachPayloadInOrder) {
  Snapshot s;
  fillSnapshot(s, 1.0f);
  const auto e = s.encoded(SpecKey::from(v1::ResultSpec{}, 2));
  std::map<int, std::string> got;
  std::uint64_t declared = 0;
  ASSERT_TRUE(sendFull(s, *e, {"s", 0}, 4096, [&](const v1::ResultMessage& m) {
    if (m.has_header()) {
      declared = m.header().payload_bytes();
      return true;
    }
    EXPECT_LE(m.chunk().data().size(), 4096u);
    EXPECT_EQ(m.chunk().offset(), got[m.chunk().payload()].size());
    got[m.chunk().payload()] += m.chunk().data();
    return true;
  }));
  std::uint64_t total = 0;
  for (const auto& p : e->payloads) {
    EXPECT_EQ(got[p.kind], p.bytes);
    total += p.bytes.size();
  }
  EXPECT_EQ(total, declared);
}

TEST(ServicePayload, WireFormIsSerializedOnceAndIsWhatSendFullSends) {
  Snapshot s;
  fillSnapshot(s, 1.0f);
  s.scene_id = "scene-a";
  const SpecKey key = SpecKey::from(v1::ResultSpec{}, 2);
  std::vector<std::string> sent;
  ASSERT_TRUE(sendFull(s, *s.encoded(key), {"scene-a", 0}, 4096, [&](const v1::ResultMessage& m) {
    sent.push_back(m.SerializeAsString());
    return true;
  }));
  const auto w = s.wire(key, 4096);
  ASSERT_TRUE(w);
  ASSERT_EQ(w->messages.size(), sent.size());
  std::uint64_t bytes = 0;
  for (std::size_t i = 0; i < sent.size(); ++i) {
    grpc::Slice one;
    ASSERT_TRUE(w->messages[i].DumpToSingleSlice(&one).ok());
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(one.begin()), one.size()), sent[i]) << "message " << i;
    bytes += one.size();
  }
  EXPECT_EQ(w->bytes, bytes);
  EXPECT_EQ(s.wire(key, 4096), w) << "serialized once per (spec, chunk size), then shared";
  EXPECT_NE(s.wire(key, 8192), w) << "another chunk size is another wire form";

  // A subscriber's delta against the previous result: the bytes sendDelta produces, shared
  // by every stream with the same previous result; a stream that skipped versions gets its
  // own header.
  Snapshot next;
  fillSnapshot(next, 1.0f);
  next.scene_id = "scene-a";
  next.version = 2;
  next.sequence = 2;
  next.lightmap_sh[(35 * 70 + 66) * 12 + 3] = 9.0f;
  s.sequence = 1;
  std::vector<std::string> delta;
  ASSERT_TRUE(sendDelta(next, *next.encoded(key), *s.encoded(key), {"scene-a", 0}, 4096, [&](const v1::ResultMessage& m) {
    delta.push_back(m.SerializeAsString());
    return true;
  }));
  const auto d = next.wire(key, 4096, &s, /*delta=*/true);
  ASSERT_TRUE(d);
  ASSERT_EQ(d->messages.size(), delta.size());
  for (std::size_t i = 0; i < delta.size(); ++i) {
    grpc::Slice one;
    ASSERT_TRUE(d->messages[i].DumpToSingleSlice(&one).ok());
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(one.begin()), one.size()), delta[i]) << "message " << i;
  }
  EXPECT_LT(d->bytes, next.wire(key, 4096)->bytes / 4) << "one changed tile of 6";
  EXPECT_EQ(next.wire(key, 4096, &s, true), d);
  // A stream whose last result was older skipped versions: its header says so.
  next.sequence = 4;
  const auto behind = next.wire(key, 4096, &s, false);
  ASSERT_TRUE(behind);
  v1::ResultMessage header;
  grpc::Slice first;
  ASSERT_TRUE(behind->messages.front().DumpToSingleSlice(&first).ok());
  ASSERT_TRUE(header.ParseFromArray(first.begin(), static_cast<int>(first.size())));
  EXPECT_EQ(header.header().skipped_versions(), 2u);
  EXPECT_FALSE(header.header().delta());
}

}  // namespace
}  // namespace lightlink::service
