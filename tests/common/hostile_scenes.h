// Test fixtures for the request budgets (docs/cli.md "Limits"): small files that claim huge
// work. Each is self-contained glTF text (data: URIs), so it can be written to disk for the
// loader and the CLI or uploaded to the daemon as gltf_bytes.
#pragma once

#include <string>

namespace lightlink::testing {

// A PNG of width x height 8-bit grey zeros: a few hundred KB that decode to width x height
// bytes (and 4x that as RGBA). Deflated row by row, so building it costs little memory.
std::string zeroPng(int width, int height);

// One static quad textured with `png` (baseColorTexture, a data: URI).
std::string texturedQuadGltf(const std::string& png);

// One static mesh of `triangles` triangles (a strip of quads) placed by `instances` nodes:
// triangles x instances triangles after instancing, from a file of about 40 bytes a node.
std::string instancedGridGltf(int triangles, int instances);

// A light-set JSON (docs/lightset.md) adding `count` point lights.
std::string manyLightsJson(int count);

}  // namespace lightlink::testing
