#include "tests/common/hostile_scenes.h"

#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>

namespace lightlink::testing {
namespace {

void put32(std::string& out, std::uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<char>((v >> s) & 0xff));
}

void chunk(std::string& png, const char* type, const std::string& data) {
  put32(png, static_cast<std::uint32_t>(data.size()));
  const std::string body = std::string(type, 4) + data;
  png += body;
  put32(png, static_cast<std::uint32_t>(
                 crc32(0, reinterpret_cast<const Bytef*>(body.data()), static_cast<uInt>(body.size()))));
}

std::string base64(const std::string& in) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const std::uint32_t v = std::uint32_t(std::uint8_t(in[i])) << 16 | std::uint32_t(std::uint8_t(in[i + 1])) << 8 |
                            std::uint8_t(in[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out.push_back(k[(v >> s) & 63]);
  }
  if (i < in.size()) {
    std::uint32_t v = std::uint32_t(std::uint8_t(in[i])) << 16;
    if (i + 1 < in.size()) v |= std::uint32_t(std::uint8_t(in[i + 1])) << 8;
    out.push_back(k[(v >> 18) & 63]);
    out.push_back(k[(v >> 12) & 63]);
    out.push_back(i + 1 < in.size() ? k[(v >> 6) & 63] : '=');
    out.push_back('=');
  }
  return out;
}

template <typename T>
void append(std::string& bin, const std::vector<T>& v) {
  bin.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

std::string bufferUri(const std::string& bin) { return "data:application/octet-stream;base64," + base64(bin); }

}  // namespace

std::string zeroPng(int width, int height) {
  std::string png = "\x89PNG\r\n\x1a\n";
  std::string ihdr;
  put32(ihdr, static_cast<std::uint32_t>(width));
  put32(ihdr, static_cast<std::uint32_t>(height));
  ihdr += std::string("\x08\x00\x00\x00\x00", 5);  // 8-bit grey, deflate, no filter, no interlace
  chunk(png, "IHDR", ihdr);

  z_stream z{};
  if (deflateInit(&z, Z_DEFAULT_COMPRESSION) != Z_OK) throw std::runtime_error("deflateInit");
  const std::vector<Bytef> row(static_cast<std::size_t>(width) + 1, 0);  // filter byte 0 + pixels
  std::vector<Bytef> out(1 << 16);
  std::string idat;
  for (int y = 0; y <= height; ++y) {
    const bool last = y == height;
    z.next_in = const_cast<Bytef*>(row.data());
    z.avail_in = last ? 0 : static_cast<uInt>(row.size());
    do {
      z.next_out = out.data();
      z.avail_out = static_cast<uInt>(out.size());
      deflate(&z, last ? Z_FINISH : Z_NO_FLUSH);
      idat.append(reinterpret_cast<const char*>(out.data()), out.size() - z.avail_out);
    } while (z.avail_out == 0);
  }
  deflateEnd(&z);
  chunk(png, "IDAT", idat);
  chunk(png, "IEND", "");
  return png;
}

std::string texturedQuadGltf(const std::string& png) {
  std::string bin;
  append(bin, std::vector<float>{0, 0, 0, 1, 0, 0, 1, 0, -1, 0, 0, -1});  // y = 0 floor, 1 m^2
  append(bin, std::vector<float>{0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0});
  append(bin, std::vector<float>{0, 0, 1, 0, 1, 1, 0, 1});
  append(bin, std::vector<std::uint16_t>{0, 1, 2, 0, 2, 3});
  const std::string json = R"({
  "asset": {"version": "2.0"},
  "buffers": [{"byteLength": 140, "uri": ")" + bufferUri(bin) + R"("}],
  "bufferViews": [
    {"buffer": 0, "byteOffset": 0, "byteLength": 48},
    {"buffer": 0, "byteOffset": 48, "byteLength": 48},
    {"buffer": 0, "byteOffset": 96, "byteLength": 32},
    {"buffer": 0, "byteOffset": 128, "byteLength": 12}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, -1], "max": [1, 0, 0]},
    {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
    {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
    {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}],
  "images": [{"uri": "data:image/png;base64,)" + base64(png) + R"("}],
  "textures": [{"source": 0}],
  "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3,
                              "material": 0}]}],
  "nodes": [{"mesh": 0}],
  "scenes": [{"nodes": [0]}],
  "scene": 0
})";
  return json;
}

std::string instancedGridGltf(int triangles, int instances) {
  const int quads = (triangles + 1) / 2;
  std::vector<float> pos;
  std::vector<std::uint32_t> idx;
  for (int q = 0; q <= quads; ++q) {
    pos.insert(pos.end(), {0.01f * float(q), 0.0f, 0.0f, 0.01f * float(q), 0.0f, -0.01f});
  }
  for (int q = 0; q < quads; ++q) {
    const auto a = std::uint32_t(2 * q), b = a + 1, c = a + 2, d = a + 3;
    idx.insert(idx.end(), {a, c, b, b, c, d});
  }
  idx.resize(static_cast<std::size_t>(triangles) * 3);
  std::string bin;
  append(bin, pos);
  append(bin, idx);
  std::string nodes, roots;
  for (int i = 0; i < instances; ++i) {
    nodes += fmt::format("{}{{\"mesh\":0,\"translation\":[0,{},0]}}", i ? "," : "", 0.01 * i);
    roots += fmt::format("{}{}", i ? "," : "", i);
  }
  const std::size_t pos_bytes = pos.size() * sizeof(float), idx_bytes = idx.size() * sizeof(std::uint32_t);
  return fmt::format(R"({{
  "asset": {{"version": "2.0"}},
  "buffers": [{{"byteLength": {}, "uri": "{}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": {}}},
                  {{"buffer": 0, "byteOffset": {}, "byteLength": {}}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": {}, "type": "VEC3", "min": [0, 0, -0.01], "max": [{}, 0, 0]}},
    {{"bufferView": 1, "componentType": 5125, "count": {}, "type": "SCALAR"}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "nodes": [{}],
  "scenes": [{{"nodes": [{}]}}],
  "scene": 0
}})",
                     bin.size(), bufferUri(bin), pos_bytes, pos_bytes, idx_bytes, pos.size() / 3, 0.01 * quads,
                     idx.size(), nodes, roots);
}

std::string manyLightsJson(int count) {
  std::string lights;
  for (int i = 0; i < count; ++i)
    lights += fmt::format("{}{{\"id\":\"l{}\",\"type\":\"point\",\"position\":[0,0.25,0],\"intensity\":1}}",
                          i ? "," : "", i);
  return "{\"version\": 1, \"lights\": [" + lights + "]}";
}

}  // namespace lightlink::testing
