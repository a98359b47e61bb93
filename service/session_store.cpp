#include "service/session_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "core/common/private_files.h"

namespace lightlink::service {
namespace {

namespace fs = std::filesystem;

std::string errnoText() { return std::strerror(errno); }

}  // namespace

Status writeFileAtomic(const std::string& path, std::string_view bytes, unsigned mode) {
  static std::atomic<unsigned> counter{0};
  const fs::path final_path(path);
  const fs::path dir = final_path.has_parent_path() ? final_path.parent_path() : fs::path(".");
  const fs::path temp =
      dir / fmt::format(".{}.tmp.{}.{}", final_path.filename().string(), ::getpid(), counter.fetch_add(1));
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
  if (fd < 0) return ioError("cannot create {}: {}", temp.string(), errnoText());
  ::fchmod(fd, mode);  // the mode asked for, whatever the umask
  auto fail = [&](const char* what) {
    const std::string why = errnoText();
    ::close(fd);
    ::unlink(temp.c_str());
    return ioError("{} {}: {}", what, temp.string(), why);
  };
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail("write");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) return fail("fsync");
  ::close(fd);
  if (::rename(temp.c_str(), final_path.c_str()) != 0) {
    const std::string why = errnoText();
    ::unlink(temp.c_str());
    return ioError("cannot rename {} to {}: {}", temp.string(), path, why);
  }
  // The rename is durable only once the directory entry is.
  if (const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  return {};
}

Expected<std::vector<SessionRecord>> loadSessions(const std::string& path) {
  std::vector<SessionRecord> out;
  // Opened without blocking: a FIFO planted as sessions.json must not hang the start.
  auto fd = openRegularFileForReading(path, "sessions file");
  if (!fd) return fd.status().code() == Code::kNotFound ? Expected<std::vector<SessionRecord>>(out) : fd.status();
  std::string text;
  char buffer[65536];
  for (ssize_t n; (n = ::read(*fd, buffer, sizeof(buffer))) != 0;) {
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const std::string why = errnoText();
      ::close(*fd);
      return ioError("cannot read {}: {}", path, why);
    }
    text.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(*fd);
  nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) return invalidInput("{}: not a JSON object", path);
  const int file_version = j.value("version", 0);
  if (file_version != 1 && file_version != kSessionsSchemaVersion)
    return invalidInput("{}: unsupported sessions schema version {}", path, j.value("version", 0));
  if (!j.contains("scenes") || !j["scenes"].is_array()) return invalidInput("{}: 'scenes' must be an array", path);
  for (std::size_t i = 0; i < j["scenes"].size(); ++i) {
    const auto& s = j["scenes"][i];
    auto str = [&](const char* key) -> Expected<std::string> {
      if (!s.contains(key) || !s[key].is_string()) return invalidInput("{}: scenes[{}].{} must be a string", path, i, key);
      return s[key].get<std::string>();
    };
    SessionRecord r;
    auto id = str("id"), token = str("token"), name = str("name"), src = str("source_path"), label = str("source");
    for (const auto* e : {&id, &token, &name, &src, &label})
      if (!*e) return e->status();
    r.id = *id;
    r.token = *token;
    r.name = *name;
    r.source_path = *src;
    r.source_label = *label;
    if (!s.contains("params") || !s["params"].is_object()) return invalidInput("{}: scenes[{}].params missing", path, i);
    if (!s.contains("lights") || !s["lights"].is_object()) return invalidInput("{}: scenes[{}].lights missing", path, i);
    if (!s.contains("version") || !s["version"].is_number_unsigned())
      return invalidInput("{}: scenes[{}].version must be a non-negative integer", path, i);
    r.params = s["params"];
    r.lights = s["lights"];
    r.version = s["version"].get<std::uint64_t>();
    if (s.contains("scenarios")) {
      if (!s["scenarios"].is_object()) return invalidInput("{}: scenes[{}].scenarios must be an object", path, i);
      r.scenarios = s["scenarios"];
    }
    out.push_back(std::move(r));
  }
  return out;
}

Status saveSessions(const std::string& path, const std::vector<SessionRecord>& records) {
  nlohmann::ordered_json j;
  j["version"] = kSessionsSchemaVersion;
  j["scenes"] = nlohmann::ordered_json::array();
  for (const auto& r : records) {
    nlohmann::ordered_json s;
    s["id"] = r.id;
    s["token"] = r.token;
    s["name"] = r.name;
    s["source"] = r.source_label;
    s["source_path"] = r.source_path;
    s["params"] = r.params;
    s["lights"] = r.lights;
    s["version"] = r.version;
    if (!r.scenarios.empty()) s["scenarios"] = r.scenarios;
    j["scenes"].push_back(std::move(s));
  }
  return writeFileAtomic(path, j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n", 0600);
}

}  // namespace lightlink::service
