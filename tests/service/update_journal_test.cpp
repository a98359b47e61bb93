// The update journal in process (service/update_journal.h): records read back in order, a
// torn or corrupt tail dropped and cut off before new appends, replay over a snapshot,
// group commit, and a failed write (a file-size limit stands in for a full disk: it needs no
// root) that fails its records and leaves the file as it was.
#include <signal.h>
#include <sys/resource.h>

#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>

#include "service/update_journal.h"
#include "tests/common/testing.h"

namespace lightlink::testing {
namespace {

namespace fs = std::filesystem;
using service::JournalRecord;
using service::UpdateJournal;

JournalRecord record(const std::string& scene, std::uint64_t version, float intensity = 1.0f) {
  return {scene, version, nlohmann::json{{"lights", {{{"id", "key"}, {"intensity", intensity}}}}}};
}

std::vector<std::uint64_t> versionsIn(const fs::path& path) {
  auto c = service::readJournal(path.string());
  EXPECT_TRUE(c) << c.status().message();
  std::vector<std::uint64_t> out;
  for (const auto& r : c->records) out.push_back(r.version);
  return out;
}

void appendBytes(const fs::path& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::app);
  f << bytes;
}

TEST(UpdateJournal, RecordsComeBackInOrder) {
  TempDir tmp;
  const fs::path path = tmp / "sessions.journal";
  {
    UpdateJournal j(path.string());
    EXPECT_TRUE(j.takeRecovered().empty());
    for (std::uint64_t v = 2; v <= 4; ++v) {
      auto t = j.append(record("a", v, float(v)), nullptr);
      ASSERT_TRUE(t);
      ASSERT_TRUE(j.wait(t)) << "version " << v;
      EXPECT_EQ(j.state(t), UpdateJournal::State::kDurable);
    }
    ASSERT_TRUE(j.wait(j.append(record("b", 7), nullptr)));
  }
  UpdateJournal again(path.string());
  const auto recovered = again.takeRecovered();
  ASSERT_EQ(recovered.size(), 4u);
  EXPECT_EQ(recovered[0].version, 2u);
  EXPECT_EQ(recovered[2].lights, record("a", 4, 4.0f).lights);
  EXPECT_EQ(recovered[3].scene_id, "b");
  EXPECT_EQ(fs::perms::none, fs::status(path).permissions() & (fs::perms::group_all | fs::perms::others_all));
}

TEST(UpdateJournal, TornTailIsDroppedAndCutBeforeTheNextAppend) {
  TempDir tmp;
  const fs::path path = tmp / "sessions.journal";
  {
    UpdateJournal j(path.string());
    ASSERT_TRUE(j.wait(j.append(record("a", 2), nullptr)));
    ASSERT_TRUE(j.wait(j.append(record("a", 3), nullptr)));
  }
  const auto intact = fs::file_size(path);
  // A crash in the middle of an append: half a record.
  const std::string next = service::encodeJournalRecord(record("a", 4));
  appendBytes(path, next.substr(0, next.size() / 2));
  auto c = service::readJournal(path.string());
  ASSERT_TRUE(c);
  EXPECT_EQ(c->records.size(), 2u);
  EXPECT_EQ(c->valid_bytes, intact);
  EXPECT_EQ(c->dropped_bytes, next.size() / 2);
  EXPECT_FALSE(c->dropped_reason.empty());
  {
    UpdateJournal j(path.string());
    EXPECT_EQ(j.takeRecovered().size(), 2u);
    EXPECT_EQ(fs::file_size(path), intact) << "the torn tail is cut off at open";
    ASSERT_TRUE(j.wait(j.append(record("a", 4), nullptr)));
  }
  EXPECT_EQ(versionsIn(path), (std::vector<std::uint64_t>{2, 3, 4})) << "the new record follows the intact ones";
}

TEST(UpdateJournal, CorruptRecordEndsTheRead) {
  TempDir tmp;
  const fs::path path = tmp / "sessions.journal";
  std::string a = service::encodeJournalRecord(record("a", 2));
  std::string b = service::encodeJournalRecord(record("a", 3));
  b[b.size() - 3] ^= 0x20;  // a flipped bit in the payload: the checksum no longer matches
  appendBytes(path, a + b + service::encodeJournalRecord(record("a", 4)));
  auto c = service::readJournal(path.string());
  ASSERT_TRUE(c);
  ASSERT_EQ(c->records.size(), 1u);
  EXPECT_EQ(c->dropped_reason, "checksum mismatch");
  // Garbage where a record should start.
  appendBytes(tmp / "g", a + std::string(40, '\0'));
  auto g = service::readJournal((tmp / "g").string());
  ASSERT_TRUE(g);
  EXPECT_EQ(g->records.size(), 1u);
  EXPECT_EQ(g->dropped_bytes, 40u);
  // No file: nothing to replay.
  auto none = service::readJournal((tmp / "missing").string());
  ASSERT_TRUE(none);
  EXPECT_TRUE(none->records.empty());
}

TEST(UpdateJournal, ReplayAppliesRecordsInOrderOverTheSnapshot) {
  std::vector<service::SessionRecord> sessions(2);
  sessions[0].id = "a";
  sessions[0].version = 5;
  sessions[0].lights = record("a", 5, 5.0f).lights;
  sessions[1].id = "b";
  sessions[1].version = 1;
  const std::vector<JournalRecord> records = {
      record("a", 4, 4.0f),   // older than the snapshot: already in it
      record("a", 6, 6.0f),   //
      record("gone", 9),      // a scene the snapshot does not have (closed)
      record("b", 2, 2.0f),   //
      record("a", 7, 7.0f),   // an unacknowledged record left by a failed write ...
      record("a", 7, 70.0f),  // ... and the acknowledged one that took its number
  };
  EXPECT_EQ(service::replayJournal(sessions, records), 4u);
  EXPECT_EQ(sessions[0].version, 7u);
  EXPECT_EQ(sessions[0].lights, record("a", 7, 70.0f).lights);
  EXPECT_EQ(sessions[1].version, 2u);
  EXPECT_EQ(sessions[1].lights, record("b", 2, 2.0f).lights);
}

TEST(UpdateJournal, ConcurrentWaitersShareOneCommit) {
  TempDir tmp;
  UpdateJournal j((tmp / "sessions.journal").string());
  std::vector<UpdateJournal::Ticket> tickets;
  for (std::uint64_t v = 2; v < 10; ++v) tickets.push_back(j.append(record("a", v), nullptr));
  std::vector<std::thread> waiters;
  std::atomic<int> ok{0};
  for (const auto& t : tickets)
    waiters.emplace_back([&, t] { ok += j.wait(t).isOk() ? 1 : 0; });
  for (auto& w : waiters) w.join();
  EXPECT_EQ(ok.load(), 8);
  EXPECT_EQ(j.records(), 8u);
  EXPECT_EQ(j.commits(), 1u) << "eight records appended before any wait: one write, one fdatasync";
}

// Writes beyond RLIMIT_FSIZE fail (EFBIG) like a full disk; SIGXFSZ is ignored meanwhile.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    old_handler_ = ::signal(SIGXFSZ, SIG_IGN);
    ::getrlimit(RLIMIT_FSIZE, &old_);
    rlimit l = old_;
    l.rlim_cur = bytes;
    ::setrlimit(RLIMIT_FSIZE, &l);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &old_);
    ::signal(SIGXFSZ, old_handler_);
  }

 private:
  rlimit old_{};
  sighandler_t old_handler_;
};

TEST(UpdateJournal, FailedWriteFailsItsRecordsAndLeavesTheFileIntact) {
  TempDir tmp;
  const fs::path path = tmp / "sessions.journal";
  UpdateJournal j(path.string());
  ASSERT_TRUE(j.wait(j.append(record("a", 2), nullptr)));
  const auto intact = fs::file_size(path);
  UpdateJournal::Ticket failed, dependent;
  {
    FileSizeLimit limit(intact + 40);  // room for a part of the next record only
    failed = j.append(record("a", 3), nullptr);
    const Status s = j.wait(failed);
    ASSERT_FALSE(s);
    EXPECT_NE(s.message().find("sessions: cannot persist the update: File too large"), std::string::npos)
        << s.message();
    EXPECT_EQ(j.state(failed), UpdateJournal::State::kFailed);
    // A record built on the failed one is refused: its writer rebuilds on durable state.
    dependent = j.append(record("a", 4), failed);
    EXPECT_FALSE(dependent);
  }
  EXPECT_EQ(fs::file_size(path), intact) << "the partial record was cut off";
  // Room again: the number the failed record had is taken by the next one.
  ASSERT_TRUE(j.wait(j.append(record("a", 3, 30.0f), nullptr)));
  EXPECT_EQ(versionsIn(path), (std::vector<std::uint64_t>{2, 3}));
  UpdateJournal reread(path.string());
  const auto recovered = reread.takeRecovered();
  ASSERT_EQ(recovered.size(), 2u);
  EXPECT_EQ(recovered[1].lights, record("a", 3, 30.0f).lights);
}

TEST(UpdateJournal, CompactEmptiesTheJournalOnlyWhenTheSnapshotIsWritten) {
  TempDir tmp;
  const fs::path path = tmp / "sessions.journal";
  UpdateJournal j(path.string());
  ASSERT_TRUE(j.wait(j.append(record("a", 2), nullptr)));
  EXPECT_FALSE(j.compact([] { return ioError("snapshot failed"); }));
  EXPECT_EQ(versionsIn(path).size(), 1u) << "a failed snapshot keeps the journal";
  bool snapshot_ran = false;
  EXPECT_TRUE(j.compact([&] {
    snapshot_ran = true;
    return Status{};
  }));
  EXPECT_TRUE(snapshot_ran);
  EXPECT_EQ(fs::file_size(path), 0u);
  EXPECT_EQ(j.bytes(), 0u);
  ASSERT_TRUE(j.wait(j.append(record("a", 3), nullptr)));
  EXPECT_EQ(versionsIn(path), (std::vector<std::uint64_t>{3}));
}

}  // namespace
}  // namespace lightlink::testing
