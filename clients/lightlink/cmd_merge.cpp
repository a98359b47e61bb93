// `lightlink merge`: the parts of a sharded precompute (`precompute --shard I/N`) into the
// artifact one machine would have written, byte for byte (core/precompute/merge.h).
#include <chrono>
#include <cstdio>
#include <filesystem>
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
  if (args.output_path.empty() == args.cache_dir.empty())
    return reportError("merge", invalidInput("give the artifact to write as -o FILE or --cache-dir DIR (one of them)"));
  std::string output = args.output_path;
  if (output.empty()) {
    // The key from the first part's header (checked against every part by the merge).
    if (args.part_paths.empty()) return reportError("merge", invalidInput("no shard parts given"));
    auto first = artifact::Artifact::open(args.part_paths[0],
                                          {.verify_payloads = false, .kind = artifact::FileKind::kShardPart});
    if (!first) return reportError("merge", first.status());
    std::error_code ec;
    std::filesystem::create_directories(args.cache_dir, ec);
    if (ec) return reportError("merge", ioError("cannot create directory {}: {}", args.cache_dir, ec.message()));
    output = (std::filesystem::path(args.cache_dir) / (artifact::cacheKeyHex(first->cacheKey()) + ".llk")).string();
  }
  auto merged = precompute::mergeParts(args.part_paths, output);
  if (!merged) return reportError("merge", merged.status());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!args.report_json.empty()) {
    nlohmann::ordered_json r;
    r["artifact"] = output;
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
                           output)
                   .c_str(),
               stdout);
  return kExitOk;
}

}  // namespace lightlink::cli
