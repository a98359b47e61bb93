// fork/exec with bounded waits for the client integration tests.
#include "tests/client/process.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <sstream>
#include <thread>

namespace lightlink::testing {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

fs::path freshDir(const char* stem) {
  std::random_device rd;
  const fs::path p = fs::temp_directory_path() / (std::string(stem) + std::to_string(::getpid()) + "-" +
                                                  std::to_string(rd()));
  fs::create_directories(p);
  return p;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

pid_t spawn(const std::vector<std::string>& argv, const fs::path& out, const fs::path& err,
            const std::vector<std::string>& env) {
  std::vector<char*> args;
  std::vector<std::string> storage = argv;
  for (auto& a : storage) args.push_back(a.data());
  args.push_back(nullptr);
  std::vector<std::string> env_storage = env;
  const pid_t pid = ::fork();
  if (pid != 0) return pid;
  // Child: own process group, so a kill reaches anything it starts.
  ::setpgid(0, 0);
  const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (o >= 0) ::dup2(o, 1);
  if (e >= 0) ::dup2(e, 2);
  for (auto& kv : env_storage) ::putenv(kv.data());
  ::execv(args[0], args.data());
  ::_exit(127);
}

// waitpid with a deadline; returns the exit code, 128 + signal, or -1 on timeout.
int waitFor(pid_t pid, Clock::time_point deadline) {
  for (;;) {
    int status = 0;
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (r < 0) return -1;
    if (Clock::now() >= deadline) return -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

}  // namespace

CommandResult runCommand(const std::vector<std::string>& argv, std::chrono::seconds limit,
                         const std::vector<std::string>& env) {
  const fs::path dir = freshDir("lightlink-cmd-");
  CommandResult r;
  const pid_t pid = spawn(argv, dir / "out", dir / "err", env);
  r.exit_code = waitFor(pid, Clock::now() + limit);
  if (r.exit_code == -1) {
    r.timed_out = true;
    ::kill(-pid, SIGKILL);
    ::kill(pid, SIGKILL);
    waitFor(pid, Clock::now() + std::chrono::seconds(5));
  }
  r.out = slurp(dir / "out");
  r.err = slurp(dir / "err");
  std::error_code ec;
  fs::remove_all(dir, ec);
  return r;
}

fs::path clientTestCacheDir() {
  const fs::path p = fs::path(LIGHTLINK_BINARY_DIR) / "tests" / "client" / "artifact-cache";
  fs::create_directories(p);
  return p;
}

}  // namespace lightlink::testing
