// UpdateJournal: the write-ahead log that makes an acknowledged light-set version durable,
// `<cache-dir>/sessions.journal`.
//
// sessions.json is the snapshot of every scene; the journal holds each version taken since
// (one record: scene id, version, the whole light set). A new version is appended and the
// caller waits until it is on disk (write + fdatasync) before the version becomes visible
// or is acknowledged. Concurrent callers share one write and one fdatasync (group commit):
// the first waiter to find no commit in flight becomes the leader and writes everything
// appended so far, the others wait for its outcome. A failed write fails every record not
// yet on disk and cuts the file back to its last synced length, so nothing after the
// failure lands behind a torn record.
//
// Records are checksummed (XXH3-64). Restore reads them in order and stops at the first
// torn or corrupt one (a crash mid-append): that tail is logged and cut off before new
// records are appended. compact() writes a snapshot and empties the journal while no
// commit is in flight, so every record is covered by the snapshot or still in the journal.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/common/status.h"
#include "service/session_store.h"

namespace lightlink::service {

struct JournalRecord {
  std::string scene_id;
  std::uint64_t version = 0;
  nlohmann::json lights;  // LightSet::toJson
};

// What a journal file holds: its intact records in order, and where they end.
struct JournalContents {
  std::vector<JournalRecord> records;
  std::uint64_t valid_bytes = 0;    // the intact prefix
  std::uint64_t dropped_bytes = 0;  // a torn or corrupt tail after it
  std::string dropped_reason;       // why the tail was dropped (empty when none)
};

// Reads `path`; a missing file is empty. Never fails on content: a bad record ends the read.
Expected<JournalContents> readJournal(const std::string& path);

// The bytes of one record (header + JSON payload), as the journal appends them.
std::string encodeJournalRecord(const JournalRecord& record);

// Applies journal records to the snapshot's sessions, in order: a record replaces the light
// set and version of its scene when its version is >= the scene's (a later record of the
// same version is the one that was acknowledged). Records of scenes not in the snapshot
// (closed, or never persisted) are skipped. Returns the number applied.
std::size_t replayJournal(std::vector<SessionRecord>& sessions, const std::vector<JournalRecord>& records);

class UpdateJournal {
 public:
  struct Batch;                                    // one group commit
  using Ticket = std::shared_ptr<const Batch>;

  // Reads `path` (the records are kept for takeRecovered()), cuts off a torn tail and opens
  // it for appending (created 0600 when missing). An open that fails is retried by the next
  // commit, which fails with the reason until it works.
  explicit UpdateJournal(std::string path);
  ~UpdateJournal();
  UpdateJournal(const UpdateJournal&) = delete;
  UpdateJournal& operator=(const UpdateJournal&) = delete;

  const std::string& path() const { return path_; }
  // The records found when the journal was opened (for restore; handed over once).
  std::vector<JournalRecord> takeRecovered() {
    std::vector<JournalRecord> out;
    out.swap(recovered_);
    return out;
  }

  // Queues a record for the next commit. `after` is the ticket of the record this one was
  // built on (null: built on durable state); when that one has failed, nothing is queued
  // and null is returned: the caller rebuilds on the durable state.
  Ticket append(const JournalRecord& record, const Ticket& after);
  // Blocks until the ticket's commit is on disk (OK) or failed (the reason). A failure
  // says "sessions: cannot persist the update: <why>".
  Status wait(const Ticket& ticket);
  enum class State { kPending, kDurable, kFailed };
  State state(const Ticket& ticket) const;

  // Runs `snapshot` while no commit is in flight; when it succeeds every record so far is
  // covered and the journal is emptied.
  Status compact(const std::function<Status()>& snapshot);
  // Called (leader thread, no lock held) once the journal exceeds `bytes` since the last
  // compaction, so the owner can schedule one.
  void onLarge(std::uint64_t bytes, std::function<void()> callback);

  std::uint64_t bytes() const;     // synced bytes in the file
  std::uint64_t commits() const;   // fdatasyncs done (group commits)
  std::uint64_t records() const;   // records made durable

 private:
  Status ensureOpen();
  Status writeAndSync(const std::string& bytes);
  Status cutBackTo(std::uint64_t size);

  std::string path_;
  std::vector<JournalRecord> recovered_;
  mutable std::mutex mutex_;
  std::condition_variable done_cv_;
  std::shared_ptr<Batch> open_;  // collecting records for the next commit
  bool busy_ = false;            // a leader (or compact) owns the file
  // The file (owned by whoever set busy_).
  int fd_ = -1;
  std::atomic<std::uint64_t> good_size_{0};  // synced, intact bytes (read by bytes() too)
  bool dirty_tail_ = false;      // bytes past good_size_ may exist: cut them before appending
  std::uint64_t commits_ = 0, records_ = 0;
  std::uint64_t large_bytes_ = 0;
  bool large_signalled_ = false;
  std::function<void()> on_large_;
};

}  // namespace lightlink::service
