// Internal to core/charts: appends vertex and index data to buffer 0 of a tinygltf model as
// new bufferViews and accessors, what both glTF writers (gltf_writer: TEXCOORD_1 added to a
// re-read glTF; gltf_scene_writer: a glTF made from a Scene) write the same way.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>
#include <tiny_gltf.h>

namespace lightlink::charts {

class GltfAppender {
 public:
  explicit GltfAppender(tinygltf::Model& model) : model_(model) {
    if (model_.buffers.empty()) model_.buffers.resize(1);
  }

  // Appends bytes (4-byte aligned) to buffer 0 as a new bufferView; returns its index.
  int addView(const void* bytes, std::size_t size, int target) {
    std::vector<unsigned char>& data = model_.buffers[0].data;
    data.resize((data.size() + 3) / 4 * 4, 0);
    tinygltf::BufferView bv;
    bv.buffer = 0;
    bv.byteOffset = data.size();
    bv.byteLength = size;
    bv.target = target;
    const auto* p = static_cast<const unsigned char*>(bytes);
    data.insert(data.end(), p, p + size);
    model_.bufferViews.push_back(std::move(bv));
    return static_cast<int>(model_.bufferViews.size() - 1);
  }

  // Float vec3 accessor; `with_bounds` adds the min/max glTF requires on POSITION.
  int addVec3(const std::vector<glm::vec3>& v, bool with_bounds) {
    tinygltf::Accessor a = floats(v.data(), v.size(), sizeof(glm::vec3), TINYGLTF_TYPE_VEC3);
    if (with_bounds && !v.empty()) {
      glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
      for (const glm::vec3& p : v) lo = glm::min(lo, p), hi = glm::max(hi, p);
      a.minValues = {lo.x, lo.y, lo.z};
      a.maxValues = {hi.x, hi.y, hi.z};
    }
    return push(std::move(a));
  }

  int addVec2(const std::vector<glm::vec2>& v) {
    return push(floats(v.data(), v.size(), sizeof(glm::vec2), TINYGLTF_TYPE_VEC2));
  }

  // Index accessor: uint16 when every index fits (`vertex_count` <= 65535), else uint32.
  int addIndices(const std::vector<std::uint32_t>& indices, std::size_t vertex_count) {
    tinygltf::Accessor a;
    if (vertex_count <= 0xffff) {
      const std::vector<std::uint16_t> small(indices.begin(), indices.end());
      a.bufferView = addView(small.data(), small.size() * 2, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
      a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    } else {
      a.bufferView = addView(indices.data(), indices.size() * 4, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
      a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    }
    a.type = TINYGLTF_TYPE_SCALAR;
    a.count = indices.size();
    return push(std::move(a));
  }

 protected:
  int push(tinygltf::Accessor a) {
    model_.accessors.push_back(std::move(a));
    return static_cast<int>(model_.accessors.size() - 1);
  }

  tinygltf::Model& model_;

 private:
  tinygltf::Accessor floats(const void* data, std::size_t count, std::size_t element_bytes, int type) {
    tinygltf::Accessor a;
    a.bufferView = addView(data, count * element_bytes, TINYGLTF_TARGET_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.type = type;
    a.count = count;
    return a;
  }
};

}  // namespace lightlink::charts
