#include "service/update_journal.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include <fmt/format.h>

#include "core/artifact/artifact.h"
#include "service/logging.h"

namespace lightlink::service {
namespace {

namespace fs = std::filesystem;

// Record: magic, payload length (u32 LE), XXH3-64 of the payload (u64 LE), the payload
// (JSON: {"scene", "version", "lights"}).
constexpr char kMagic[4] = {'L', 'L', 'J', '1'};
constexpr std::size_t kHeaderBytes = 16;
constexpr std::uint32_t kMaxPayloadBytes = 256u << 20;  // far above any light set the daemon accepts

void putLe(std::string& out, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}

std::uint64_t getLe(const char* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(p[i])) << (8 * i);
  return v;
}

std::string errnoText(int e) { return std::strerror(e); }

}  // namespace

struct UpdateJournal::Batch {
  std::string bytes;
  std::size_t count = 0;
  bool done = false;  // guarded by the journal's mutex, like status
  Status status;
};

std::string encodeJournalRecord(const JournalRecord& record) {
  nlohmann::ordered_json j;
  j["scene"] = record.scene_id;
  j["version"] = record.version;
  j["lights"] = record.lights;
  const std::string payload = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  std::string out(kMagic, sizeof kMagic);
  putLe(out, payload.size(), 4);
  putLe(out, artifact::hashBytes(payload.data(), payload.size()), 8);
  out += payload;
  return out;
}

Expected<JournalContents> readJournal(const std::string& path) {
  JournalContents c;
  std::ifstream in(path, std::ios::binary);
  if (!in) return c;
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return ioError("{}: cannot read", path);
  std::size_t at = 0;
  while (at < data.size()) {
    const std::size_t left = data.size() - at;
    if (left < kHeaderBytes) {
      c.dropped_reason = fmt::format("a {}-byte record header cut short", left);
      break;
    }
    const char* h = data.data() + at;
    if (std::memcmp(h, kMagic, sizeof kMagic) != 0) {
      c.dropped_reason = "no record marker";
      break;
    }
    const std::uint64_t n = getLe(h + 4, 4);
    if (n > kMaxPayloadBytes || n > left - kHeaderBytes) {
      c.dropped_reason = fmt::format("a {}-byte record with {} bytes left", n, left - kHeaderBytes);
      break;
    }
    const char* payload = h + kHeaderBytes;
    if (artifact::hashBytes(payload, n) != getLe(h + 8, 8)) {
      c.dropped_reason = "checksum mismatch";
      break;
    }
    const nlohmann::json j = nlohmann::json::parse(payload, payload + n, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded() || !j.is_object() || !j.contains("scene") || !j["scene"].is_string() ||
        !j.contains("version") || !j["version"].is_number_unsigned() || !j.contains("lights") ||
        !j["lights"].is_object()) {
      c.dropped_reason = "a record that is not {scene, version, lights}";
      break;
    }
    c.records.push_back({j["scene"].get<std::string>(), j["version"].get<std::uint64_t>(), j["lights"]});
    at += kHeaderBytes + n;
  }
  c.valid_bytes = at;
  c.dropped_bytes = data.size() - at;
  return c;
}

std::size_t replayJournal(std::vector<SessionRecord>& sessions, const std::vector<JournalRecord>& records) {
  std::map<std::string, SessionRecord*> by_id;
  for (auto& s : sessions) by_id[s.id] = &s;
  std::size_t applied = 0;
  for (const auto& r : records) {
    const auto it = by_id.find(r.scene_id);
    if (it == by_id.end() || r.version < it->second->version) continue;
    it->second->version = r.version;
    it->second->lights = r.lights;
    ++applied;
  }
  return applied;
}

UpdateJournal::UpdateJournal(std::string path) : path_(std::move(path)) {
  auto contents = readJournal(path_);
  if (!contents) {
    logEvent(LogLevel::kError, "journal_unreadable", {{"path", path_}, {"error", contents.status().message()}});
    dirty_tail_ = true;  // appends start a new journal rather than overwrite an unknown one
  } else {
    recovered_ = std::move(contents->records);
    good_size_ = contents->valid_bytes;
    if (contents->dropped_bytes > 0) {
      // A crash during an append: that record was never acknowledged.
      logEvent(LogLevel::kWarn, "journal_tail_ignored",
               {{"path", path_},
                {"offset", contents->valid_bytes},
                {"bytes", contents->dropped_bytes},
                {"reason", contents->dropped_reason}});
      dirty_tail_ = true;
    }
  }
  if (Status s = ensureOpen(); !s)
    logEvent(LogLevel::kError, "journal_write_failed", {{"path", path_}, {"error", s.message()}});
}

UpdateJournal::~UpdateJournal() {
  if (fd_ >= 0) ::close(fd_);
}

Status UpdateJournal::ensureOpen() {
  if (fd_ < 0) {
    const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0600);
    if (fd < 0) return ioError("cannot open the journal: {}", errnoText(errno));
    // A new file's name must be durable too, or a power loss could take the records with it.
    const std::string dir = fs::path(path_).has_parent_path() ? fs::path(path_).parent_path().string() : ".";
    const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    const bool synced = dfd >= 0 && ::fsync(dfd) == 0;
    const int sync_errno = errno;
    if (dfd >= 0) ::close(dfd);
    if (!synced) {
      ::close(fd);
      return ioError("cannot sync the journal's directory: {}", errnoText(sync_errno));
    }
    fd_ = fd;
  }
  if (dirty_tail_) return cutBackTo(good_size_);
  return {};
}

Status UpdateJournal::cutBackTo(std::uint64_t size) {
  dirty_tail_ = true;
  if (::ftruncate(fd_, static_cast<off_t>(size)) != 0)
    return ioError("cannot cut the journal back to {} bytes: {}", size, errnoText(errno));
  // The file is that long now, synced or not: later appends go there.
  good_size_ = size;
  if (::fdatasync(fd_) != 0) return ioError("cannot sync the journal: {}", errnoText(errno));
  dirty_tail_ = false;
  return {};
}

Status UpdateJournal::writeAndSync(const std::string& bytes) {
  if (Status s = ensureOpen(); !s) return s;
  std::size_t done = 0;
  int error = 0;
  while (done < bytes.size()) {
    const auto at = static_cast<off_t>(good_size_.load() + done);
    const ssize_t n = ::pwrite(fd_, bytes.data() + done, bytes.size() - done, at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = n < 0 ? errno : EIO;
      break;
    }
    done += static_cast<std::size_t>(n);
  }
  if (error == 0 && ::fdatasync(fd_) != 0) error = errno;
  if (error != 0) {
    // Part of the batch may be in the file: cut it off, so the next commit does not follow
    // a torn record (restore would stop there). If even that fails, the next commit retries.
    dirty_tail_ = true;
    (void)cutBackTo(good_size_);
    return ioError("{}", errnoText(error));
  }
  good_size_ += bytes.size();
  return {};
}

UpdateJournal::Ticket UpdateJournal::append(const JournalRecord& record, const Ticket& after) {
  std::string bytes = encodeJournalRecord(record);
  std::lock_guard lock(mutex_);
  if (after && after->done && !after->status) return nullptr;
  if (!open_) open_ = std::make_shared<Batch>();
  open_->bytes += bytes;
  ++open_->count;
  return open_;
}

Status UpdateJournal::wait(const Ticket& ticket) {
  std::unique_lock lock(mutex_);
  while (!ticket->done) {
    if (busy_) {
      done_cv_.wait(lock);
      continue;
    }
    // Nobody is writing, so the ticket's batch is the open one: write it, with every record
    // appended so far.
    std::shared_ptr<Batch> batch = std::move(open_);
    open_.reset();
    busy_ = true;
    lock.unlock();
    Status s = writeAndSync(batch->bytes);
    lock.lock();
    busy_ = false;
    batch->done = true;
    batch->bytes.clear();
    std::function<void()> signal;
    if (s) {
      ++commits_;
      records_ += batch->count;
      if (on_large_ && !large_signalled_ && good_size_ > large_bytes_) {
        large_signalled_ = true;
        signal = on_large_;
      }
    } else {
      batch->status = ioError("sessions: cannot persist the update: {}", s.message());
      logEvent(LogLevel::kError, "journal_write_failed",
               {{"path", path_}, {"records", batch->count}, {"error", s.message()}});
      // Records appended meanwhile may build on the failed ones: they fail too.
      if (open_) {
        open_->done = true;
        open_->status = batch->status;
        open_.reset();
      }
    }
    done_cv_.notify_all();
    if (signal) {
      lock.unlock();
      signal();
      lock.lock();
    }
  }
  return ticket->status;
}

UpdateJournal::State UpdateJournal::state(const Ticket& ticket) const {
  std::lock_guard lock(mutex_);
  if (!ticket->done) return State::kPending;
  return ticket->status ? State::kDurable : State::kFailed;
}

Status UpdateJournal::compact(const std::function<Status()>& snapshot) {
  {
    std::unique_lock lock(mutex_);
    done_cv_.wait(lock, [&] { return !busy_; });
    busy_ = true;
  }
  Status s = snapshot();
  if (s && good_size_ > 0 && fd_ >= 0) {
    // The snapshot covers every record: the journal may start over. If cutting fails the
    // records stay and replay re-applies them onto the snapshot (same versions, same lights).
    if (Status cut = cutBackTo(0); !cut)
      logEvent(LogLevel::kWarn, "journal_compaction_incomplete", {{"path", path_}, {"error", cut.message()}});
  }
  std::lock_guard lock(mutex_);
  busy_ = false;
  if (s) large_signalled_ = false;
  done_cv_.notify_all();
  return s;
}

void UpdateJournal::onLarge(std::uint64_t bytes, std::function<void()> callback) {
  std::lock_guard lock(mutex_);
  large_bytes_ = bytes;
  on_large_ = std::move(callback);
}

std::uint64_t UpdateJournal::bytes() const { return good_size_.load(); }

std::uint64_t UpdateJournal::commits() const {
  std::lock_guard lock(mutex_);
  return commits_;
}

std::uint64_t UpdateJournal::records() const {
  std::lock_guard lock(mutex_);
  return records_;
}

}  // namespace lightlink::service
