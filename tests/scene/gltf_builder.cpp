#include "tests/scene/gltf_builder.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "tests/common/testing.h"

namespace lightlink::testing {
namespace {

constexpr int kFloat = 5126;
constexpr int kU8 = 5121;
constexpr int kU16 = 5123;
constexpr int kU32 = 5125;

void put32(std::string& out, std::uint32_t v) {
  char b[4];
  std::memcpy(b, &v, 4);
  out.append(b, 4);
}

}  // namespace

std::string base64(const std::uint8_t* data, std::size_t size) {
  static const char* kChars = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  for (std::size_t i = 0; i < size; i += 3) {
    const std::uint32_t b0 = data[i];
    const std::uint32_t b1 = i + 1 < size ? data[i + 1] : 0;
    const std::uint32_t b2 = i + 2 < size ? data[i + 2] : 0;
    const std::uint32_t v = (b0 << 16) | (b1 << 8) | b2;
    out += kChars[(v >> 18) & 63];
    out += kChars[(v >> 12) & 63];
    out += i + 1 < size ? kChars[(v >> 6) & 63] : '=';
    out += i + 2 < size ? kChars[v & 63] : '=';
  }
  return out;
}

std::vector<std::uint8_t> bmp24(int width, int height, const std::vector<std::uint8_t>& rgb) {
  const std::size_t row = (static_cast<std::size_t>(width) * 3 + 3) & ~std::size_t{3};
  const std::size_t pixels = row * static_cast<std::size_t>(height);
  std::string out = "BM";
  put32(out, static_cast<std::uint32_t>(54 + pixels));
  put32(out, 0);
  put32(out, 54);
  put32(out, 40);  // BITMAPINFOHEADER
  put32(out, static_cast<std::uint32_t>(width));
  put32(out, static_cast<std::uint32_t>(height));  // positive: rows stored bottom-up
  out += std::string("\x01\x00\x18\x00", 4);       // 1 plane, 24 bits
  for (int i = 0; i < 6; ++i) put32(out, 0);        // BI_RGB, sizes, palette
  for (int y = height - 1; y >= 0; --y) {
    std::string r;
    for (int x = 0; x < width; ++x) {
      const std::size_t at = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                              static_cast<std::size_t>(x)) * 3;
      r += static_cast<char>(rgb[at + 2]);  // BGR
      r += static_cast<char>(rgb[at + 1]);
      r += static_cast<char>(rgb[at + 0]);
    }
    r.resize(row, '\0');
    out += r;
  }
  return {out.begin(), out.end()};
}

std::vector<glm::vec3> unitTriangle() { return {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}; }

GltfBuilder::GltfBuilder() {
  json_ = {{"asset", {{"version", "2.0"}, {"generator", "lightlink tests"}}},
           {"scene", 0},
           {"scenes", nlohmann::json::array({{{"nodes", nlohmann::json::array()}}})},
           {"nodes", nlohmann::json::array()},
           {"meshes", nlohmann::json::array()},
           {"accessors", nlohmann::json::array()},
           {"bufferViews", nlohmann::json::array()}};
}

int GltfBuilder::addBufferView(const void* bytes, std::size_t size, std::size_t byte_stride) {
  while (bin_.size() % 4 != 0) bin_.push_back(0);
  const std::size_t offset = bin_.size();
  const auto* p = static_cast<const std::uint8_t*>(bytes);
  bin_.insert(bin_.end(), p, p + size);
  nlohmann::json view = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", size}};
  if (byte_stride != 0) view["byteStride"] = byte_stride;
  json_["bufferViews"].push_back(view);
  return static_cast<int>(json_["bufferViews"].size() - 1);
}

int GltfBuilder::addAccessor(const void* bytes, std::size_t size, int component_type,
                             const std::string& type, std::size_t count, bool normalized,
                             std::size_t byte_stride) {
  const int view = addBufferView(bytes, size, byte_stride);
  nlohmann::json accessor = {
      {"bufferView", view}, {"componentType", component_type}, {"type", type}, {"count", count}};
  if (normalized) accessor["normalized"] = true;
  json_["accessors"].push_back(accessor);
  return static_cast<int>(json_["accessors"].size() - 1);
}

int GltfBuilder::addVec3(const std::vector<glm::vec3>& values) {
  return addAccessor(values.data(), values.size() * sizeof(glm::vec3), kFloat, "VEC3", values.size());
}
int GltfBuilder::addVec2(const std::vector<glm::vec2>& values) {
  return addAccessor(values.data(), values.size() * sizeof(glm::vec2), kFloat, "VEC2", values.size());
}
int GltfBuilder::addIndicesU8(const std::vector<std::uint8_t>& values) {
  return addAccessor(values.data(), values.size(), kU8, "SCALAR", values.size());
}
int GltfBuilder::addIndicesU16(const std::vector<std::uint16_t>& values) {
  return addAccessor(values.data(), values.size() * 2, kU16, "SCALAR", values.size());
}
int GltfBuilder::addIndicesU32(const std::vector<std::uint32_t>& values) {
  return addAccessor(values.data(), values.size() * 4, kU32, "SCALAR", values.size());
}

int GltfBuilder::addMesh(const nlohmann::json& primitive, const std::string& name) {
  nlohmann::json mesh = {{"primitives", nlohmann::json::array({primitive})}};
  if (!name.empty()) mesh["name"] = name;
  json_["meshes"].push_back(mesh);
  return static_cast<int>(json_["meshes"].size() - 1);
}

int GltfBuilder::addTriangles(const std::vector<glm::vec3>& positions,
                              const std::vector<std::uint16_t>& indices, const std::string& name,
                              const std::vector<glm::vec3>& normals) {
  nlohmann::json primitive = {{"attributes", {{"POSITION", addVec3(positions)}}}};
  if (!normals.empty()) primitive["attributes"]["NORMAL"] = addVec3(normals);
  primitive["indices"] = addIndicesU16(indices);
  return addMesh(primitive, name);
}

int GltfBuilder::addNode(const nlohmann::json& node, bool root) {
  json_["nodes"].push_back(node.is_null() ? nlohmann::json::object() : node);
  const int index = static_cast<int>(json_["nodes"].size() - 1);
  if (root) json_["scenes"][0]["nodes"].push_back(index);
  return index;
}

void GltfBuilder::addChild(int parent, int child) {
  json_["nodes"][static_cast<std::size_t>(parent)]["children"].push_back(child);
  auto& roots = json_["scenes"][0]["nodes"];
  roots.erase(std::remove(roots.begin(), roots.end(), nlohmann::json(child)), roots.end());
}

std::string GltfBuilder::gltfText() const {
  nlohmann::json j = json_;
  if (!bin_.empty() && !j.contains("buffers")) {
    j["buffers"] = nlohmann::json::array(
        {{{"byteLength", bin_.size()},
          {"uri", "data:application/octet-stream;base64," + base64(bin_.data(), bin_.size())}}});
  }
  return j.dump();
}

std::string GltfBuilder::writeGltf(const std::filesystem::path& path) const {
  return writeFile(path, gltfText());
}

std::string GltfBuilder::writeGltfWithBin(const std::filesystem::path& path,
                                          const std::string& bin_name) const {
  nlohmann::json j = json_;
  if (!j.contains("buffers")) {
    j["buffers"] = nlohmann::json::array({{{"byteLength", bin_.size()}, {"uri", bin_name}}});
  }
  writeFile(path.parent_path() / bin_name, std::string(bin_.begin(), bin_.end()));
  return writeFile(path, j.dump());
}

std::string GltfBuilder::writeGlb(const std::filesystem::path& path) const {
  nlohmann::json j = json_;
  if (!j.contains("buffers")) j["buffers"] = nlohmann::json::array({{{"byteLength", bin_.size()}}});
  std::string text = j.dump();
  while (text.size() % 4 != 0) text += ' ';
  std::string bin(bin_.begin(), bin_.end());
  while (bin.size() % 4 != 0) bin += '\0';
  std::string out = "glTF";
  put32(out, 2);
  put32(out, static_cast<std::uint32_t>(12 + 8 + text.size() + 8 + bin.size()));
  put32(out, static_cast<std::uint32_t>(text.size()));
  put32(out, 0x4E4F534Au);  // "JSON"
  out += text;
  put32(out, static_cast<std::uint32_t>(bin.size()));
  put32(out, 0x004E4942u);  // "BIN\0"
  out += bin;
  return writeFile(path, out);
}

}  // namespace lightlink::testing
