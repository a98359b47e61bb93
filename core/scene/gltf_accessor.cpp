#include "core/scene/gltf_accessor.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace lightlink::scene::gltf {
namespace {

std::string typeName(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return fmt::format("{} (not a glTF type)", type);
  }
}

std::string componentName(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_INT: return "INT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return "FLOAT";
    default: return fmt::format("{} (not a glTF componentType)", component_type);
  }
}

template <typename T>
T load(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));  // glTF data need not be aligned for T
  return v;
}

bool finite(float v) { return std::isfinite(v); }

}  // namespace

Expected<AccessorView> viewAccessor(const Context& ctx, int accessor, const std::string& object,
                                    const char* role, const AccessorRequirement& requirement) {
  const tinygltf::Model& model = ctx.model;
  if (accessor < 0 || static_cast<std::size_t>(accessor) >= model.accessors.size()) {
    return ctx.invalid(object, fmt::format("{} refers to accessor {}, but the file has {}", role,
                                           accessor, model.accessors.size()));
  }
  const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(accessor)];
  AccessorView view;
  view.name = fmt::format("{} accessor {} ({})", object, accessor, role);

  if (a.sparse.isSparse) {
    return ctx.unsupported(view.name, "sparse accessors are not supported");
  }
  if (a.type != requirement.type) {
    return ctx.invalid(view.name, fmt::format("type is {}, expected {}", typeName(a.type),
                                              typeName(requirement.type)));
  }
  const bool type_ok = std::find(requirement.component_types.begin(),
                                 requirement.component_types.end(),
                                 a.componentType) != requirement.component_types.end();
  if (!type_ok) {
    std::string allowed;
    for (int t : requirement.component_types) {
      allowed += allowed.empty() ? "" : "/";
      allowed += componentName(t);
    }
    return ctx.invalid(view.name, fmt::format("componentType is {}, expected {}",
                                              componentName(a.componentType), allowed));
  }
  if (a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !a.normalized &&
      !requirement.allow_unnormalized_integers) {
    return ctx.invalid(view.name, fmt::format("{} components must be normalized",
                                              componentName(a.componentType)));
  }
  if (a.count == 0) return ctx.invalid(view.name, "count is 0");

  const int component_bytes = tinygltf::GetComponentSizeInBytes(
      static_cast<std::uint32_t>(a.componentType));
  const int components = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type));
  const std::size_t element_bytes = static_cast<std::size_t>(component_bytes * components);
  view.count = a.count;
  view.component_type = a.componentType;
  view.normalized = a.normalized;
  view.stride_bytes = element_bytes;

  if (a.bufferView < 0) {
    return view;  // glTF: an accessor without a bufferView reads as zeros
  }
  if (static_cast<std::size_t>(a.bufferView) >= model.bufferViews.size()) {
    return ctx.invalid(view.name, fmt::format("bufferView {} does not exist (the file has {})",
                                              a.bufferView, model.bufferViews.size()));
  }
  const tinygltf::BufferView& bv = model.bufferViews[static_cast<std::size_t>(a.bufferView)];
  if (bv.byteStride != 0) {
    if (bv.byteStride < element_bytes) {
      return ctx.invalid(view.name,
                         fmt::format("bufferView {} byteStride {} is smaller than the {}-byte "
                                     "element", a.bufferView, bv.byteStride, element_bytes));
    }
    view.stride_bytes = bv.byteStride;
  }
  // Bound count first so (count - 1) * stride cannot overflow.
  const std::size_t last = a.count - 1;
  const bool fits = a.byteOffset <= bv.byteLength && element_bytes <= bv.byteLength - a.byteOffset &&
                    last <= (bv.byteLength - a.byteOffset - element_bytes) / view.stride_bytes;
  if (!fits) {
    return ctx.invalid(
        view.name,
        fmt::format("byteOffset {} + {} elements x stride {} B ({} B each) exceed bufferView {} "
                    "byteLength {}",
                    a.byteOffset, a.count, view.stride_bytes, element_bytes, a.bufferView,
                    bv.byteLength));
  }
  // Buffer ranges of every bufferView were checked up front (validateStructure).
  const tinygltf::Buffer& buffer = model.buffers[static_cast<std::size_t>(bv.buffer)];
  view.data = buffer.data.data() + bv.byteOffset + a.byteOffset;
  return view;
}

Status readVec3(const Context& ctx, const AccessorView& view, std::vector<glm::vec3>& out) {
  out.assign(view.count, glm::vec3(0.0f));
  if (view.data == nullptr) return Status::ok();
  for (std::size_t i = 0; i < view.count; ++i) {
    const std::uint8_t* p = view.data + i * view.stride_bytes;
    glm::vec3 v(load<float>(p), load<float>(p + 4), load<float>(p + 8));
    if (!finite(v.x) || !finite(v.y) || !finite(v.z)) {
      // Which element, not its values: messages never quote the bytes of a buffer.
      return ctx.invalid(view.name, fmt::format("element {} is not finite", i));
    }
    out[i] = v;
  }
  return Status::ok();
}

Status readVec2(const Context& ctx, const AccessorView& view, std::vector<glm::vec2>& out) {
  out.assign(view.count, glm::vec2(0.0f));
  if (view.data == nullptr) return Status::ok();
  for (std::size_t i = 0; i < view.count; ++i) {
    const std::uint8_t* p = view.data + i * view.stride_bytes;
    glm::vec2 v;
    switch (view.component_type) {
      case TINYGLTF_COMPONENT_TYPE_FLOAT:
        v = glm::vec2(load<float>(p), load<float>(p + 4));
        break;
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        v = glm::vec2(p[0], p[1]) / 255.0f;
        break;
      default:  // UNSIGNED_SHORT, the only other type viewAccessor lets through
        v = glm::vec2(load<std::uint16_t>(p), load<std::uint16_t>(p + 2)) / 65535.0f;
        break;
    }
    if (!finite(v.x) || !finite(v.y)) {
      return ctx.invalid(view.name, fmt::format("element {} is not finite", i));
    }
    out[i] = v;
  }
  return Status::ok();
}

void readIndices(const AccessorView& view, std::vector<std::uint32_t>& out) {
  out.assign(view.count, 0u);
  if (view.data == nullptr) return;
  for (std::size_t i = 0; i < view.count; ++i) {
    const std::uint8_t* p = view.data + i * view.stride_bytes;
    switch (view.component_type) {
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: out[i] = p[0]; break;
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: out[i] = load<std::uint16_t>(p); break;
      default: out[i] = load<std::uint32_t>(p); break;
    }
  }
}

}  // namespace lightlink::scene::gltf
