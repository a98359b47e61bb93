// Sharded precompute and merge (core/precompute/merge.h, docs/farm.md): N parts merge into
// the artifact one machine writes, byte for byte, for any N, and a missing, duplicated,
// corrupt, foreign or differently split part is rejected with a message naming it.
#include "core/precompute/merge.h"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/artifact/artifact.h"
#include "core/precompute/precompute.h"
#include "core/scene/load.h"
#include "tests/common/testing.h"
#include "tests/precompute/demo_options.h"

namespace lightlink::precompute {
namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Precomputes the demo (as shard `shard` when given) and writes the artifact or the part.
void precomputeTo(const fs::path& path, const PrecomputeOptions& base, std::optional<ShardSpec> shard,
                  const std::string& scene_path = kDemo) {
  auto scene = scene::loadGltf(scene_path);
  ASSERT_TRUE(scene) << scene.status().toString();
  PrecomputeOptions o = base;
  o.shard = shard;
  auto key = cacheKeyFor(scene_path, o);
  ASSERT_TRUE(key) << key.status().toString();
  auto p = run(*scene, o);
  ASSERT_TRUE(p) << p.status().toString();
  const Status s = shard ? savePart(*p, path.string(), *key, scene_path) : save(*p, path.string(), *key);
  ASSERT_TRUE(s) << s.toString();
}

std::vector<std::string> writeParts(const testing::TempDir& dir, int n, const PrecomputeOptions& o = smallOptions(),
                                    const std::string& prefix = "part") {
  std::vector<std::string> parts;
  for (int i = 0; i < n; ++i) {
    parts.push_back((dir / fmt::format("{}_{}of{}", prefix, i, n)).string());
    precomputeTo(parts.back(), o, ShardSpec{i, n});
  }
  return parts;
}

TEST(ShardSpec, ParsesIOverNAndRejectsTheRest) {
  auto s = parseShard("3/8");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->index, 3);
  EXPECT_EQ(s->count, 8);
  for (const char* bad : {"", "3", "8/8", "-1/4", "1/0", "a/4", "1/4x", " 1/4", "1/99999"}) {
    auto r = parseShard(bad);
    ASSERT_FALSE(r) << bad;
    EXPECT_NE(r.status().message().find("--shard"), std::string::npos) << r.status().message();
  }
}

TEST(ShardSpec, RangesTileEveryTotalInOrder) {
  for (std::size_t total : {0u, 1u, 7u, 1000u, 1001u})
    for (int n : {1, 2, 3, 8, 13}) {
      std::size_t at = 0;
      for (int i = 0; i < n; ++i) {
        const CacheRange r = shardRange(total, {i, n});
        EXPECT_EQ(r.begin, at) << total << " " << i << "/" << n;
        EXPECT_LE(r.end - r.begin, total / n + 1);
        at = r.end;
      }
      EXPECT_EQ(at, total);
    }
}

TEST(ShardMerge, PartsMergeIntoTheUnshardedArtifactByteForByte) {
  testing::TempDir dir;
  precomputeTo(dir / "whole.llk", smallOptions(), std::nullopt);
  const std::string whole = readFile(dir / "whole.llk");
  ASSERT_FALSE(whole.empty());
  // N = 1 and more shards than some ranges have caches for (empty lightmap or grid ranges).
  for (int n : {1, 2, 3, 7}) {
    const auto parts = writeParts(dir, n);
    const fs::path out = dir / fmt::format("merged_{}.llk", n);
    auto merged = mergeParts(parts, out.string());
    ASSERT_TRUE(merged) << merged.status().toString();
    EXPECT_EQ(merged->shards, n);
    EXPECT_EQ(readFile(out), whole) << n << " shards";
  }
}

TEST(ShardMerge, AShardRerunGivesTheSameBytesAndPartsMergeInAnyOrder) {
  testing::TempDir dir;
  auto parts = writeParts(dir, 3);
  const std::string first = readFile(parts[1]);
  precomputeTo(parts[1], smallOptions(), ShardSpec{1, 3});
  EXPECT_EQ(readFile(parts[1]), first);
  ASSERT_TRUE(mergeParts(parts, (dir / "a.llk").string()));
  std::swap(parts[0], parts[2]);
  ASSERT_TRUE(mergeParts(parts, (dir / "b.llk").string()));
  EXPECT_EQ(readFile(dir / "a.llk"), readFile(dir / "b.llk"));
}

TEST(ShardMerge, APartIsNotAnArtifactAndAnArtifactIsNotAPart) {
  testing::TempDir dir;
  const auto parts = writeParts(dir, 2);
  auto opened = open(parts[0]);
  ASSERT_FALSE(opened);
  EXPECT_NE(opened.status().message().find("lightlink merge"), std::string::npos) << opened.status().message();
  precomputeTo(dir / "whole.llk", smallOptions(), std::nullopt);
  auto merged = mergeParts(std::vector<std::string>{parts[0], (dir / "whole.llk").string()}, (dir / "m.llk").string());
  ASSERT_FALSE(merged);
  EXPECT_NE(merged.status().message().find("whole.llk"), std::string::npos) << merged.status().message();
  EXPECT_NE(merged.status().message().find("not a shard part"), std::string::npos) << merged.status().message();
}

// Each rejection names the offending part and leaves an existing output as it was.
class ShardMergeRejects : public ::testing::Test {
 protected:
  void SetUp() override {
    parts_ = writeParts(dir_, 3);
    out_ = (dir_ / "scene.llk").string();
    testing::writeFile(out_, "previous artifact");
  }
  Status merge(const std::vector<std::string>& parts) {
    auto r = mergeParts(parts, out_);
    EXPECT_EQ(readFile(out_), "previous artifact");
    return r ? Status{} : r.status();
  }
  testing::TempDir dir_;
  std::vector<std::string> parts_;
  std::string out_;
};

TEST_F(ShardMergeRejects, AMissingShard) {
  const Status s = merge({parts_[0], parts_[2]});
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("shard 1/3"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("missing"), std::string::npos) << s.message();
}

TEST_F(ShardMergeRejects, ADuplicatedShard) {
  const fs::path copy = dir_ / "copy_of_1";
  fs::copy_file(parts_[1], copy);
  const Status s = merge({parts_[0], parts_[1], copy.string(), parts_[2]});
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("both shard 1/3"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find(copy.string()), std::string::npos) << s.message();
}

TEST_F(ShardMergeRejects, ACorruptPart) {
  // One flipped byte in the middle of the link nodes: the section checksum catches it.
  std::size_t at = 0;
  {
    auto part = artifact::Artifact::open(parts_[2], {.kind = artifact::FileKind::kShardPart});
    ASSERT_TRUE(part) << part.status().toString();
    for (const auto& e : part->sections())
      if (std::string(e.name) == "lmlink.node") at = e.offset + e.bytes / 2;
  }
  ASSERT_GT(at, 0u);
  std::string bytes = readFile(parts_[2]);
  bytes[at] ^= 0x5a;
  testing::writeFile(parts_[2], bytes);
  const Status s = merge(parts_);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find(parts_[2]), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("corrupt"), std::string::npos) << s.message();
}

TEST_F(ShardMergeRejects, ATruncatedPart) {
  const std::string bytes = readFile(parts_[0]);
  testing::writeFile(parts_[0], bytes.substr(0, bytes.size() - 100));
  const Status s = merge(parts_);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find(parts_[0]), std::string::npos) << s.message();
}

TEST_F(ShardMergeRejects, AForeignPart) {
  // Shard 1/3 of another run of the same scene (other options: another cache key).
  PrecomputeOptions other = smallOptions();
  other.seed = 2;
  const fs::path foreign = dir_ / "foreign_1of3";
  precomputeTo(foreign, other, ShardSpec{1, 3});
  const Status s = merge({parts_[0], foreign.string(), parts_[2]});
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find(foreign.string()), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("another precompute"), std::string::npos) << s.message();
}

TEST_F(ShardMergeRejects, APartOfADifferentlySplitRun) {
  const auto halves = writeParts(dir_, 2, smallOptions(), "half");
  const Status s = merge({parts_[0], parts_[1], halves[1]});
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find(halves[1]), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("1/2"), std::string::npos) << s.message();
}

TEST_F(ShardMergeRejects, NoPartsAtAll) {
  const Status s = merge({});
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("no shard parts"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace lightlink::precompute
