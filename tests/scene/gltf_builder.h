// Test helper: builds small glTF files in memory (nlohmann JSON plus one binary buffer)
// and writes them as .gltf with a base64 data URI, .gltf with an external .bin, or .glb.
// Tests reach into json() to break a file on purpose after building a valid one.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

namespace lightlink::testing {

class GltfBuilder {
 public:
  GltfBuilder();

  nlohmann::json& json() { return json_; }
  std::vector<std::uint8_t>& bin() { return bin_; }

  // Appends `bytes` as a new 4-byte-aligned bufferView and returns its index.
  int addBufferView(const void* bytes, std::size_t size, std::size_t byte_stride = 0);
  // A new bufferView holding `bytes` plus an accessor over it; returns the accessor index.
  int addAccessor(const void* bytes, std::size_t size, int component_type, const std::string& type,
                  std::size_t count, bool normalized = false, std::size_t byte_stride = 0);
  int addVec3(const std::vector<glm::vec3>& values);
  int addVec2(const std::vector<glm::vec2>& values);
  int addIndicesU8(const std::vector<std::uint8_t>& values);
  int addIndicesU16(const std::vector<std::uint16_t>& values);
  int addIndicesU32(const std::vector<std::uint32_t>& values);

  // Adds {"primitives":[primitive]} as a mesh; returns the mesh index.
  int addMesh(const nlohmann::json& primitive, const std::string& name = "");
  // Adds a triangle-list mesh with u16 indices (and normals when given).
  int addTriangles(const std::vector<glm::vec3>& positions, const std::vector<std::uint16_t>& indices,
                   const std::string& name = "", const std::vector<glm::vec3>& normals = {});
  // Adds a node; root nodes are listed in scene 0. Returns the node index.
  int addNode(const nlohmann::json& node, bool root = true);
  // Makes `child` a child of `parent` (and not a scene root).
  void addChild(int parent, int child);

  // Writers return the path written.
  std::string writeGltf(const std::filesystem::path& path) const;  // buffer as data URI
  std::string writeGltfWithBin(const std::filesystem::path& path, const std::string& bin_name) const;
  std::string writeGlb(const std::filesystem::path& path) const;

  // The JSON text with the buffer embedded (for tests that corrupt the text itself).
  std::string gltfText() const;

 private:
  nlohmann::json json_;
  std::vector<std::uint8_t> bin_;
};

std::string base64(const std::uint8_t* data, std::size_t size);

// An uncompressed 24-bit BMP of `rgb` (rows top first, 3 bytes per pixel), for image tests.
std::vector<std::uint8_t> bmp24(int width, int height, const std::vector<std::uint8_t>& rgb);

// A unit right triangle in the z = 0 plane, counter-clockwise seen from +Z.
std::vector<glm::vec3> unitTriangle();

}  // namespace lightlink::testing
