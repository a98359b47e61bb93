// Gateway: the browser viewer's way to a daemon (docs/web.md "Live mode"). A small HTTP
// server on loopback that serves the viewer's page and the bake folders under one root, and
// turns a bake into a live scene: it opens the bake's scene on the daemon (the same
// precompute, so the same lightmap atlas), subscribes to its results and writes each new
// version as the files a bake writes, announced to pages over Server-Sent Events; light
// changes and scenario blends come back as JSON POSTs and go to the daemon as UpdateLights
// and UseScenarios. The daemon stays gRPC-only: everything HTTP lives here.
//
// Browsers can be made to talk to loopback by any web page, so requests whose Host is not
// this loopback address (DNS rebinding) and POSTs that are not `application/json` from this
// origin (cross-site requests) are refused; files are served only from inside the two roots.
#pragma once

#include <memory>
#include <string>

#include "clients/client/client.h"
#include "core/common/status.h"

namespace lightlink::gateway {

struct GatewayOptions {
  std::string listen = "127.0.0.1:8080";  // host:port, a loopback host; port 0 picks a free one
  std::string web_root;     // the built viewer (index.html, viewer.js), served at /
  std::string files_root;   // bake folders, served under /files/ and openable live
  std::string port_file;    // written (atomically) with the bound port
  client::ConnectOptions daemon;  // how the gateway reaches the daemon
  std::string work_dir;     // where live versions' files go; empty: a fresh folder under $TMPDIR
  // Newest versions kept per live scene (older folders removed): the one a page may still be
  // reading, one more, and the one just written. Each is the whole lightmap and grid.
  int keep_versions = 3;
};

class Gateway {
 public:
  // Checks the options, connects (lazily) to the daemon and starts listening.
  static Expected<std::unique_ptr<Gateway>> start(const GatewayOptions& options);
  ~Gateway();
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  int port() const;
  // Ends the event streams, closes the live scenes on the daemon, stops listening and removes
  // the work folder. Idempotent; the destructor calls it.
  void stop();

  struct Impl;

 private:
  explicit Gateway(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace lightlink::gateway
