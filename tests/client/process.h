// One-shot child processes for the client integration tests (the CLI, the Python example),
// each with a time limit so a hung daemon fails a test instead of hanging CI. The daemon
// itself is started with lightlink::client::LocalDaemon.
#pragma once

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

namespace lightlink::testing {

struct CommandResult {
  int exit_code = -1;   // -1: killed at the time limit
  std::string out, err;
  bool timed_out = false;
};

// Runs argv[0] with `argv` (no shell), environment plus `env` ("NAME=value"), capturing
// stdout and stderr; kills it after `limit`.
CommandResult runCommand(const std::vector<std::string>& argv, std::chrono::seconds limit,
                         const std::vector<std::string>& env = {});

// Where the client tests keep artifacts between test processes (ctest runs each TEST in its
// own process): the first one precomputes the scene, later ones reuse the artifact.
std::filesystem::path clientTestCacheDir();

}  // namespace lightlink::testing
