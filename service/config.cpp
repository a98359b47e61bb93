#include "service/config.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "service/auth.h"
#include "service/scene_roots.h"

namespace lightlink::service {
namespace {

Expected<std::string> readTokenFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return notFound("--token-file {}: cannot read", path);
  std::ostringstream text;
  text << in.rdbuf();
  std::string token = text.str();
  // One line; surrounding whitespace (a trailing newline) is not part of the token.
  const auto first = token.find_first_not_of(" \t\r\n");
  const auto last = token.find_last_not_of(" \t\r\n");
  if (first == std::string::npos) return invalidInput("--token-file {}: the file is empty", path);
  return token.substr(first, last - first + 1);
}

// Reads the JSON config file into `c`. Unknown keys are errors: a typo must not silently
// leave a security setting at its default.
Status applyConfigFile(const std::string& path, DaemonConfig& c) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return notFound("--config {}: cannot read", path);
  nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) return invalidInput("--config {}: not a JSON object", path);
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& key = it.key();
    const auto& v = it.value();
    auto str = [&](std::string& out) -> Status {
      if (!v.is_string()) return invalidInput("--config {}: '{}' must be a string", path, key);
      out = v.get<std::string>();
      return {};
    };
    auto integer = [&](auto& out) -> Status {
      if (!v.is_number_integer()) return invalidInput("--config {}: '{}' must be an integer", path, key);
      out = v.get<std::decay_t<decltype(out)>>();
      return {};
    };
    Status s;
    if (key == "listen") s = str(c.listen);
    else if (key == "port_file") s = str(c.port_file);
    else if (key == "cache_dir") s = str(c.cache_dir);
    else if (key == "scene_roots") {
      if (!v.is_array()) return invalidInput("--config {}: 'scene_roots' must be an array of directories", path);
      c.scene_roots.clear();
      for (const auto& e : v) {
        if (!e.is_string()) return invalidInput("--config {}: 'scene_roots' must be an array of strings", path);
        c.scene_roots.push_back(e.get<std::string>());
      }
    }
    else if (key == "token") s = str(c.token);  // a config file is not visible in ps, argv is
    else if (key == "allow_plaintext_token") {
      if (!v.is_boolean()) return invalidInput("--config {}: 'allow_plaintext_token' must be true or false", path);
      c.allow_plaintext_token = v.get<bool>();
    } else if (key == "cache_quota") {
      if (!v.is_number_unsigned()) return invalidInput("--config {}: 'cache_quota' must be a byte count", path);
      c.cache_quota = v.get<std::uint64_t>();
    }
    else if (key == "token_file") {
      std::string file;
      s = str(file);
      if (s) {
        auto t = readTokenFile(file);
        if (!t) return t.status();
        c.token = *t;
      }
    } else if (key == "tls_cert") s = str(c.tls_cert);
    else if (key == "tls_key") s = str(c.tls_key);
    else if (key == "backend") s = str(c.backend);
    else if (key == "log_format") {
      std::string f;
      s = str(f);
      if (s && f != "text" && f != "json")
        return invalidInput("--config {}: 'log_format' must be \"text\" or \"json\"", path);
      c.log_format = f == "json" ? LogFormat::kJson : LogFormat::kText;
    } else if (key == "log_level") s = str(c.log_level);
    else if (key == "log_file") s = str(c.log_file);
    else if (key == "max_streams_per_client") s = integer(c.max_streams_per_client);
    else if (key == "max_scenes") s = integer(c.max_scenes);
    else if (key == "max_image_pixels") s = integer(c.max_image_pixels);
    else if (key == "max_triangles") s = integer(c.max_triangles);
    else if (key == "max_texels") s = integer(c.max_texels);
    else if (key == "max_link_bytes") s = integer(c.max_link_bytes);
    else if (key == "chunk_bytes") s = integer(c.chunk_bytes);
    else if (key == "drain_seconds") {
      if (!v.is_number()) return invalidInput("--config {}: 'drain_seconds' must be a number", path);
      c.drain_seconds = v.get<double>();
    } else if (key == "session_idle_timeout") {
      if (!v.is_number()) return invalidInput("--config {}: 'session_idle_timeout' must be a number", path);
      c.session_idle_timeout_s = v.get<double>();
    } else if (key == "bounces") s = integer(c.relight_bounces);
    else if (key == "progressive") {
      if (!v.is_boolean()) return invalidInput("--config {}: 'progressive' must be true or false", path);
      c.progressive = v.get<bool>();
    }
    else if (key == "preview") {
      if (!v.is_boolean()) return invalidInput("--config {}: 'preview' must be true or false", path);
      c.preview = v.get<bool>();
    }
    else if (key == "shared_memory_dir") s = str(c.shared_memory_dir);
    else if (key == "restore_sessions") {
      if (!v.is_boolean()) return invalidInput("--config {}: 'restore_sessions' must be true or false", path);
      c.restore_sessions = v.get<bool>();
    } else return invalidInput("--config {}: unknown key '{}'", path, key);
    if (!s) return s;
  }
  return {};
}

// Declares every flag on `app`, bound to `c`. Called twice (see parseArgs).
void declareFlags(CLI::App& app, DaemonConfig& c, std::string& config_path, std::string& token_file,
                  std::string& argv_token, std::string& log_format, bool& no_restore, bool& no_shared_memory) {
  app.add_option("--config", config_path, "JSON config file; its keys are the flag names with '_' (flags override it)");
  app.add_option("--listen", c.listen,
                 "Address host:port to listen on; port 0 picks a free port. Anything but loopback requires --token")
      ->capture_default_str();
  app.add_option("--port-file", c.port_file, "Write the bound port (a decimal number) to this file once listening");
  app.add_option("--cache-dir", c.cache_dir,
                 "Directory for artifacts, inline scenes and sessions.json (required)");
  app.add_option("--scene-root", c.scene_roots,
                 "Directory under which OpenScene may open scenes by path (repeatable); none: uploads only")
      ->allow_extra_args(false);
  // Declared only to refuse it with a useful message: argv is visible to every user in ps.
  app.add_option("--token", argv_token,
                 "Refused: a token in argv is visible in ps; use --token-file or $LIGHTLINKD_TOKEN");
  app.add_option("--token-file", token_file,
                 "Read the bearer token clients must send ('authorization: Bearer <token>') from this file; "
                 "default: $LIGHTLINKD_TOKEN. At least 16 characters");
  app.add_flag("--allow-plaintext-token", c.allow_plaintext_token,
               "Allow a token on a non-loopback --listen without TLS (the token then crosses the network in clear)");
  app.add_option("--cache-quota", c.cache_quota,
                 "Bytes the cache's artifacts and inline scenes may take (suffixes KiB, MiB, GiB...; 0 = no limit); "
                 "closed scenes' files are evicted least recently used first")
      ->transform(CLI::AsSizeValue(false))
      ->default_str("10GiB");
  app.add_option("--tls-cert", c.tls_cert, "PEM server certificate chain: serve TLS (with --tls-key)");
  app.add_option("--tls-key", c.tls_key, "PEM private key of --tls-cert");
  app.add_option("--backend", c.backend, "Default relight backend for OpenScene's BACKEND_AUTO: auto | cpu | gpu")
      ->capture_default_str();
  app.add_option("--log-format", log_format, "Log lines as 'text' or 'json' (one object per line)")
      ->capture_default_str();
  app.add_option("--log-level", c.log_level, "trace | debug | info | warn | error")->capture_default_str();
  app.add_option("--log-file", c.log_file, "Append logs to this file instead of stderr");
  app.add_option("--max-streams-per-client", c.max_streams_per_client,
                 "Concurrent server streams one client connection (gRPC peer) may hold; more get RESOURCE_EXHAUSTED")
      ->capture_default_str();
  app.add_option("--max-scenes", c.max_scenes, "Resident scenes at most; OpenScene beyond gets RESOURCE_EXHAUSTED")
      ->capture_default_str();
  app.add_option("--max-image-pixels", c.max_image_pixels,
                 "Pixels of one scene image (from its header, before decoding); more: RESOURCE_EXHAUSTED")
      ->capture_default_str();
  app.add_option("--max-triangles", c.max_triangles, "Triangles of a scene after instancing; more: RESOURCE_EXHAUSTED")
      ->capture_default_str();
  app.add_option("--max-texels", c.max_texels, "Lightmap texels (width x height) of a scene; more: RESOURCE_EXHAUSTED")
      ->capture_default_str();
  app.add_option("--max-link-bytes", c.max_link_bytes,
                 "Estimated link memory of one precompute (0 = half the physical memory); more: RESOURCE_EXHAUSTED")
      ->capture_default_str();
  app.add_option("--chunk-bytes", c.chunk_bytes, "Payload bytes per Chunk message (4096 .. 1048576)")
      ->capture_default_str();
  app.add_option("--drain-seconds", c.drain_seconds,
                 "On SIGTERM/SIGINT: seconds open streams get to finish before the server stops")
      ->capture_default_str();
  app.add_option("--session-idle-timeout", c.session_idle_timeout_s,
                 "Seconds a scene may go without a client call naming it (and without a Subscribe stream) before "
                 "the daemon closes it and forgets it (0 = never)")
      ->capture_default_str();
  app.add_option("--bounces", c.relight_bounces, "Indirect bounce cap of every relight (0..256); relights stop earlier once converged")->capture_default_str();
  app.add_flag("--progressive", c.progressive,
               "Publish each light change after one bounce iteration started from the last solution, then more "
               "iterations as new versions until converged");
  app.add_option("--preview", c.preview,
                 "Instant preview: publish a grid lit without links as a new scene's first version while its "
                 "links are computed (on | off; OpenScene's `preview` overrides it per scene)")
      ->capture_default_str();
  app.add_flag("--no-restore", no_restore, "Do not re-open the scenes recorded in <cache-dir>/sessions.json");
  app.add_option("--shared-memory-dir", c.shared_memory_dir,
                 "Base directory (a memory file system) for results handed to clients on this machine through "
                 "shared memory; empty turns that delivery off")
      ->capture_default_str();
  app.add_flag("--no-shared-memory", no_shared_memory,
               "Send every result on the stream, also to clients on this machine that ask for shared memory");
}

}  // namespace

bool DaemonConfig::loopbackOnly() const { return isLoopbackListen(listen); }

Status DaemonConfig::validate() const {
  if (cache_dir.empty()) return invalidInput("--cache-dir: required (artifacts and sessions.json live there)");
  if (listen.empty() || listen.rfind(':') == std::string::npos)
    return invalidInput("--listen '{}': expected host:port", listen);
  if (!loopbackOnly() && token.empty())
    return invalidInput("--listen '{}' is not a loopback address: give a token with --token-file or ${} (refusing "
                        "to serve an unauthenticated daemon beyond this machine)",
                        listen, kTokenEnvVar);
  if (!token.empty() && token.size() < kMinTokenLength)
    return invalidInput("token: {} characters is too short, at least {} are required (e.g. `openssl rand -hex 16`)",
                        token.size(), kMinTokenLength);
  if (tls_cert.empty() != tls_key.empty()) return invalidInput("--tls-cert and --tls-key: give both or neither");
  if (!token.empty() && !loopbackOnly() && tls_cert.empty() && !allow_plaintext_token)
    return invalidInput("--listen '{}' is not a loopback address and TLS is off: the token would cross the network "
                        "in clear; give --tls-cert and --tls-key, or --allow-plaintext-token to accept that",
                        listen);
  if (auto roots = SceneRoots::resolve(scene_roots); !roots) return roots.status();
  if (backend != "auto" && backend != "cpu" && backend != "gpu")
    return invalidInput("--backend '{}' must be auto, cpu or gpu", backend);
  if (log_level != "trace" && log_level != "debug" && log_level != "info" && log_level != "warn" &&
      log_level != "error")
    return invalidInput("--log-level '{}' must be trace, debug, info, warn or error", log_level);
  if (max_streams_per_client < 1 || max_streams_per_client > 100000)
    return invalidInput("--max-streams-per-client {} is out of range (1..100000)", max_streams_per_client);
  if (max_scenes < 1 || max_scenes > 1024) return invalidInput("--max-scenes {} is out of range (1..1024)", max_scenes);
  if (max_image_pixels < 1 || max_triangles < 1 || max_texels < 1)
    return invalidInput("--max-image-pixels, --max-triangles and --max-texels must be >= 1");
  if (chunk_bytes < 4096 || chunk_bytes > (1u << 20))
    return invalidInput("--chunk-bytes {} is out of range (4096..1048576)", chunk_bytes);
  if (!std::isfinite(drain_seconds) || drain_seconds < 0.0 || drain_seconds > 3600.0)
    return invalidInput("--drain-seconds {} is out of range (0..3600)", drain_seconds);
  if (!std::isfinite(session_idle_timeout_s) || session_idle_timeout_s < 0.0 || session_idle_timeout_s > 31536000.0)
    return invalidInput("--session-idle-timeout {} is out of range (0..31536000 seconds, 0 = never)",
                        session_idle_timeout_s);
  if (!shared_memory_dir.empty() && shared_memory_dir.front() != '/')
    return invalidInput("--shared-memory-dir '{}' must be an absolute path", shared_memory_dir);
  if (relight_bounces < 0 || relight_bounces > 256)
    return invalidInput("--bounces {} is out of range (0..256)", relight_bounces);
  return {};
}

ParsedArgs parseArgs(int argc, char** argv) {
  ParsedArgs out;
  auto run = [&](DaemonConfig& c, std::string& config_path) -> bool {
    CLI::App app{"lightlinkd: keeps precomputed scenes resident and relights them over gRPC (lightlink.v1)"};
    app.set_version_flag("--version", "lightlinkd 0.1.0");
    std::string token_file, argv_token, log_format = c.log_format == LogFormat::kJson ? "json" : "text";
    bool no_restore = false, no_shared_memory = false;
    declareFlags(app, c, config_path, token_file, argv_token, log_format, no_restore, no_shared_memory);
    try {
      app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      std::ostringstream os, es;
      out.exit_now = true;
      out.exit_code = app.exit(e, os, es);
      out.output = os.str() + es.str();
      return false;
    }
    if (log_format != "text" && log_format != "json") {
      out.exit_now = true;
      out.exit_code = 2;
      out.output = "lightlinkd: --log-format '" + log_format + "' must be text or json\n";
      return false;
    }
    if (app.count("--token") > 0) {
      out.exit_now = true;
      out.exit_code = 2;
      out.output = fmt::format(
          "lightlinkd: --token: a token on the command line is visible to every user of this machine (ps); give it "
          "with --token-file FILE, the environment variable {}, or the config file key \"token\"\n",
          kTokenEnvVar);
      return false;
    }
    c.log_format = log_format == "json" ? LogFormat::kJson : LogFormat::kText;
    if (no_restore) c.restore_sessions = false;
    if (no_shared_memory) c.shared_memory_dir.clear();
    if (!token_file.empty()) {
      auto t = readTokenFile(token_file);
      if (!t) {
        out.exit_now = true;
        out.exit_code = 2;
        out.output = "lightlinkd: " + t.status().message() + "\n";
        return false;
      }
      c.token = *t;
    }
    return true;
  };
  // First pass: find --config (and handle --help/--version). Second pass: flags over the file.
  DaemonConfig probe;
  std::string config_path;
  if (!run(probe, config_path)) return out;
  if (config_path.empty()) {
    out.config = probe;
  } else {
    DaemonConfig base;
    if (Status s = applyConfigFile(config_path, base); !s) {
      out.exit_now = true;
      out.exit_code = 2;
      out.output = "lightlinkd: " + s.message() + "\n";
      return out;
    }
    std::string ignored;
    if (!run(base, ignored)) return out;
    out.config = base;
  }
  // The environment is the token's last source: a file (flag or config) or the config's
  // own key take precedence.
  if (out.config.token.empty())
    if (const char* env = std::getenv(kTokenEnvVar); env != nullptr && *env != '\0') out.config.token = env;
  if (Status s = out.config.validate(); !s) {
    out.exit_now = true;
    out.exit_code = 2;
    out.output = "lightlinkd: " + s.message() + "\n";
  }
  return out;
}

}  // namespace lightlink::service
