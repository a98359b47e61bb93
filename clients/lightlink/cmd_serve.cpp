// `lightlink serve`: the daemon in this process, so one binary is enough on a workstation.
// The arguments are lightlinkd's (docs/clients.md), passed through unchanged, plus the web
// gateway's (docs/web.md "Live mode"): with --http the page and the bakes under --files are
// served on loopback, and pages can make a bake live on this daemon.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "clients/gateway/gateway.h"
#include "clients/lightlink/commands.h"
#include "service/daemon.h"

#ifndef LIGHTLINK_WEB_VIEWER_DIR
#define LIGHTLINK_WEB_VIEWER_DIR ""
#endif

namespace lightlink::cli {

namespace {

struct GatewayFlags {
  bool on = false;
  gateway::GatewayOptions options;
};

// Takes the gateway's flags (--http H:P, --http-port-file F, --web-root DIR, --files DIR;
// `--flag value` or `--flag=value`) out of `args`; the rest are the daemon's.
Expected<GatewayFlags> takeGatewayFlags(std::vector<std::string>& args) {
  GatewayFlags g;
  g.options.web_root = LIGHTLINK_WEB_VIEWER_DIR;
  std::vector<std::string> rest;
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::string name = args[i], value;
    const auto eq = name.find('=');
    if (eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
    }
    std::string* target = name == "--http"             ? &g.options.listen
                          : name == "--http-port-file" ? &g.options.port_file
                          : name == "--web-root"       ? &g.options.web_root
                          : name == "--files"          ? &g.options.files_root
                                                       : nullptr;
    if (!target) {
      rest.push_back(args[i]);
      continue;
    }
    if (eq == std::string::npos) {
      if (i + 1 >= args.size()) return invalidInput("{}: needs a value", name);
      value = args[++i];
    }
    *target = value;
    if (name == "--http") g.on = true;
  }
  if (!g.on && (!g.options.port_file.empty() || !g.options.files_root.empty()))
    return invalidInput("--files and --http-port-file go with --http HOST:PORT");
  args = std::move(rest);
  return g;
}

}  // namespace

int runServe(const std::vector<std::string>& in_args) {
  std::vector<std::string> args = in_args;
  auto gw = takeGatewayFlags(args);
  if (!gw) {
    std::fprintf(stderr, "lightlink serve: %s\n", gw.status().message().c_str());
    return 2;
  }
  std::vector<std::string> storage;
  storage.reserve(args.size() + 1);
  storage.push_back("lightlink serve");
  storage.insert(storage.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : storage) argv.push_back(a.data());
  argv.push_back(nullptr);

  service::DaemonHooks hooks;
  std::unique_ptr<gateway::Gateway> gateway;
  if (gw->on) {
    hooks.on_listening = [&](const service::DaemonConfig& config, int port) -> Status {
      if (!config.tls_cert.empty())
        return invalidInput("--http: the gateway talks to the daemon in plaintext over loopback; run it with a "
                            "daemon without --tls-cert");
      gw->options.daemon.target = fmt::format("127.0.0.1:{}", port);
      gw->options.daemon.bearer_token = config.token;
      auto started = gateway::Gateway::start(gw->options);
      if (!started) return started.status();
      gateway = std::move(started).value();
      std::fprintf(stderr, "lightlink serve: the viewer is at http://%s/\n",
                   fmt::format("{}:{}", gw->options.listen.substr(0, gw->options.listen.rfind(':')), gateway->port()).c_str());
      return Status::ok();
    };
    hooks.on_draining = [&] {
      if (gateway) gateway->stop();
    };
  }
  return service::runDaemon(int(storage.size()), argv.data(), hooks);
}

}  // namespace lightlink::cli
