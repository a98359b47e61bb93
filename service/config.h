// DaemonConfig: everything lightlinkd is told at start, from flags and an optional JSON
// config file (`--config FILE`; flags given on the command line override the file).
//
// Security defaults are conservative: the daemon listens on loopback; a non-loopback
// `--listen` without a bearer token refuses to start, and so does one with a token but
// without TLS (unless `--allow-plaintext-token`). The token comes from `--token-file`, the
// environment (LIGHTLINKD_TOKEN) or the config file, never from argv (visible in `ps`),
// and has at least kMinTokenLength characters. TLS is used when a certificate and key are
// given (both or neither). Limits bound what
// one client can make the daemon hold (streams, scenes, message sizes). The JSON keys are
// the flag names without the dashes, with '_' for '-' (docs/service.md lists them).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/common/status.h"
#include "core/relight/relight.h"

namespace lightlink::service {

enum class LogFormat { kText, kJson };

// Shortest daemon bearer token accepted at start.
inline constexpr std::size_t kMinTokenLength = 16;
// Environment variable the daemon reads its bearer token from (when no file names one).
inline constexpr const char* kTokenEnvVar = "LIGHTLINKD_TOKEN";

struct DaemonConfig {
  std::string listen = "127.0.0.1:50051";  // host:port; port 0 picks a free one
  std::string port_file;                   // written (atomically) with the bound port
  std::string cache_dir;                   // artifacts, inline scenes, sessions.json
  std::vector<std::string> scene_roots;    // OpenScene by path only under these (none: uploads only)
  std::string token;                       // daemon bearer token (--token-file, $LIGHTLINKD_TOKEN, config)
  bool allow_plaintext_token = false;      // a token on a non-loopback address without TLS
  std::string tls_cert, tls_key;           // PEM files: serve TLS when both are set
  std::string backend = "auto";            // default relight backend: auto | cpu | gpu
  LogFormat log_format = LogFormat::kText;
  std::string log_level = "info";          // trace | debug | info | warn | error
  std::string log_file;                    // empty: stderr
  int max_streams_per_client = 32;         // concurrent server streams per gRPC peer
  int max_scenes = 16;                     // resident scenes
  // Per-OpenScene budgets, checked before the work (docs/service.md "Limits"); over one:
  // RESOURCE_EXHAUSTED naming it. Defaults: scene::LoadOptions, precompute::PrecomputeLimits.
  std::uint64_t max_image_pixels = std::uint64_t(8192) * 8192;  // one decoded image
  std::uint64_t max_triangles = 20'000'000;                     // after instancing
  std::uint64_t max_texels = std::uint64_t(4096) * 4096;        // lightmap width x height
  std::uint64_t max_link_bytes = 0;                             // 0 = half the physical memory
  std::size_t chunk_bytes = 1 << 20;       // data bytes per Chunk message (<= 1 MiB)
  std::size_t max_receive_bytes = 64u << 20;  // largest request message
  std::size_t max_send_bytes = 4u << 20;      // largest response message
  double drain_seconds = 5.0;              // SIGTERM: how long open streams may take to finish
  // A scene that no client call named for this long (and with no Subscribe stream open) is
  // closed, as CloseScene would: its memory is freed and it leaves sessions.json. 0: never.
  double session_idle_timeout_s = 1800.0;
  int relight_bounces = relight::RelightOptions{}.max_bounces;  // relight options of every scene
  bool progressive = false;                // one warm iteration first, then more as new versions
  // Instant preview: a new scene's first version is a grid lit without links (core/preview),
  // published as soon as the scene is loaded; the linked result follows (OpenSceneRequest.preview).
  bool preview = true;
  bool restore_sessions = true;            // re-open the scenes of sessions.json at start
  // Bytes the cache's artifacts and inline scenes may take; closed scenes' files are
  // evicted least recently used first beyond it (service/cache_quota.h). 0: no limit.
  std::uint64_t cache_quota = 10ull << 30;
  // Base directory (a memory file system) for results delivered through shared memory to
  // clients on this machine (service/shared_results.h); empty: that delivery is off.
  std::string shared_memory_dir = "/dev/shm";

  // Host part of `listen` is a loopback address (127.0.0.0/8, ::1, localhost).
  bool loopbackOnly() const;
  // Cross-field checks (token when exposed, TLS pair, ranges).
  Status validate() const;
};

// Outcome of parsing argv: run with `config`, or exit with `exit_code` after printing
// `output` (help, version or an error message).
struct ParsedArgs {
  DaemonConfig config;
  bool exit_now = false;
  int exit_code = 0;
  std::string output;
};

// Parses lightlinkd's flags (and the config file they name). `argv[0]` is the program name.
ParsedArgs parseArgs(int argc, char** argv);

}  // namespace lightlink::service
