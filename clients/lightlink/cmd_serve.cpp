// `lightlink serve`: the daemon in this process, so one binary is enough on a workstation.
// The arguments are lightlinkd's (docs/clients.md), passed through unchanged.
#include <string>
#include <vector>

#include "clients/lightlink/commands.h"
#include "service/daemon.h"

namespace lightlink::cli {

int runServe(const std::vector<std::string>& args) {
  std::vector<std::string> storage;
  storage.reserve(args.size() + 1);
  storage.push_back("lightlink serve");
  storage.insert(storage.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : storage) argv.push_back(a.data());
  argv.push_back(nullptr);
  return service::runDaemon(int(storage.size()), argv.data());
}

}  // namespace lightlink::cli
