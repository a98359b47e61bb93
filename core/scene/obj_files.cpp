#include "core/scene/obj_files.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <set>
#include <vector>

namespace lightlink::scene {
namespace {

// The statement's keyword and the rest of the line, trimmed; comments dropped.
std::pair<std::string_view, std::string_view> statement(std::string_view line) {
  if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
  const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  while (!line.empty() && space(line.front())) line.remove_prefix(1);
  while (!line.empty() && space(line.back())) line.remove_suffix(1);
  std::size_t end = 0;
  while (end < line.size() && !space(line[end])) ++end;
  std::string_view rest = line.substr(end);
  while (!rest.empty() && space(rest.front())) rest.remove_prefix(1);
  return {line.substr(0, end), rest};
}

template <class F>
void forEachStatement(std::string_view text, F&& f) {
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    const auto [key, rest] = statement(text.substr(start, end - start));
    if (!key.empty()) f(key, rest);
    start = end + 1;
  }
}

// As the loader names files: Windows separators become '/'.
std::string fileName(std::string_view raw) {
  std::string name(raw);
  std::replace(name.begin(), name.end(), '\\', '/');
  return name;
}

Status append(const SceneFiles& files, const std::string& name, const char* what, std::string& out) {
  Expected<std::string> bytes = files.readName(name, what);
  if (!bytes && bytes.status().code() == Code::kNotFound) {
    out += fmt::format("{}\nmissing\n", name);
    return Status::ok();
  }
  if (!bytes) return bytes.status();
  out += fmt::format("{}\n{}\n", name, bytes->size());
  out += *bytes;
  return Status::ok();
}

}  // namespace

Expected<std::string> objDependencyBytes(const SceneFiles& files, std::string_view obj_text) {
  std::string ext = std::filesystem::path(files.scenePath()).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext != ".obj") return std::string();
  std::vector<std::string> libraries;
  forEachStatement(obj_text, [&](std::string_view key, std::string_view rest) {
    if (key == "mtllib" && !rest.empty()) libraries.push_back(fileName(rest));
  });
  std::string out;
  std::set<std::string> textures_seen;
  for (const std::string& library : libraries) {
    Expected<std::string> mtl = files.readName(library, "mtllib");
    if (!mtl && mtl.status().code() == Code::kNotFound) {
      out += fmt::format("{}\nmissing\n", library);
      continue;
    }
    if (!mtl) return mtl.status();
    out += fmt::format("{}\n{}\n", library, mtl->size());
    out += *mtl;
    std::vector<std::string> textures;
    forEachStatement(*mtl, [&](std::string_view key, std::string_view rest) {
      if ((key == "map_Kd" || key == "map_Ke") && !rest.empty()) {
        // Options (-s 1 1 1 ...) come first; the file name is the last word.
        const std::size_t space = rest.find_last_of(" \t");
        textures.push_back(fileName(space == std::string_view::npos ? rest : rest.substr(space + 1)));
      }
    });
    for (const std::string& texture : textures) {
      if (!textures_seen.insert(texture).second) continue;
      if (Status s = append(files, texture, "texture", out); !s) return s;
    }
  }
  return out;
}

}  // namespace lightlink::scene
