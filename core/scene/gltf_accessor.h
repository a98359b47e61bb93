// Internal to core/scene: bounds-checked access to glTF accessors.
//
// `viewAccessor` checks everything needed to read an accessor without touching memory
// outside its buffer (indices in range, type/componentType as the caller requires,
// byteOffset/byteStride/count inside the bufferView); the readers then decode into
// caller-owned vectors (resized once, no per-element allocation) and reject NaN/Inf.
// Every Status names the file, `object` (the caller's description, e.g. "mesh 2 'Floor'
// primitive 0") and the accessor with its role.
#pragma once

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/scene/gltf_context.h"

namespace lightlink::scene::gltf {

struct AccessorView {
  const std::uint8_t* data = nullptr;  // first element; null for a bufferView-less (all zero) accessor
  std::size_t count = 0;
  std::size_t stride_bytes = 0;
  int component_type = 0;  // TINYGLTF_COMPONENT_TYPE_*
  bool normalized = false;
  std::string name;        // "<object> accessor N (ROLE)" for messages
};

struct AccessorRequirement {
  int type;                                  // TINYGLTF_TYPE_*
  std::initializer_list<int> component_types;
  bool allow_unnormalized_integers;          // indices: yes; texcoords: must be normalized
};

Expected<AccessorView> viewAccessor(const Context& ctx, int accessor, const std::string& object,
                                    const char* role, const AccessorRequirement& requirement);

// FLOAT VEC3, every component finite.
Status readVec3(const Context& ctx, const AccessorView& view, std::vector<glm::vec3>& out);
// FLOAT (bit-exact) or normalized UNSIGNED_BYTE/SHORT VEC2, every component finite.
Status readVec2(const Context& ctx, const AccessorView& view, std::vector<glm::vec2>& out);
// UNSIGNED_BYTE/SHORT/INT SCALAR.
void readIndices(const AccessorView& view, std::vector<std::uint32_t>& out);

}  // namespace lightlink::scene::gltf
