// SharedResults: results handed to clients on the daemon's machine through files in shared
// memory instead of over the socket (proto SharedResult, docs/service.md "Shared-memory
// delivery").
//
// Fifty game clients polling one 1 MB lightmap over loopback TCP move 50 MB per version
// through the kernel twice (send and receive copies) and through 100 threads' wake-ups: tens
// of ms per version beyond the relight on 2 cores (bench/service, 50 clients). A
// client on the same machine can instead read the bytes the daemon wrote once: the daemon
// writes a result's chunk messages for a spec to one immutable file, per result and spec, and
// answers each asking client with a header naming it. The file holds exactly the chunk
// messages the stream would carry, so the client decodes them with the same code.
//
// Files live in a directory of this daemon's own (mode 0700, created on first use under the
// configured base, /dev/shm by default), named by a counter. Each scene keeps the files of
// its kKeepResults newest results and at most kMaxFilesPerScene files; older ones are
// removed, a closed scene's at once, and the directory when the daemon exits. A client that
// finds a file gone asks again on the stream. Directories left by a daemon that was killed
// are removed by the next one that starts with the same base (the pid in the name is gone).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include <grpcpp/support/byte_buffer.h>

#include "core/common/status.h"
#include "proto/shared_result_format.h"
#include "service/snapshot.h"

namespace lightlink::service {

// Removes `base`/lightlinkd-<pid>-* directories whose daemon process no longer exists.
// Returns how many it removed.
int removeStaleSharedDirs(const std::string& base);

class SharedResults {
 public:
  static constexpr std::size_t kKeepResults = 4;        // newest results per scene kept on disk
  static constexpr std::size_t kMaxFilesPerScene = 32;  // across specs

  // Delivery is off when `base` is empty. The directory is made on first use.
  explicit SharedResults(std::string base);
  ~SharedResults();  // removes the directory and everything in it
  SharedResults(const SharedResults&) = delete;
  SharedResults& operator=(const SharedResults&) = delete;

  bool enabled() const { return !base_.empty(); }

  // The header message to send for `snap` under `spec` (wire: its full wire form, messages[0]
  // the header, the rest the chunks): the same header with `shared` naming a file that holds
  // the chunk messages. The file is written on the first call for (scene, result, spec,
  // chunk bytes) and shared by every later caller. An error (no space, no directory) leaves
  // the caller to send the result on the stream.
  Expected<std::shared_ptr<const grpc::ByteBuffer>> header(const Snapshot& snap, const SpecKey& spec,
                                                           std::size_t chunk_bytes, const WireResult& wire);

  // Removes the files of a scene (closed).
  void dropScene(const std::string& scene_id);

  // The directory holding the files; empty until the first file is written.
  std::string directory() const;
  // Files currently on disk (all scenes), and their bytes.
  std::size_t fileCount() const;
  std::uint64_t byteCount() const;

 private:
  struct Entry {
    std::uint64_t sequence = 0;
    SpecKey spec;
    std::size_t chunk_bytes = 0;
    std::string path;
    std::uint64_t bytes = 0;  // the file's size
    std::shared_ptr<const grpc::ByteBuffer> header;
  };
  Status ensureDirectory();  // under mutex_
  Expected<Entry> write(const Snapshot& snap, const SpecKey& spec, std::size_t chunk_bytes,
                        const WireResult& wire);  // under mutex_
  void trim(std::deque<Entry>& files);  // under mutex_
  static std::size_t distinctResults(const std::deque<Entry>& files);  // results among a scene's files
  // True when a scene already keeps kKeepResults results, all newer than `sequence`.
  static bool olderThanKept(const std::deque<Entry>& files, std::uint64_t sequence);

  const std::string base_;
  mutable std::mutex mutex_;
  std::string dir_;
  std::uint64_t counter_ = 0;
  std::map<std::string, std::deque<Entry>> by_scene_;  // oldest first
};

}  // namespace lightlink::service
