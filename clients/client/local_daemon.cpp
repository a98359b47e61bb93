// LocalDaemon: fork/exec lightlinkd, port file, bounded waits.
#include "clients/client/local_daemon.h"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include <fmt/ranges.h>

#include "core/common/private_files.h"

namespace lightlink::client {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// waitpid with a deadline: exit code, 128 + signal, or -1 when still running at the deadline.
int waitUntil(pid_t pid, Clock::time_point deadline) {
  for (;;) {
    int status = 0;
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (r < 0 || Clock::now() >= deadline) return -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

}  // namespace

Expected<std::unique_ptr<LocalDaemon>> LocalDaemon::start(const Options& o) {
  if (o.binary.empty() || !fs::exists(o.binary)) return notFound("{}: no lightlinkd binary there", o.binary);
  std::unique_ptr<LocalDaemon> d(new LocalDaemon());
  std::random_device rd;
  d->dir_ = fs::temp_directory_path() / ("lightlinkd-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
  std::error_code ec;
  fs::create_directories(d->dir_, ec);
  if (ec) return ioError("{}: cannot create: {}", d->dir_.string(), ec.message());
  const fs::path cache = o.cache_dir.empty() ? d->dir_ / "cache" : o.cache_dir;
  // Private, as lightlinkd itself would create it (it never changes an existing one's mode).
  if (Status s = createPrivateDirectories(cache.string()); !s) return ioError("cache directory: {}", s.message());

  std::vector<std::string> args = {o.binary};
  args.insert(args.end(), o.prefix.begin(), o.prefix.end());
  args.insert(args.end(), {"--listen", "127.0.0.1:0", "--port-file", (d->dir_ / "port").string(), "--cache-dir",
                           cache.string()});
  args.insert(args.end(), o.extra.begin(), o.extra.end());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::string out = (d->dir_ / "stdout").string(), err = (d->dir_ / "stderr").string();

  // The CPU set is built before fork: the child of a threaded parent only makes plain
  // system calls until exec.
  cpu_set_t cpus;
  CPU_ZERO(&cpus);
  for (int c : o.cpus) {
    if (c < 0 || c >= CPU_SETSIZE) return invalidInput("cpus: {} is not a CPU number", c);
    CPU_SET(c, &cpus);
  }
  const pid_t pid = ::fork();
  if (pid < 0) return ioError("fork failed starting {}", o.binary);
  if (pid == 0) {
    if (!o.cpus.empty() && ::sched_setaffinity(0, sizeof(cpus), &cpus) != 0) ::_exit(126);
    const int fo = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int fe = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fo >= 0) ::dup2(fo, 1);
    if (fe >= 0) ::dup2(fe, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  d->pid_ = pid;
  const auto deadline = Clock::now() + o.start_timeout;
  while (Clock::now() < deadline) {
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      d->pid_ = -1;
      return ioError("{} exited before listening ({}): {}", o.binary,
                     WIFEXITED(status) ? fmt::format("exit code {}", WEXITSTATUS(status))
                                       : fmt::format("signal {}", WTERMSIG(status)),
                     d->log());
    }
    std::ifstream in(d->dir_ / "port");
    int port = 0;
    if (in >> port && port > 0) {
      d->port_ = port;
      return d;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const std::string log = d->log();
  d->stop();
  return ioError("{} did not write its port file within {} ms: {}", o.binary, o.start_timeout.count(), log);
}

int LocalDaemon::stop(std::chrono::milliseconds limit) {
  if (pid_ <= 0) return -1;
  ::kill(pid_, SIGTERM);
  int code = waitUntil(pid_, Clock::now() + limit);
  if (code == -1) {
    ::kill(pid_, SIGKILL);
    code = waitUntil(pid_, Clock::now() + std::chrono::seconds(5));
  }
  pid_ = -1;
  return code;
}

int LocalDaemon::signalAndWait(int sig, std::chrono::milliseconds limit) {
  if (pid_ <= 0) return -1;
  ::kill(pid_, sig);
  const int code = waitUntil(pid_, Clock::now() + limit);
  if (code != -1) pid_ = -1;
  return code;
}

std::string LocalDaemon::log() const { return slurp(dir_ / "stderr") + slurp(dir_ / "stdout"); }

LocalDaemon::~LocalDaemon() {
  stop();
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

Expected<std::vector<int>> parseCpuList(std::string_view list) {
  std::vector<int> cpus;
  const int limit = CPU_SETSIZE;
  std::size_t pos = 0;
  auto number = [&](std::string_view part, std::string_view text) -> Expected<int> {
    int v = 0;
    if (text.empty() || text.size() > 5) return invalidInput("cpu list '{}': '{}' is not a CPU number", list, part);
    for (char c : text) {
      if (c < '0' || c > '9') return invalidInput("cpu list '{}': '{}' is not a CPU number", list, part);
      v = v * 10 + (c - '0');
    }
    if (v >= limit) return invalidInput("cpu list '{}': CPU {} is beyond {}", list, v, limit - 1);
    return v;
  };
  while (pos <= list.size()) {
    const std::size_t comma = list.find(',', pos);
    const std::string_view part = list.substr(pos, comma == std::string_view::npos ? list.npos : comma - pos);
    const std::size_t dash = part.find('-');
    auto lo = number(part, part.substr(0, dash));
    if (!lo) return lo.status();
    int hi_v = *lo;
    if (dash != std::string_view::npos) {
      auto hi = number(part, part.substr(dash + 1));
      if (!hi) return hi.status();
      if (*hi < *lo) return invalidInput("cpu list '{}': range '{}' runs backwards", list, part);
      hi_v = *hi;
    }
    for (int c = *lo; c <= hi_v; ++c) cpus.push_back(c);
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  std::sort(cpus.begin(), cpus.end());
  cpus.erase(std::unique(cpus.begin(), cpus.end()), cpus.end());
  return cpus;
}

Status pinCurrentThread(const std::vector<int>& cpus) {
  cpu_set_t set;
  CPU_ZERO(&set);
  for (int c : cpus)
    if (c >= 0 && c < CPU_SETSIZE) CPU_SET(c, &set);
  if (::sched_setaffinity(0, sizeof(set), &set) != 0)
    return ioError("sched_setaffinity: cannot run on CPUs {} (not on this machine or not allowed)",
                   fmt::join(cpus, ","));
  return {};
}

}  // namespace lightlink::client
