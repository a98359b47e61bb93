#include "core/scene/gltf_primitive.h"

#include <cmath>
#include <numeric>

#include "core/scene/gltf_accessor.h"
#include "core/scene/mesh_ops.h"

namespace lightlink::scene::gltf {
namespace {

const char* modeName(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP: return "LINE_STRIP";
    default: return "unknown";
  }
}

const AccessorRequirement kVec3Float{TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT}, false};
const AccessorRequirement kTexcoord{
    TINYGLTF_TYPE_VEC2,
    {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
     TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
    false};
const AccessorRequirement kIndices{
    TINYGLTF_TYPE_SCALAR,
    {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
     TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
    true};

// Strip/fan vertex order per glTF 2.0 section 3.7.2.1, so front faces stay front.
void triangulate(int mode, const std::vector<std::uint32_t>& in, std::vector<std::uint32_t>& out) {
  out.clear();
  if (in.size() < 3) return;
  out.reserve((in.size() - 2) * 3);
  for (std::size_t i = 0; i + 2 < in.size(); ++i) {
    if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      const bool odd = (i % 2) == 1;
      out.insert(out.end(), {in[i], in[odd ? i + 2 : i + 1], in[odd ? i + 1 : i + 2]});
    } else {  // TRIANGLE_FAN
      out.insert(out.end(), {in[i + 1], in[i + 2], in[0]});
    }
  }
}

std::string instanceName(const tinygltf::Model& model, int node, int mesh, int primitive) {
  const std::string& mesh_name = model.meshes[static_cast<std::size_t>(mesh)].name;
  const std::string& node_name = model.nodes[static_cast<std::size_t>(node)].name;
  const std::string base = !mesh_name.empty() ? mesh_name
                           : !node_name.empty() ? node_name
                                                : fmt::format("mesh{}", mesh);
  return fmt::format("{}/{}", base, primitive);
}

}  // namespace

Expected<MeshInstance> buildInstance(const Context& ctx, const PlacedNode& placed, int mesh,
                                     int primitive) {
  const tinygltf::Model& model = ctx.model;
  const tinygltf::Primitive& prim =
      model.meshes[static_cast<std::size_t>(mesh)].primitives[static_cast<std::size_t>(primitive)];
  const std::string object = describePrimitive(model, mesh, primitive);

  const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
  if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
      mode != TINYGLTF_MODE_TRIANGLE_FAN) {
    return ctx.unsupported(object, fmt::format("mode {} ({}) is not supported; only triangles, "
                                               "triangle strips and fans are",
                                               mode, modeName(mode)));
  }
  if (prim.material >= 0 && static_cast<std::size_t>(prim.material) >= model.materials.size()) {
    return ctx.invalid(object, fmt::format("refers to material {}, but the file has {}",
                                           prim.material, model.materials.size()));
  }
  if (!prim.targets.empty()) {
    ctx.warn(object, "morph targets are ignored; the base shape is used");
  }

  MeshInstance out;
  out.name = instanceName(model, placed.node, mesh, primitive);
  out.gltf_node = placed.node;
  out.gltf_mesh = mesh;
  out.gltf_primitive = primitive;
  out.material = prim.material;
  out.is_static = placed.is_static;
  out.lightmap_scale = placed.lightmap_scale;
  out.probe_lit = placed.probe_lit;
  // Node extras (inherited) over material extras over the defaults.
  const Material* material = prim.material < 0 ? nullptr : &ctx.scene.materials[static_cast<std::size_t>(prim.material)];
  out.cast_shadows = placed.cast_shadows >= 0 ? placed.cast_shadows == 1 : material == nullptr || material->cast_shadows;
  out.contribute_gi = placed.contribute_gi >= 0 ? placed.contribute_gi == 1 : material == nullptr || material->contribute_gi;
  const int receive = placed.receive_gi >= 0                          ? placed.receive_gi
                      : placed.probe_lit                              ? int(ReceiveGi::kVolume)
                      : material != nullptr && material->receive_gi >= 0 ? material->receive_gi
                                                                         : int(ReceiveGi::kLightmap);
  out.receive_gi = static_cast<ReceiveGi>(receive);
  out.probe_lit = out.receive_gi != ReceiveGi::kLightmap;
  out.world_from_mesh = glm::mat4(placed.world_from_node);

  const auto attribute = [&](const char* semantic) {
    const auto it = prim.attributes.find(semantic);
    return it == prim.attributes.end() ? -1 : it->second;
  };

  // Positions (mesh space for now).
  const int position_accessor = attribute("POSITION");
  if (position_accessor < 0) return ctx.invalid(object, "has no POSITION attribute");
  Expected<AccessorView> positions = viewAccessor(ctx, position_accessor, object, "POSITION", kVec3Float);
  if (!positions) return positions.status();
  if (Status s = readVec3(ctx, *positions, out.positions); !s) return s;
  const std::size_t vertex_count = out.positions.size();

  const auto sameCount = [&](const AccessorView& view) -> Status {
    if (view.count != vertex_count) {
      return ctx.invalid(view.name, fmt::format("count {} differs from the POSITION count {}",
                                                view.count, vertex_count));
    }
    return Status::ok();
  };

  const int normal_accessor = attribute("NORMAL");
  if (normal_accessor >= 0) {
    Expected<AccessorView> normals = viewAccessor(ctx, normal_accessor, object, "NORMAL", kVec3Float);
    if (!normals) return normals.status();
    if (Status s = sameCount(*normals); !s) return s;
    if (Status s = readVec3(ctx, *normals, out.normals); !s) return s;
  }
  const char* texcoord_names[2] = {"TEXCOORD_0", "TEXCOORD_1"};
  std::vector<glm::vec2>* texcoord_out[2] = {&out.uv0, &out.uv1};
  for (int set = 0; set < 2; ++set) {
    const int accessor = attribute(texcoord_names[set]);
    if (accessor < 0) continue;
    Expected<AccessorView> uv = viewAccessor(ctx, accessor, object, texcoord_names[set], kTexcoord);
    if (!uv) return uv.status();
    if (Status s = sameCount(*uv); !s) return s;
    if (Status s = readVec2(ctx, *uv, *texcoord_out[set]); !s) return s;
  }

  // Indices, range-checked, then triangulated.
  std::vector<std::uint32_t> raw;
  std::string index_name = fmt::format("{} (non-indexed)", object);
  if (prim.indices >= 0) {
    Expected<AccessorView> indices = viewAccessor(ctx, prim.indices, object, "indices", kIndices);
    if (!indices) return indices.status();
    index_name = indices->name;
    readIndices(*indices, raw);
    for (std::size_t i = 0; i < raw.size(); ++i) {
      if (raw[i] >= vertex_count) {
        // The value itself is not shown: messages never quote the bytes of a buffer.
        return ctx.invalid(index_name, fmt::format("the index at element {} is out of range for {} vertices", i,
                                                   vertex_count));
      }
    }
  } else {
    raw.resize(vertex_count);
    std::iota(raw.begin(), raw.end(), 0u);
  }
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    if (raw.size() % 3 != 0) {
      return ctx.invalid(index_name, fmt::format("{} indices is not a multiple of 3 for "
                                                 "TRIANGLES", raw.size()));
    }
    out.indices = std::move(raw);
  } else {
    triangulate(mode, raw, out.indices);
  }

  // To world space. Double precision for the transform, then one rounding to float.
  const glm::dmat4& world = placed.world_from_node;
  for (glm::vec3& p : out.positions) {
    p = glm::vec3(world * glm::dvec4(glm::dvec3(p), 1.0));
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      return ctx.invalid(object, fmt::format("a world-space position overflows single precision "
                                             "under {}", describeNode(model, placed.node)));
    }
  }
  const glm::dmat3 linear(world);
  if (glm::determinant(linear) < 0.0) {
    // A mirror reverses the handedness of the triangle; swapping two corners keeps the
    // counter-clockwise = front rule in world space.
    for (std::size_t t = 0; t + 2 < out.indices.size(); t += 3) {
      std::swap(out.indices[t + 1], out.indices[t + 2]);
    }
  }

  if (out.material >= 0) {
    // albedoAt/emissionAt fall back to the factor alone; say so once per primitive.
    const Material& material = ctx.scene.materials[static_cast<std::size_t>(out.material)];
    const std::pair<const char*, TextureRef> refs[2] = {{"baseColorTexture", material.base_color_texture},
                                                        {"emissiveTexture", material.emissive_texture}};
    for (const auto& [field, ref] : refs) {
      if (ref.valid() && (ref.texcoord == 1 ? out.uv1 : out.uv0).empty()) {
        ctx.warn(object, fmt::format("material {} reads its {} through TEXCOORD_{}, which this "
                                     "primitive lacks; the factor alone applies",
                                     out.material, field, ref.texcoord));
      }
    }
  }

  if (const std::size_t replaced = worldNormalsOrGenerated(linear, out); replaced > 0)
    ctx.warn(object, fmt::format("{} zero-length normals replaced by generated ones", replaced));
  return out;
}

}  // namespace lightlink::scene::gltf
