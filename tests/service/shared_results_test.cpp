// Shared-memory delivery in process: the daemon's writer (service/shared_results.h) against
// the client library's reader (clients/client/shared_result.h), the files' lifetime, the
// peers that may ask, and stale directories of killed daemons.
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "clients/client/shared_result.h"
#include "service/shared_results.h"
#include "service/snapshot.h"
#include "tests/common/testing.h"
#include "tests/service/test_snapshots.h"

namespace lightlink::service {
namespace {

namespace fs = std::filesystem;

// The service tests' small snapshot as result `sequence` of scene-a.
void fill(Snapshot& s, std::uint64_t sequence, float base) {
  testing::fillSnapshot(s, base);
  s.scene_id = "scene-a";
  s.version = sequence;
  s.sequence = sequence;
}

v1::ResultHeader parseHeader(const grpc::ByteBuffer& b) {
  grpc::Slice one;
  EXPECT_TRUE(b.DumpToSingleSlice(&one).ok());
  v1::ResultMessage m;
  EXPECT_TRUE(m.ParseFromArray(one.begin(), static_cast<int>(one.size())));
  EXPECT_TRUE(m.has_header());
  return m.header();
}

std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// The payloads a client assembles from the stream's messages.
client::Textures fromStream(const WireResult& w) {
  client::ResultAssembler a;
  for (const grpc::ByteBuffer& b : w.messages) {
    grpc::Slice one;
    EXPECT_TRUE(b.DumpToSingleSlice(&one).ok());
    v1::ResultMessage m;
    EXPECT_TRUE(m.ParseFromArray(one.begin(), static_cast<int>(one.size())));
    EXPECT_TRUE(a.add(m).isOk());
  }
  auto t = a.take();
  EXPECT_TRUE(t) << t.status().toString();
  return t ? std::move(t).value() : client::Textures{};
}

TEST(ServiceSharedMemory, TheFileHoldsTheStreamsChunksAndReadsBackToTheSameResult) {
  lightlink::testing::TempDir tmp;
  Snapshot s;
  fill(s, 1, 0.5f);
  const SpecKey key = SpecKey::from(v1::ResultSpec{}, 2);
  const auto wire = s.wire(key, 4096);
  ASSERT_TRUE(wire);
  ASSERT_GT(wire->messages.size(), 3u) << "several chunks at 4096 bytes";
  std::string dir;
  {
    SharedResults shared(tmp.path().string());
    EXPECT_TRUE(shared.directory().empty()) << "nothing made before the first file";
    auto h = shared.header(s, key, 4096, *wire);
    ASSERT_TRUE(h) << h.status().toString();
    dir = shared.directory();
    EXPECT_EQ(fs::path(dir).parent_path(), tmp.path());
    EXPECT_EQ(fs::status(dir).permissions() & fs::perms::all, fs::perms::owner_all) << "0700";
    const v1::ResultHeader header = parseHeader(**h);
    ASSERT_TRUE(header.has_shared());
    const std::string path = header.shared().path();
    EXPECT_EQ(fs::path(path).parent_path(), fs::path(dir));
    EXPECT_EQ(fs::status(path).permissions() & fs::perms::all, fs::perms::owner_read | fs::perms::owner_write);
    // The header is the stream's, plus `shared`.
    v1::ResultHeader stream_header = parseHeader(wire->messages[0]);
    *stream_header.mutable_shared() = header.shared();
    EXPECT_EQ(header.SerializeAsString(), stream_header.SerializeAsString());

    // Byte for byte: magic, then each chunk message with its length.
    std::string expected(v1::kSharedResultMagic, sizeof v1::kSharedResultMagic);
    for (std::size_t i = 1; i < wire->messages.size(); ++i) {
      grpc::Slice one;
      ASSERT_TRUE(wire->messages[i].DumpToSingleSlice(&one).ok());
      const auto length = static_cast<std::uint32_t>(one.size());
      expected.append(reinterpret_cast<const char*>(&length), 4);
      expected.append(reinterpret_cast<const char*>(one.begin()), one.size());
    }
    const std::string bytes = fileBytes(path);
    EXPECT_EQ(bytes.size(), header.shared().bytes());
    EXPECT_TRUE(bytes == expected);

    // What the client library assembles from it is what it assembles from the stream.
    client::ResultAssembler a;
    v1::ResultMessage hm;
    *hm.mutable_header() = header;
    ASSERT_TRUE(a.add(hm).isOk());
    ASSERT_TRUE(client::readSharedResult(header.shared(), a).isOk());
    auto t = a.take();
    ASSERT_TRUE(t) << t.status().toString();
    EXPECT_TRUE(t->info.shared);
    const client::Textures streamed = fromStream(*wire);
    EXPECT_FALSE(streamed.info.shared);
    EXPECT_EQ(t->payloads, streamed.payloads);
    EXPECT_GT(t->totalBytes(), 70u * 40 * 12 * 2) << "SH, direct and validity all arrived";
    EXPECT_EQ(t->info.version, streamed.info.version);

    // Written once: a second client with the same spec gets the same header.
    auto again = shared.header(s, key, 4096, *wire);
    ASSERT_TRUE(again);
    EXPECT_EQ(again->get(), h->get());
    EXPECT_EQ(shared.fileCount(), 1u);
  }
  EXPECT_FALSE(fs::exists(dir)) << "the daemon's directory goes with it";
}

TEST(ServiceSharedMemory, OnlyTheNewestResultsKeepTheirFilesAndAClosedSceneNone) {
  lightlink::testing::TempDir tmp;
  SharedResults shared(tmp.path().string());
  const SpecKey all = SpecKey::from(v1::ResultSpec{}, 2);
  v1::ResultSpec one_band;
  one_band.set_bands(1);
  const SpecKey first_band = SpecKey::from(one_band, 2);
  std::vector<std::string> paths;  // per result, the all-bands file
  constexpr std::uint64_t kResults = SharedResults::kKeepResults + 3;
  for (std::uint64_t seq = 1; seq <= kResults; ++seq) {
    Snapshot s;
    fill(s, seq, 0.1f * static_cast<float>(seq));
    for (const SpecKey& k : {all, first_band}) {
      auto h = shared.header(s, k, 1 << 20, *s.wire(k, 1 << 20));
      ASSERT_TRUE(h) << h.status().toString();
      if (k == all) paths.push_back(parseHeader(**h).shared().path());
    }
    EXPECT_LE(shared.fileCount(), 2 * SharedResults::kKeepResults);
  }
  EXPECT_EQ(shared.fileCount(), 2 * SharedResults::kKeepResults);
  for (std::uint64_t seq = 1; seq <= kResults; ++seq)
    EXPECT_EQ(fs::exists(paths[seq - 1]), seq > kResults - SharedResults::kKeepResults) << "result " << seq;
  std::size_t on_disk = 0;
  std::uint64_t bytes_on_disk = 0;
  for (const auto& e : fs::directory_iterator(shared.directory())) {
    on_disk += e.is_regular_file() ? 1 : 0;
    bytes_on_disk += e.is_regular_file() ? e.file_size() : 0;
  }
  EXPECT_EQ(on_disk, shared.fileCount()) << "no temporary or orphaned file is left";
  EXPECT_EQ(bytes_on_disk, shared.byteCount());

  // A result older than every kept one gets no file (the caller sends it on the stream).
  Snapshot old;
  fill(old, 1, 0.1f);
  EXPECT_FALSE(shared.header(old, all, 1 << 20, *old.wire(all, 1 << 20)));
  EXPECT_EQ(shared.fileCount(), 2 * SharedResults::kKeepResults);

  shared.dropScene("scene-a");
  EXPECT_EQ(shared.fileCount(), 0u);
  EXPECT_EQ(shared.byteCount(), 0u);
  EXPECT_TRUE(fs::is_empty(shared.directory()));
}

TEST(ServiceSharedMemory, OffWithoutABaseAndAnErrorWhereNoDirectoryCanBeMade) {
  Snapshot s;
  fill(s, 1, 0.5f);
  const SpecKey key = SpecKey::from(v1::ResultSpec{}, 2);
  SharedResults off("");
  EXPECT_FALSE(off.enabled());
  EXPECT_FALSE(off.header(s, key, 4096, *s.wire(key, 4096)));
  lightlink::testing::TempDir tmp;
  SharedResults nowhere((tmp.path() / "missing" / "deeper").string());
  auto h = nowhere.header(s, key, 4096, *s.wire(key, 4096));
  ASSERT_FALSE(h);
  EXPECT_NE(h.status().message().find("missing"), std::string::npos) << h.status().toString();
}

TEST(ServiceSharedMemory, ReaderRefusesWhatIsNotTheNamedFile) {
  lightlink::testing::TempDir tmp;
  Snapshot s;
  fill(s, 1, 0.5f);
  const SpecKey key = SpecKey::from(v1::ResultSpec{}, 2);
  SharedResults shared(tmp.path().string());
  auto h = shared.header(s, key, 4096, *s.wire(key, 4096));
  ASSERT_TRUE(h);
  const v1::ResultHeader header = parseHeader(**h);
  const std::string good = fileBytes(header.shared().path());
  v1::ResultMessage hm;
  *hm.mutable_header() = header;

  auto readAs = [&](const std::string& bytes, std::uint64_t claimed) {
    const std::string path = (tmp / "copy.llr").string();
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    v1::SharedResult named;
    named.set_path(path);
    named.set_bytes(claimed);
    client::ResultAssembler a;
    EXPECT_TRUE(a.add(hm).isOk());
    return client::readSharedResult(named, a);
  };
  EXPECT_TRUE(readAs(good, good.size()).isOk());
  const Status size = readAs(good, good.size() + 1);
  EXPECT_EQ(size.code(), Code::kInvalidInput);
  EXPECT_NE(size.message().find("the header names"), std::string::npos) << size.toString();
  std::string magic = good;
  magic[7] = '2';  // a format version this reader does not know
  const Status version = readAs(magic, magic.size());
  EXPECT_NE(version.message().find("format version 1"), std::string::npos) << version.toString();
  const std::string cut = good.substr(0, good.size() - 10);
  const Status truncated = readAs(cut, cut.size());
  EXPECT_EQ(truncated.code(), Code::kInvalidInput);
  EXPECT_NE(truncated.message().find("record"), std::string::npos) << truncated.toString();

  v1::SharedResult gone;
  gone.set_path((tmp / "no-such.llr").string());
  gone.set_bytes(good.size());
  client::ResultAssembler a;
  ASSERT_TRUE(a.add(hm).isOk());
  EXPECT_EQ(client::readSharedResult(gone, a).code(), Code::kNotFound);
}

TEST(ServiceSharedMemory, StaleDirectoriesOfKilledDaemonsAreRemoved) {
  lightlink::testing::TempDir tmp;
  // A pid that is certainly gone: a child that exited and was reaped.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) ::_exit(0);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  const fs::path stale = tmp / ("lightlinkd-" + std::to_string(child) + "-abc123");
  const fs::path mine = tmp / ("lightlinkd-" + std::to_string(::getpid()) + "-def456");
  const fs::path other = tmp / "lightlinkd-notapid-x";
  const fs::path unrelated = tmp / "someone-else";
  for (const auto& d : {stale, mine, other, unrelated}) fs::create_directories(d);
  std::ofstream(stale / "r1.llr") << "x";
  EXPECT_EQ(removeStaleSharedDirs(tmp.path().string()), 1);
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(mine));
  EXPECT_TRUE(fs::exists(other));
  EXPECT_TRUE(fs::exists(unrelated));
  EXPECT_EQ(removeStaleSharedDirs((tmp / "absent").string()), 0);
  EXPECT_EQ(removeStaleSharedDirs(""), 0);
}

}  // namespace
}  // namespace lightlink::service
