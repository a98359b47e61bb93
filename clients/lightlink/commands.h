// The subcommands of the `lightlink` CLI. main.cpp parses the command line (CLI11) into
// these argument structs and calls run*(); each returns a process exit code
// (exit_codes.h). Keeping parsing apart from doing lets tests call commands directly.
#pragma once

#include <string>

namespace lightlink::cli {

struct InspectArgs {
  std::string scene_path;
  bool json = false;
};
int runInspect(const InspectArgs& args);

}  // namespace lightlink::cli
