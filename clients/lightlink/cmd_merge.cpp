// `lightlink merge`: the parts of a sharded precompute (`precompute --shard I/N`) into the
// artifact one machine would have written, byte for byte (core/precompute/merge.h).
#include <chrono>
#include <cstdio>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "core/artifact/artifact.h"
#include "core/precompute/merge.h"

namespace lightlink::cli {

int runMerge(const MergeArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  auto merged = precompute::mergeParts(args.part_paths, args.output_path);
  if (!merged) return reportError("merge", merged.status());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!args.report_json.empty()) {
    nlohmann::ordered_json r;
    r["artifact"] = args.output_path;
    r["cache_key"] = artifact::cacheKeyHex(merged->cache_key);
    r["shards"] = merged->shards;
    r["parts"] = args.part_paths;
    r["bytes"] = merged->bytes;
    r["seconds"] = seconds;
    std::ofstream out(args.report_json, std::ios::binary | std::ios::trunc);
    out << r.dump(2) << "\n";
    if (!out) return reportError("merge", ioError("cannot write report {}", args.report_json));
  }
  if (!args.quiet)
    std::fputs(fmt::format("merged       {} shards, cache key {}, {} bytes in {:.3f} s\nwrote        {}\n",
                           merged->shards, artifact::cacheKeyHex(merged->cache_key), merged->bytes, seconds,
                           args.output_path)
                   .c_str(),
               stdout);
  return kExitOk;
}

}  // namespace lightlink::cli
