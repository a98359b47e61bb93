// Replays every committed fuzz input (tests/fuzz/corpus/<target>/ and
// tests/fuzz/regressions/<target>/) through the fuzzers' entry functions in an ordinary
// build: each input must be accepted or rejected with a Status that names the problem, and
// nothing may crash (the sanitizer builds, scripts/test --sanitize and the fuzz build, turn
// an out-of-bounds read here into a failure too). Regressions are inputs the fuzzers once
// crashed on; docs/fuzzing.md lists them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <vector>

#include "core/artifact/artifact.h"
#include "tests/fuzz/fuzz_inputs.h"
#ifdef LIGHTLINK_FUZZ_SERVICE
#include "tests/fuzz/fuzz_service_inputs.h"
#endif

namespace lightlink::fuzz {
namespace {

namespace fs = std::filesystem;

std::vector<std::uint8_t> readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Committed inputs of one target: the seeds (corpus/, valid files that reach deep into the
// loader) or the regressions (inputs that once crashed it).
std::vector<fs::path> inputs(const char* kind, const char* target) {
  std::vector<fs::path> out;
  const fs::path dir = fs::path(LIGHTLINK_FUZZ_DIR) / kind / target;
  if (fs::is_directory(dir))
    for (const auto& entry : fs::directory_iterator(dir))
      if (entry.is_regular_file()) out.push_back(entry.path());
  std::sort(out.begin(), out.end());
  return out;
}

// Accepted, or rejected as the caller's fault with a message: a loader must not call bad
// bytes an internal error, nor reject them silently.
void expectClear(const Status& s, const fs::path& input, const char* step) {
  if (s) return;
  EXPECT_NE(s.code(), Code::kInternal) << input << " " << step << ": " << s.toString();
  EXPECT_FALSE(s.message().empty()) << input << " " << step << ": rejected without a message";
}

// The seeds must stay valid: a seed the loader rejects early leaves the fuzzer exploring
// only the rejection.
TEST(FuzzReplay, GltfSeedsLoad) {
  const auto files = inputs("corpus", "gltf");
  ASSERT_FALSE(files.empty()) << "no seeds under " << LIGHTLINK_FUZZ_DIR << "/corpus/gltf";
  for (const fs::path& f : files) {
    const Status s = loadGltfBytes(readBytes(f));
    EXPECT_TRUE(s) << f << ": " << s.toString();
  }
}

// tinygltf converts extras recursively: deep nesting used to overflow the stack (20000
// levels under ASan, regressions/gltf/deep_extras.gltf). It is now refused before parsing.
TEST(FuzzReplay, DeeplyNestedJsonIsRefusedBeforeParsing) {
  const std::string head = R"({"asset":{"version":"2.0"},"extras":)";
  const std::string deep = head + std::string(300, '[') + std::string(300, ']') + "}";
  const Status s = loadGltfBytes(std::span(reinterpret_cast<const std::uint8_t*>(deep.data()), deep.size()));
  EXPECT_EQ(s.code(), Code::kInvalidInput) << s.toString();
  EXPECT_NE(s.message().find("JSON nested deeper than 256 levels"), std::string::npos) << s.toString();
  // Brackets inside strings are text, not nesting.
  const std::string text = head + "\"" + std::string(300, '[') + "\"}";
  const Status t = loadGltfBytes(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
  EXPECT_EQ(t.message().find("nested deeper"), std::string::npos) << t.toString();
}

TEST(FuzzReplay, GltfRegressions) {
  const auto files = inputs("regressions", "gltf");
  ASSERT_FALSE(files.empty());
  for (const fs::path& f : files) expectClear(loadGltfBytes(readBytes(f)), f, "loadGltf");
}

// Each artifact regression once opened and then crashed a consumer (the relight); open()
// now rejects it, checksums repaired or not, so the crash stays unreachable in any build.
TEST(FuzzReplay, ArtifactRegressionsAreRejectedAtOpen) {
  const auto files = inputs("regressions", "artifact");
  ASSERT_FALSE(files.empty());
  for (const fs::path& f : files) {
    const ArtifactVerdict v = openArtifactBytes(readBytes(f));
    expectClear(v.raw, f, "open");
    // Rejected by the format version check only, a regression tests nothing any more: carry
    // its mutation over to the current seed (docs/fuzzing.md, "When the format changes").
    EXPECT_EQ(v.raw.message().find("format version"), std::string::npos) << f << " is stale: " << v.raw.toString();
    if (v.fixed) expectClear(v.after_fix, f, "open after fixChecksums");
    if (v.relit) expectClear(v.relight, f, "relight");
    EXPECT_FALSE(v.relit) << f << " opens again; the open() check that rejected it is gone";
  }
}

// Artifacts the open accepts (their values are in range) whose relight once crashed: each
// must open and relight cleanly. footprint_beyond_float_range.llk: a surfel's shadow-ray
// footprint (from its area) left the float range, and Embree asserted on the ray.
TEST(FuzzReplay, ArtifactRelightRegressions) {
  const auto files = inputs("regressions", "artifact_relit");
  ASSERT_FALSE(files.empty());
  for (const fs::path& f : files) {
    const ArtifactVerdict v = openArtifactBytes(readBytes(f));
    expectClear(v.raw, f, "open");
    if (v.fixed) expectClear(v.after_fix, f, "open after fixChecksums");
    EXPECT_TRUE(v.relit) << f << " no longer opens: it tests nothing here";
    if (v.relit) {
      EXPECT_TRUE(v.relight) << f << ": " << v.relight.toString();
    }
  }
}

fs::path seedPath() { return fs::path(LIGHTLINK_FUZZ_DIR) / "corpus" / "artifact" / "tiny.llk"; }

// A stale seed (format version bumped, a section renamed) would leave the artifact fuzzer
// bouncing off the version check: fail until it is regenerated.
TEST(FuzzReplay, SeedArtifactIsCurrent) {
  const ArtifactVerdict v = openArtifactBytes(readBytes(seedPath()));
  EXPECT_TRUE(v.raw) << v.raw.toString()
                     << "\nregenerate it: fuzz_make_seed " << seedPath().string();
  EXPECT_TRUE(v.relit);
  EXPECT_TRUE(v.relight) << v.relight.toString();
}

// The checksum repair is what lets mutations reach the section parsing: a changed payload
// byte fails the checksum as given and opens once repaired.
TEST(FuzzReplay, ChecksumRepairReachesPastTheChecksums) {
  std::vector<std::uint8_t> bytes = readBytes(seedPath());
  ASSERT_GE(bytes.size(), sizeof(artifact::FileHeader));
  artifact::FileHeader h;
  std::memcpy(&h, bytes.data(), sizeof(h));
  const auto* table = reinterpret_cast<const artifact::SectionEntry*>(bytes.data() + sizeof(h));
  std::size_t area_offset = 0;
  for (std::uint32_t i = 0; i < h.section_count; ++i)
    if (std::strcmp(table[i].name, "surfel.area") == 0) area_offset = table[i].offset;
  ASSERT_NE(area_offset, 0u) << "the seed has no surfel.area section";
  const float doubled = 2.0f * [&] { float a; std::memcpy(&a, &bytes[area_offset], 4); return a; }();
  std::memcpy(&bytes[area_offset], &doubled, 4);

  const ArtifactVerdict v = openArtifactBytes(bytes);
  EXPECT_FALSE(v.raw);
  EXPECT_NE(v.raw.message().find("checksum mismatch in section 'surfel.area'"), std::string::npos)
      << v.raw.toString();
  EXPECT_TRUE(v.fixed);
  EXPECT_TRUE(v.after_fix) << v.after_fix.toString();
  EXPECT_TRUE(v.relit);
  EXPECT_TRUE(v.relight) << v.relight.toString();
  std::vector<std::uint8_t> repaired = bytes;
  EXPECT_TRUE(fixChecksums(repaired));
  EXPECT_FALSE(fixChecksums(repaired)) << "a second repair must change nothing";
}

// The seed with one element of one section overwritten and the checksums repaired: what a
// buggy writer or a hostile file looks like to open().
template <typename T>
std::vector<std::uint8_t> seedWith(const char* section, std::size_t element, T value) {
  std::vector<std::uint8_t> bytes = readBytes(seedPath());
  artifact::FileHeader h;
  std::memcpy(&h, bytes.data(), sizeof(h));
  for (std::uint32_t i = 0; i < h.section_count; ++i) {
    artifact::SectionEntry e;
    std::memcpy(&e, bytes.data() + sizeof(h) + i * sizeof(e), sizeof(e));
    if (std::strcmp(e.name, section) != 0) continue;
    EXPECT_LE((element + 1) * sizeof(T), e.bytes) << section;
    std::memcpy(bytes.data() + e.offset + element * sizeof(T), &value, sizeof(T));
    fixChecksums(bytes);
    return bytes;
  }
  ADD_FAILURE() << "the seed has no section " << section;
  return bytes;
}

void expectRejected(const std::vector<std::uint8_t>& bytes, const std::string& needle) {
  const ArtifactVerdict v = openArtifactBytes(bytes);
  EXPECT_FALSE(v.raw);
  EXPECT_FALSE(v.fixed) << "the test input already carries correct checksums";
  EXPECT_EQ(v.raw.code(), Code::kInvalidInput) << v.raw.toString();
  EXPECT_NE(v.raw.message().find(needle), std::string::npos) << "expected '" << needle << "' in: " << v.raw.toString();
  EXPECT_FALSE(v.relit);
}

// Indices the relight uses unchecked in its loops: each out-of-range one is rejected at open,
// naming the section (before these checks, each one read or wrote out of bounds).
TEST(FuzzReplay, OpenRejectsOutOfRangeIndices) {
  expectRejected(seedWith<std::int32_t>("tree.left", 0, 1 << 30), "tree node 0 has children");
  expectRejected(seedWith<std::int32_t>("tree.parent", 3, 7), "do not name it as parent");
  expectRejected(seedWith<std::uint32_t>("tree.leaf_of_surfel", 0, 1u << 30), "'tree.leaf_of_surfel' element 0");
  expectRejected(seedWith<std::int32_t>("lm.cache_of_texel", 0, 1 << 30), "'lm.cache_of_texel' element 0");
  expectRejected(seedWith<std::uint32_t>("lmlink.node", 0, 0xffffffffu), "'lmlink.node' element 0");
  expectRejected(seedWith<std::uint32_t>("lmlink.offsets", 1, 0xffffffffu), "'lmlink.offsets'");
  expectRejected(seedWith<std::uint32_t>("gridlink.offsets", 0, 5u), "'gridlink.offsets' starts at 5");
  expectRejected(seedWith<std::uint32_t>("dilate.source", 0, 1u << 30), "'dilate.source' element 0");
}

TEST(FuzzReplay, OpenRejectsNonFiniteAndAbsurdValues) {
  expectRejected(seedWith<float>("surfel.area", 2, std::numeric_limits<float>::quiet_NaN()),
                 "'surfel.area' element 2 is not finite");
  expectRejected(seedWith<std::uint16_t>("lmlink.coeffs", 1, 0x7c00), "'lmlink.coeffs' element 1 is not a finite half");
  expectRejected(seedWith<float>("surfel.lightmap_uv", 0, 3e37f), "'surfel.lightmap_uv' element 0");
  expectRejected(seedWith<float>("surfel.position", 0, 1e30f), "'surfel.position' element 0 lies millions of grid cells");
}

// Metadata fields of the wrong type or range: a Status naming the field, never an exception.
TEST(FuzzReplay, OpenRejectsBadMetadata) {
  std::vector<std::uint8_t> bytes = readBytes(seedPath());
  const std::string text(bytes.begin(), bytes.end());
  const std::size_t at = text.find("\"bands\":2");
  ASSERT_NE(at, std::string::npos);
  bytes[at + 8] = '"';  // "bands":" ... : a string where a number belongs
  fixChecksums(bytes);
  ArtifactVerdict v = openArtifactBytes(bytes);
  EXPECT_NE(v.raw.message().find("artifact"), std::string::npos) << v.raw.toString();
  EXPECT_FALSE(v.relit);
  bytes[at + 8] = '9';
  fixChecksums(bytes);
  v = openArtifactBytes(bytes);
  EXPECT_NE(v.raw.message().find("meta field 'bands' must be an integer in [1, 4] (is 9)"), std::string::npos)
      << v.raw.toString();
  EXPECT_FALSE(v.relit);
}

// --- Bake outputs read by `lightlink render` and the game client ---

TEST(FuzzReplay, BakeOutputSeedsLoad) {
  for (const char* target : {"grid_raw", "lightmap_exr"}) {
    const auto files = inputs("corpus", target);
    ASSERT_FALSE(files.empty()) << "no seeds for " << target;
    for (const fs::path& f : files) {
      const Status s = std::string(target) == "grid_raw" ? readGridRawBytes(readBytes(f)) : readLightmapExrBytes(readBytes(f));
      EXPECT_TRUE(s) << f << ": " << s.toString();
    }
  }
}

// regressions/grid_raw/dims_product_overflow.raw made `lightlink render` segfault (dims
// whose product wraps to 11716 points, read as negative ints); the others allocated memory
// the file did not hold or let a NaN spacing through.
TEST(FuzzReplay, BakeOutputRegressionsAreRejected) {
  for (const char* target : {"grid_raw", "lightmap_exr"}) {
    for (const fs::path& f : inputs("regressions", target)) {
      const Status s = std::string(target) == "grid_raw" ? readGridRawBytes(readBytes(f)) : readLightmapExrBytes(readBytes(f));
      EXPECT_FALSE(s) << f << " was accepted";
      expectClear(s, f, target);
    }
  }
}

// Found by fuzz_lightmap_exr: a header attribute whose size field points far past the end of
// a 4.7 KB file. OpenEXR allocated the stated size before failing (seconds per read under
// ASan, hundreds of MB); the reader now checks attribute sizes against the file first.
TEST(FuzzReplay, ExrAttributeBeyondTheFileIsRejectedBeforeOpenExrReadsIt) {
  const fs::path f = fs::path(LIGHTLINK_FUZZ_DIR) / "regressions/lightmap_exr/attribute_size_beyond_file.exr";
  const Status s = readLightmapExrBytes(readBytes(f));
  EXPECT_EQ(s.code(), Code::kInvalidInput) << s.toString();
  EXPECT_NE(s.message().find("claims"), std::string::npos) << s.toString();
  EXPECT_NE(s.message().find("beyond the end of the file"), std::string::npos) << s.toString();
  // The same, in a 120 s campaign after that fix: a channel list whose size field disagrees
  // with its content, so a walk by sizes and OpenEXR's walk by content parted ways and
  // OpenEXR met a 1.8 GB opaque attribute. The walk now parses as OpenEXR does.
  const Status t = readLightmapExrBytes(
      readBytes(fs::path(LIGHTLINK_FUZZ_DIR) / "regressions/lightmap_exr/channel_list_size_mismatch.exr"));
  EXPECT_EQ(t.code(), Code::kInvalidInput) << t.toString();
  EXPECT_NE(t.message().find("the channel list disagrees with its size"), std::string::npos) << t.toString();
}

// --- Light sets ---

TEST(FuzzReplay, LightSetSeedsLoadApplyAndRelight) {
  const auto files = inputs("corpus", "lightset");
  ASSERT_FALSE(files.empty());
  for (const fs::path& f : files) {
    const LightSetVerdict v = loadLightSetBytes(readBytes(f));
    expectClear(v.load, f, "load");  // a merge file may remove a scene light: alone it cannot load
    EXPECT_TRUE(v.apply) << f << ": " << v.apply.toString();
    EXPECT_TRUE(v.round_trip) << f << ": " << v.round_trip.toString();
    EXPECT_TRUE(v.relit && v.relight) << f << ": " << v.relight.toString();
  }
}

TEST(FuzzReplay, LightSetRegressions) {
  for (const fs::path& f : inputs("regressions", "lightset")) {
    const LightSetVerdict v = loadLightSetBytes(readBytes(f));
    expectClear(v.load, f, "load");
    expectClear(v.apply, f, "apply");
    EXPECT_TRUE(v.round_trip) << f << ": " << v.round_trip.toString();
    if (v.relit) {
      EXPECT_TRUE(v.relight) << f << ": " << v.relight.toString();
    }
  }
}

#ifdef LIGHTLINK_FUZZ_SERVICE
// --- Requests through the daemon's validation; light sets through the client library ---

TEST(FuzzReplay, RequestSeedsAreCurrentAndAccepted) {
  const auto seeds = requestSeeds();
  ASSERT_EQ(inputs("corpus", "requests").size(), seeds.size()) << "regenerate: fuzz_make_seed --requests";
  for (const auto& [name, bytes] : seeds) {
    EXPECT_EQ(readBytes(fs::path(LIGHTLINK_FUZZ_DIR) / "corpus/requests" / name), bytes)
        << name << " is stale: regenerate with fuzz_make_seed --requests tests/fuzz/corpus/requests";
    const RequestVerdict v = applyRequestBytes(bytes);
    EXPECT_TRUE(v.parsed) << name;
    EXPECT_TRUE(v.validation) << name << ": " << v.validation.toString();
    if (v.relit) {
      EXPECT_TRUE(v.relight) << name << ": " << v.relight.toString();
    }
  }
}

TEST(FuzzReplay, RequestRegressions) {
  for (const fs::path& f : inputs("regressions", "requests")) {
    const RequestVerdict v = applyRequestBytes(readBytes(f));
    expectClear(v.validation, f, "validation");
    if (v.relit) {
      EXPECT_TRUE(v.relight) << f << ": " << v.relight.toString();
    }
  }
}

TEST(FuzzReplay, LightSetsThroughTheClientLibrary) {
  for (const char* kind : {"corpus", "regressions"})
    for (const fs::path& f : inputs(kind, "lightset")) {
      const RequestVerdict v = lightSetThroughClient(readBytes(f));
      expectClear(v.validation, f, "client");
      if (v.relit) {
        EXPECT_TRUE(v.relight) << f << ": " << v.relight.toString();
      }
    }
}
#endif

}  // namespace
}  // namespace lightlink::fuzz
