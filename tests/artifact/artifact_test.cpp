#include "core/artifact/artifact.h"

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <cstring>
#include <numeric>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "tests/common/testing.h"

namespace lightlink::artifact {
namespace {

std::vector<char> readFile(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void writeBytes(const std::filesystem::path& p, const std::vector<char>& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

struct Fixture {
  std::vector<float> floats = std::vector<float>(1000);
  std::vector<std::uint32_t> ints = std::vector<std::uint32_t>(37);
  std::string meta = R"({"surfels": 1000})";
  Fixture() {
    std::iota(floats.begin(), floats.end(), 0.5f);
    std::iota(ints.begin(), ints.end(), 7u);
  }
  Status write(const std::string& path, std::uint64_t key = 42) const {
    Writer w(key);
    if (auto s = w.addArray<float>("floats", floats); !s) return s;
    if (auto s = w.addArray<std::uint32_t>("ints", ints); !s) return s;
    if (auto s = w.addString("meta", meta); !s) return s;
    return w.write(path);
  }
};

TEST(Artifact, RoundTripIsZeroCopyAndAligned) {
  testing::TempDir dir;
  const auto path = (dir / "a.llk").string();
  Fixture f;
  ASSERT_TRUE(f.write(path)) << "write failed";
  auto a = Artifact::open(path);
  ASSERT_TRUE(a) << a.status().toString();
  EXPECT_EQ(a->cacheKey(), 42u);
  auto floats = a->array<float>("floats");
  ASSERT_TRUE(floats);
  ASSERT_EQ(floats->size(), f.floats.size());
  EXPECT_TRUE(std::equal(floats->begin(), floats->end(), f.floats.begin()));
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(floats->data()) % kSectionAlignment, 0u);
  auto ints = a->array<std::uint32_t>("ints");
  ASSERT_TRUE(ints);
  EXPECT_TRUE(std::equal(ints->begin(), ints->end(), f.ints.begin()));
  EXPECT_EQ(*a->string("meta"), f.meta);
  // Same bytes out for the same input: artifacts are deterministic.
  const auto path2 = (dir / "b.llk").string();
  ASSERT_TRUE(f.write(path2));
  EXPECT_EQ(readFile(path), readFile(path2));
}

TEST(Artifact, MissingSectionAndWrongTypeAreNamed) {
  testing::TempDir dir;
  const auto path = (dir / "a.llk").string();
  ASSERT_TRUE(Fixture().write(path));
  auto a = Artifact::open(path);
  ASSERT_TRUE(a);
  auto missing = a->array<float>("links");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.status().message().find("'links'"), std::string::npos);
  auto wrong = a->array<double>("floats");
  ASSERT_FALSE(wrong);
  EXPECT_NE(wrong.status().message().find("4-byte elements"), std::string::npos) << wrong.status().message();
}

TEST(Artifact, CorruptPayloadIsDetectedNamingTheSection) {
  testing::TempDir dir;
  const auto path = dir / "a.llk";
  ASSERT_TRUE(Fixture().write(path.string()));
  auto bytes = readFile(path);
  {
    auto a = Artifact::open(path.string());
    ASSERT_TRUE(a);
    const auto& e = a->sections()[1];  // "ints"
    bytes[e.offset + 5] ^= 0x10;
  }
  writeBytes(path, bytes);
  auto a = Artifact::open(path.string());
  ASSERT_FALSE(a);
  EXPECT_EQ(a.status().code(), Code::kInvalidInput);
  EXPECT_NE(a.status().message().find("checksum mismatch in section 'ints'"), std::string::npos)
      << a.status().message();
  // A reader that skips payload checks can still find the damage on demand.
  auto lazy = Artifact::open(path.string(), {.verify_payloads = false});
  ASSERT_TRUE(lazy);
  EXPECT_TRUE(lazy->verify("floats"));
  EXPECT_FALSE(lazy->verify("ints"));
}

TEST(Artifact, TruncatedFileIsRejected) {
  testing::TempDir dir;
  const auto path = dir / "a.llk";
  ASSERT_TRUE(Fixture().write(path.string()));
  auto bytes = readFile(path);
  for (std::size_t keep : {bytes.size() - 1, bytes.size() / 2, std::size_t(100), std::size_t(10)}) {
    writeBytes(path, std::vector<char>(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(keep)));
    auto a = Artifact::open(path.string());
    ASSERT_FALSE(a) << "kept " << keep << " bytes";
    EXPECT_NE(a.status().message().find("truncated"), std::string::npos) << a.status().message();
  }
}

TEST(Artifact, WrongMagicVersionAndHeaderDamageAreRejected) {
  testing::TempDir dir;
  const auto path = dir / "a.llk";
  ASSERT_TRUE(Fixture().write(path.string()));
  const auto good = readFile(path);

  auto bad_magic = good;
  bad_magic[0] = 'X';
  writeBytes(path, bad_magic);
  auto a = Artifact::open(path.string());
  ASSERT_FALSE(a);
  EXPECT_NE(a.status().message().find("not a lightlink artifact"), std::string::npos);

  // A file from a future version, with a self-consistent header.
  auto future = good;
  FileHeader h;
  std::memcpy(&h, future.data(), sizeof(h));
  h.format_version = kFormatVersion + 1;
  h.header_checksum = hashBytes(&h, offsetof(FileHeader, header_checksum));
  std::memcpy(future.data(), &h, sizeof(h));
  writeBytes(path, future);
  a = Artifact::open(path.string());
  ASSERT_FALSE(a);
  EXPECT_EQ(a.status().code(), Code::kUnsupported);
  EXPECT_NE(a.status().message().find(fmt::format("format version {}, this build reads version {}", kFormatVersion + 1,
                                                 kFormatVersion)),
            std::string::npos)
      << a.status().message();

  auto damaged = good;
  damaged[offsetof(FileHeader, cache_key)] ^= 1;
  writeBytes(path, damaged);
  a = Artifact::open(path.string());
  ASSERT_FALSE(a);
  EXPECT_NE(a.status().message().find("header checksum"), std::string::npos);
}

TEST(Artifact, AtomicWriteReplacesAndLeavesNoTemporaries) {
  testing::TempDir dir;
  const auto path = dir / "a.llk";
  Fixture f;
  ASSERT_TRUE(f.write(path.string(), 1));
  ASSERT_TRUE(f.write(path.string(), 2));  // overwrite while nothing holds it
  auto a = Artifact::open(path.string());
  ASSERT_TRUE(a);
  EXPECT_EQ(a->cacheKey(), 2u);
  // A reader holding the old mapping keeps valid data while a writer replaces the file.
  ASSERT_TRUE(f.write(path.string(), 3));
  EXPECT_EQ(a->cacheKey(), 2u);
  EXPECT_EQ((*a->array<float>("floats"))[10], f.floats[10]);
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path())) ++entries;
  EXPECT_EQ(entries, 1u) << "temporary files were left behind";
}

TEST(Artifact, WriteIntoMissingDirectoryFailsCleanly) {
  testing::TempDir dir;
  const auto path = dir / "no" / "such" / "dir" / "a.llk";
  Status s = Fixture().write(path.string());
  ASSERT_FALSE(s);
  EXPECT_EQ(s.code(), Code::kIoError);
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(Artifact, InvalidSectionsAreRefused) {
  Writer w(0);
  std::vector<float> v(3);
  EXPECT_FALSE(w.addArray<float>("", v));
  EXPECT_FALSE(w.addArray<float>("a-name-that-is-far-too-long-for-the-table", v));
  EXPECT_TRUE(w.addArray<float>("v", v));
  EXPECT_FALSE(w.addArray<float>("v", v));  // duplicate
}

TEST(CacheKey, DependsOnSceneParametersAndNothingElse) {
  const std::vector<std::byte> scene_a(100, std::byte{1});
  std::vector<std::byte> scene_b = scene_a;
  scene_b[50] = std::byte{2};
  EXPECT_EQ(cacheKey(scene_a, "nS=32768"), cacheKey(scene_a, "nS=32768"));
  EXPECT_NE(cacheKey(scene_a, "nS=32768"), cacheKey(scene_b, "nS=32768"));
  EXPECT_NE(cacheKey(scene_a, "nS=32768"), cacheKey(scene_a, "nS=16384"));
  EXPECT_EQ(cacheKeyHex(0xabcULL), "0000000000000abc");
}

}  // namespace
}  // namespace lightlink::artifact
