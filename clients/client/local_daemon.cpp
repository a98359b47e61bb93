// LocalDaemon: fork/exec lightlinkd, port file, bounded waits.
#include "clients/client/local_daemon.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <sstream>
#include <thread>

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
  fs::create_directories(cache, ec);
  if (ec) return ioError("{}: cannot create cache directory: {}", cache.string(), ec.message());

  std::vector<std::string> args = {o.binary};
  args.insert(args.end(), o.prefix.begin(), o.prefix.end());
  args.insert(args.end(), {"--listen", "127.0.0.1:0", "--port-file", (d->dir_ / "port").string(), "--cache-dir",
                           cache.string()});
  args.insert(args.end(), o.extra.begin(), o.extra.end());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::string out = (d->dir_ / "stdout").string(), err = (d->dir_ / "stderr").string();

  const pid_t pid = ::fork();
  if (pid < 0) return ioError("fork failed starting {}", o.binary);
  if (pid == 0) {
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

std::string LocalDaemon::log() const { return slurp(dir_ / "stderr") + slurp(dir_ / "stdout"); }

LocalDaemon::~LocalDaemon() {
  stop();
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

}  // namespace lightlink::client
