#include "core/precompute/merge.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <cerrno>
#include <filesystem>
#include <limits>
#include <optional>
#include <tuple>
#include <string_view>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/artifact/artifact.h"
#include "core/precompute/precompute.h"

namespace lightlink::precompute {
namespace {

namespace fs = std::filesystem;

std::string_view sectionName(const artifact::SectionEntry& e) { return {e.name, strnlen(e.name, sizeof(e.name))}; }

bool isLinkSection(std::string_view name) { return name.starts_with("lmlink.") || name.starts_with("gridlink."); }

// One opened part and what its "shard" section says.
struct Part {
  std::string path;
  artifact::Artifact file;
  ShardSpec shard;
  std::string key_hex, scene;
  CacheRange lightmap, grid;
  std::size_t lightmap_total = 0, grid_total = 0;
};

// Reads the "shard" section without exceptions: a damaged or foreign one is a message.
Expected<Part> readPart(const std::string& path) {
  auto file = artifact::Artifact::open(path, {.verify_payloads = true, .kind = artifact::FileKind::kShardPart});
  if (!file) return file.status();
  auto text = file->string(kShardSection);
  if (!text) return text.status();
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, /*allow_exceptions=*/false);
  auto bad = [&](std::string_view what) {
    return invalidInput("shard part {}: its '{}' section {}", path, kShardSection, what);
  };
  if (j.is_discarded() || !j.is_object()) return bad("is not a JSON object");
  if (!j.contains("format") || j["format"] != kShardFormat) return bad(fmt::format("is not {}", kShardFormat));
  if (!j.contains("version") || !j["version"].is_number_integer() || j["version"] != kShardFormatVersion)
    return bad(fmt::format("has another version than {} (written by another lightlink)", kShardFormatVersion));
  auto count = [&](const nlohmann::json& o, const char* key, std::size_t& out) {
    if (!o.is_object() || !o.contains(key) || !o[key].is_number_unsigned()) return false;
    out = o[key].get<std::size_t>();
    return true;
  };
  Part p{path, std::move(file).value(), {}, {}, {}, {}, {}, 0, 0};
  std::size_t index = 0, shards = 0;
  if (!count(j, "shard", index) || !count(j, "shards", shards) || shards < 1 || shards > std::size_t(kMaxShards) ||
      index >= shards)
    return bad("has no valid shard and shards");
  p.shard = {static_cast<int>(index), static_cast<int>(shards)};
  if (!j.contains("cache_key") || !j["cache_key"].is_string()) return bad("has no cache key");
  p.key_hex = j["cache_key"].get<std::string>();
  if (p.key_hex != artifact::cacheKeyHex(p.file.cacheKey())) return bad("names another cache key than the file header");
  if (j.contains("scene") && j["scene"].is_string()) p.scene = j["scene"].get<std::string>();
  for (auto [key, range, total] : {std::tuple{"lightmap_caches", &p.lightmap, &p.lightmap_total},
                                   std::tuple{"grid_caches", &p.grid, &p.grid_total}}) {
    if (!j.contains(key) || !count(j[key], "total", *total) || !count(j[key], "begin", range->begin) ||
        !count(j[key], "end", range->end))
      return bad(fmt::format("has no valid '{}' range", key));
  }
  // The split is a function of the totals and the shard: a part that linked another range is
  // not this shard of this run.
  const CacheRange all = shardRange(p.lightmap_total + p.grid_total, p.shard);
  const CacheRange lm{std::min(all.begin, p.lightmap_total), std::min(all.end, p.lightmap_total)};
  const CacheRange grid{std::max(all.begin, p.lightmap_total) - p.lightmap_total,
                        std::max(all.end, p.lightmap_total) - p.lightmap_total};
  if (p.lightmap.begin != lm.begin || p.lightmap.end != lm.end || p.grid.begin != grid.begin || p.grid.end != grid.end)
    return bad(fmt::format("gives cache ranges that are not shard {}/{}'s", p.shard.index, p.shard.count));
  return p;
}

// The link arrays of one prefix ("lmlink", "gridlink") over all parts in shard order: sizes
// checked against each part's range, offsets rebased onto the links before them.
Status concatenateLinks(std::span<const Part> parts, std::string_view name, bool lightmap,
                        std::vector<std::byte>& out) {
  const bool offsets = name.ends_with(".offsets");
  std::uint64_t base = 0;  // links of the parts before this one
  bool empty_all = true;
  for (const Part& p : parts) empty_all &= p.file.bytes(name)->empty();
  if (empty_all) return {};  // a set of caches the scene has none of (no grid)
  for (const Part& p : parts) {
    const CacheRange r = lightmap ? p.lightmap : p.grid;
    auto bytes = p.file.bytes(name);
    if (!bytes) return bytes.status();
    if (!offsets) {
      out.insert(out.end(), bytes->begin(), bytes->end());
      continue;
    }
    auto view = p.file.array<std::uint32_t>(name);
    if (!view) return view.status();
    const std::span<const std::uint32_t> o = *view;
    if (o.size() != r.end - r.begin + 1 || o.front() != 0 || !std::is_sorted(o.begin(), o.end()))
      return invalidInput("shard part {}: section '{}' does not hold the offsets of its {} caches", p.path, name,
                          r.end - r.begin);
    auto nodes = p.file.array<std::uint32_t>(fmt::format("{}.node", name.substr(0, name.find('.'))));
    if (!nodes) return nodes.status();
    if (o.back() != nodes->size())
      return invalidInput("shard part {}: section '{}' ends at link {} but the part holds {} links", p.path, name,
                          o.back(), nodes->size());
    if (base + o.back() > std::numeric_limits<std::uint32_t>::max())
      return resourceExhausted("merge: more than 2^32 links in '{}'", name);
    // The first part's leading 0 starts the whole array; later parts' are the previous end.
    for (std::size_t i = out.empty() ? 0 : 1; i < o.size(); ++i) {
      const std::uint32_t v = static_cast<std::uint32_t>(base + o[i]);
      const auto* b = reinterpret_cast<const std::byte*>(&v);
      out.insert(out.end(), b, b + sizeof(v));
    }
    base += o.back();
  }
  return {};
}

}  // namespace

Expected<MergeResult> mergeParts(std::span<const std::string> part_paths, const std::string& output_path) {
  if (part_paths.empty()) return invalidInput("merge: no shard parts given");
  std::vector<Part> given;
  given.reserve(part_paths.size());
  for (const std::string& path : part_paths) {
    auto p = readPart(path);
    if (!p) return p.status();
    given.push_back(std::move(p).value());
  }
  // One run: the same key (scene bytes, options, lightlink version) and N, each index once.
  const Part& first = given.front();
  const int n = first.shard.count;
  std::vector<std::optional<std::size_t>> slot(static_cast<std::size_t>(n));
  for (std::size_t i = 0; i < given.size(); ++i) {
    const Part& p = given[i];
    if (p.key_hex != first.key_hex)
      return invalidInput("shard part {} belongs to another precompute (cache key {}, scene '{}') than {} (cache key "
                          "{}, scene '{}'): another scene, other options or another lightlink version",
                          p.path, p.key_hex, p.scene, first.path, first.key_hex, first.scene);
    if (p.shard.count != n)
      return invalidInput("shard part {} is shard {}/{} but {} is shard {}/{}: parts of differently split runs",
                          p.path, p.shard.index, p.shard.count, first.path, first.shard.index, n);
    auto& s = slot[static_cast<std::size_t>(p.shard.index)];
    if (s) return invalidInput("shard parts {} and {} are both shard {}/{}", given[*s].path, p.path, p.shard.index, n);
    s = i;
  }
  std::vector<std::string> missing;
  for (int i = 0; i < n; ++i)
    if (!slot[static_cast<std::size_t>(i)]) missing.push_back(fmt::format("{}/{}", i, n));
  if (!missing.empty())
    return invalidInput("merge: shard{} {} of cache key {} missing ({} of {} parts given)",
                        missing.size() == 1 ? "" : "s", fmt::join(missing, ", "), first.key_hex, given.size(), n);
  std::vector<Part> parts;
  parts.reserve(given.size());
  for (const auto& s : slot) parts.push_back(std::move(given[*s]));

  // The same sections everywhere; every section but the links and the seen flags the same bytes.
  const auto table = parts[0].file.sections();
  for (const Part& p : parts) {
    const auto t = p.file.sections();
    bool same = t.size() == table.size();
    for (std::size_t i = 0; same && i < t.size(); ++i)
      same = sectionName(t[i]) == sectionName(table[i]) && t[i].element_bytes == table[i].element_bytes;
    if (!same)
      return invalidInput("shard part {} has other sections than {}: written by another lightlink version", p.path,
                          parts[0].path);
    for (std::size_t i = 0; i < t.size(); ++i) {
      const std::string_view name = sectionName(t[i]);
      if (isLinkSection(name) || name == "surfel.seen" || name == kShardSection) continue;
      if (t[i].bytes != table[i].bytes || t[i].checksum != table[i].checksum)
        return invalidInput("shard part {} disagrees with {} in section '{}': the shards did not compute the same "
                            "scene (another build or a changed scene file under the same key)",
                            p.path, parts[0].path, name);
    }
  }

  // Assemble in the artifact's section order (the parts' minus "shard").
  std::vector<std::vector<std::byte>> built;
  built.reserve(table.size());
  artifact::Writer w(parts[0].file.cacheKey());
  for (const artifact::SectionEntry& e : table) {
    const std::string_view name = sectionName(e);
    if (name == kShardSection) continue;
    if (isLinkSection(name)) {
      built.emplace_back();
      if (Status s = concatenateLinks(parts, name, name.starts_with("lmlink."), built.back()); !s) return s;
      if (Status s = w.addSection(name, built.back(), e.element_bytes); !s) return s;
    } else if (name == "surfel.seen") {
      built.emplace_back(parts[0].file.bytes(name)->size());
      std::vector<std::byte>& seen = built.back();
      for (const Part& p : parts) {
        const auto b = *p.file.bytes(name);
        if (b.size() != seen.size())
          return invalidInput("shard part {}: section 'surfel.seen' has {} surfels, {} has {}", p.path, b.size(),
                              parts[0].path, seen.size());
        for (std::size_t i = 0; i < b.size(); ++i) seen[i] |= b[i];
      }
      if (Status s = w.addSection(name, seen, e.element_bytes); !s) return s;
    } else {
      if (Status s = w.addSection(name, *parts[0].file.bytes(name), e.element_bytes); !s) return s;
    }
  }

  // Written beside the output under a temporary name, checked as every reader checks an
  // artifact, and only then renamed over the output: a bad merge never replaces a good file.
  const fs::path out(output_path);
  const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
  const fs::path staging = dir / fmt::format(".{}.merging.{}", out.filename().string(), ::getpid());
  if (Status s = w.write(staging.string()); !s) return s;
  auto unlink_staging = [&] { ::unlink(staging.c_str()); };
  {
    auto check = open(staging.string());
    if (!check) {
      unlink_staging();
      return Status(check.status().code(),
                    fmt::format("merge: the assembled artifact fails its checks: {}", check.status().message()));
    }
  }
  MergeResult result;
  result.cache_key = parts[0].file.cacheKey();
  result.shards = n;
  std::error_code ec;
  result.bytes = fs::file_size(staging, ec);
  if (::rename(staging.c_str(), out.c_str()) != 0) {
    const std::string err = std::strerror(errno);
    unlink_staging();
    return ioError("merge: cannot rename {} to {}: {}", staging.string(), output_path, err);
  }
  if (const int dir_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dir_fd >= 0) {
    ::fsync(dir_fd);
    ::close(dir_fd);
  }
  return result;
}

}  // namespace lightlink::precompute
