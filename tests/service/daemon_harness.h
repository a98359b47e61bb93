// Test harness for the daemon: real lightlinkd processes on loopback (port 0 + port file,
// a private cache dir), gRPC clients with deadlines, and a reader that reassembles results
// (header + chunks, full or delta) while checking that none is torn.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "clients/client/local_daemon.h"
#include "proto/lightlink.grpc.pb.h"

namespace lightlink::testing {

namespace v1 = lightlink::v1;
// gRPC's generated client class for the Lightlink service (its own name for it is Stub).
using LightlinkRpc = v1::Lightlink::Stub;

// A lightlinkd for one test: the client library's LocalDaemon (one fork/exec and port-file
// wait for the tests, the benchmark and tools), here reporting start failures through
// ok() / error() and killed (SIGKILL, no drain) at the end of the test.
class DaemonProcess {
 public:
  // Starts lightlinkd with `--listen 127.0.0.1:0 --port-file ... --cache-dir cache_dir` and
  // `extra` flags; waits (bounded) for the port. Check ok() / error(). Unless `extra` has a
  // --scene-root or --config, the source tree and cache_dir's parent are the scene roots;
  // unless it has --preview or --config, the instant preview is off (--preview off).
  DaemonProcess(const std::filesystem::path& cache_dir, std::vector<std::string> extra = {});
  ~DaemonProcess();  // SIGKILL if still running

  bool ok() const { return daemon_ != nullptr; }
  const std::string& error() const { return error_; }
  int port() const { return daemon_ ? daemon_->port() : 0; }
  pid_t pid() const { return daemon_ ? daemon_->pid() : -1; }
  std::string target() const { return daemon_ ? daemon_->target() : std::string(); }
  std::string log() const { return daemon_ ? daemon_->log() : error_; }

  // Sends `sig` and waits up to `limit` for the exit; returns the exit code, 128 + signal
  // when killed by one, -1 on timeout.
  int signalAndWait(int sig, std::chrono::milliseconds limit = std::chrono::milliseconds(10000));

  // A new connection to the daemon, waited for (up to `connect_wait`) before it is returned,
  // as the client library's Client::connect does: a call on a channel whose first connect
  // attempt failed fails at once (UNAVAILABLE) instead of retrying. Without the wait, one
  // of Daemon.TwentyConcurrentClients...'s 20 first calls failed that way in about 1 of 40
  // runs ("failed to connect to all addresses" on 127.0.0.1). A test that expects the
  // connection to fail passes 0.
  std::unique_ptr<LightlinkRpc> rpc(std::chrono::milliseconds connect_wait = std::chrono::milliseconds(10000)) const;
  std::shared_ptr<grpc::Channel> channel(std::chrono::milliseconds connect_wait = std::chrono::milliseconds(10000)) const;

 private:
  std::unique_ptr<client::LocalDaemon> daemon_;
  std::string error_;
};

// Runs a lightlinkd to completion with `args` (no port wait); returns the exit code (-1 when
// it was still running at `limit` and was killed).
int runDaemonToExit(const std::vector<std::string>& args, std::string* output,
                    std::chrono::milliseconds limit = std::chrono::milliseconds(10000));

// A context with a deadline `ms` from now (and a bearer token when given).
std::unique_ptr<grpc::ClientContext> context(int ms = 20000, const std::string& bearer = "");

// OpenScene to completion. Fills `opened` and the progress stages seen.
grpc::Status openScene(LightlinkRpc& rpc, const v1::OpenSceneRequest& request, v1::SceneOpened* opened,
                       std::vector<std::string>* stages = nullptr, const std::string& bearer = "",
                       int deadline_ms = 60000);

// The small Cornell box request every service test uses (draft preset, a tiny grid).
v1::OpenSceneRequest cornellRequest();

// One result, reassembled.
struct Result {
  v1::ResultHeader header;
  std::map<int, std::string> payloads;  // by v1::Payload
  std::size_t chunks = 0;
};

// Reads results from a stream. Full results are reassembled; delta results are applied to
// the previous one (the returned Result holds the updated full payloads). Any torn result
// (chunks beyond the header's payload_bytes, offsets out of order, a header mid-result)
// is reported through `error`.
class ResultReader {
 public:
  explicit ResultReader(grpc::ClientReader<v1::ResultMessage>* reader) : reader_(reader) {}
  // False at the end of the stream or on a protocol error (then error() is set).
  bool next(Result& out);
  const std::string& error() const { return error_; }

 private:
  grpc::ClientReader<v1::ResultMessage>* reader_;
  std::optional<Result> previous_;
  std::string error_;
};

// Reads exactly one result from a unary-like stream (Relight, GetTextures) and its status.
grpc::Status readOne(grpc::ClientReader<v1::ResultMessage>* reader, Result& out, std::string* error);

// Decodes a half/float payload into floats.
std::vector<float> decodeValues(const std::string& bytes, v1::Precision precision);

}  // namespace lightlink::testing
