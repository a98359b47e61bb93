// Scenes whose buffer URI leaves the scene's folder, for the confinement tests of the loader,
// the CLI and the daemon (core/scene/scene_files.h). Each is a one-triangle glTF in
// <dir>/scene/ naming a file in <dir>/outside/ by `..`, by absolute path, or through a
// symbolic link inside the scene's folder; and one whose index buffer is a "secret" text
// file, as the attack in issue 44 read sessions.json (an out-of-range index quoting its bytes).
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "tests/common/testing.h"

namespace lightlink::testing {

enum class Escape { kDotDot, kAbsolute, kSymlink };

inline const char* escapeName(Escape e) {
  return e == Escape::kDotDot ? "dotdot" : e == Escape::kAbsolute ? "absolute" : "symlink";
}

// Secret text outside the scene's folder; its first 4 bytes as a little-endian u32 index.
inline constexpr const char* kSecretText = "TOPSECRETTOKEN-0123456789abcdef\n";
inline std::string secretFirstIndex() {
  std::uint32_t v = 0;
  std::memcpy(&v, kSecretText, 4);
  return std::to_string(v);
}

// 3 float3 positions and u32 indices {0, 1, 2}: 48 bytes.
inline std::string triangleBin() {
  const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::uint32_t i[3] = {0, 1, 2};
  std::string bin(48, '\0');
  std::memcpy(bin.data(), p, 36);
  std::memcpy(bin.data() + 36, i, 12);
  return bin;
}

// The glTF JSON of the triangle: positions from buffer 0 (`geo_uri`, triangleBin()); the
// indices from buffer 0 too, or from buffer 1 (`index_uri`, `index_bytes` long) when given.
inline std::string triangleGltf(const std::string& geo_uri, const std::string& index_uri = "",
                                std::size_t index_bytes = 0) {
  const bool separate = !index_uri.empty();
  const std::string buffers =
      separate ? fmt::format(R"([{{"uri": "{}", "byteLength": 48}}, {{"uri": "{}", "byteLength": {}}}])", geo_uri,
                             index_uri, index_bytes)
               : fmt::format(R"([{{"uri": "{}", "byteLength": 48}}])", geo_uri);
  return fmt::format(
      R"({{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "buffers": {},
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
                  {{"buffer": {}, "byteOffset": {}, "byteLength": 12}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                  "min": [0, 0, 0], "max": [1, 1, 0]}},
                {{"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}}]}})",
      buffers, separate ? 1 : 0, separate ? 0 : 36);
}

// <dir>/outside/geo.bin and <dir>/scene/escape.gltf naming it as `how` says. Returns the scene.
inline std::filesystem::path writeEscapingScene(const std::filesystem::path& dir, Escape how) {
  namespace fs = std::filesystem;
  fs::create_directories(dir / "outside");
  fs::create_directories(dir / "scene");
  writeFile(dir / "outside" / "geo.bin", triangleBin());
  std::string uri;
  switch (how) {
    case Escape::kDotDot: uri = "../outside/geo.bin"; break;
    case Escape::kAbsolute: uri = fs::absolute(dir / "outside" / "geo.bin").string(); break;
    case Escape::kSymlink:
      fs::create_directory_symlink(fs::absolute(dir / "outside"), dir / "scene" / "assets");
      uri = "assets/geo.bin";
      break;
  }
  return writeFile(dir / "scene" / "escape.gltf", triangleGltf(uri));
}

// <dir>/secret.txt and <dir>/scene/secret.gltf whose indices are the first 12 bytes of it.
inline std::filesystem::path writeSecretReadingScene(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  fs::create_directories(dir / "scene");
  writeFile(dir / "secret.txt", kSecretText);
  writeFile(dir / "scene" / "geo.bin", triangleBin());
  return writeFile(dir / "scene" / "secret.gltf",
                   triangleGltf("geo.bin", "../secret.txt", std::strlen(kSecretText)));
}

}  // namespace lightlink::testing
