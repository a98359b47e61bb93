#include "core/scene/gltf_nodes.h"

#include <algorithm>
#include <cmath>

#include <glm/gtc/quaternion.hpp>

namespace lightlink::scene::gltf {
namespace {

// |det| relative to the cube of the longest basis vector: 1 for a rotation times a uniform
// scale, 0 for a collapsed axis. Below this a transform flattens geometry past float
// precision and its inverse-transpose (for normals) is meaningless.
constexpr double kMinRelativeDeterminant = 1e-9;

bool finiteMatrix(const glm::dmat4& m) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(m[c][r])) return false;
    }
  }
  return true;
}

double relativeDeterminant(const glm::dmat4& m) {
  const glm::dmat3 b(m);
  const double longest =
      std::max({glm::length(b[0]), glm::length(b[1]), glm::length(b[2])});
  if (!(longest > 0.0)) return 0.0;
  return std::abs(glm::determinant(b)) / (longest * longest * longest);
}

template <typename Vec>
Status checkFinite(const Context& ctx, const std::string& object, const char* field,
                   const Vec& values) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return ctx.invalid(object, fmt::format("{}[{}] is not finite ({})", field, i, values[i]));
    }
  }
  return Status::ok();
}

Expected<glm::dmat4> localTransform(const Context& ctx, int index) {
  const tinygltf::Node& node = ctx.model.nodes[static_cast<std::size_t>(index)];
  const std::string object = describeNode(ctx.model, index);
  if (!node.matrix.empty()) {
    if (node.matrix.size() != 16) {
      return ctx.invalid(object, fmt::format("matrix has {} numbers, expected 16", node.matrix.size()));
    }
    if (Status s = checkFinite(ctx, object, "matrix", node.matrix); !s) return s;
    glm::dmat4 m;
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) m[c][r] = node.matrix[static_cast<std::size_t>(c * 4 + r)];
    }
    if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0) {
      return ctx.invalid(object, fmt::format("matrix is not affine (last row {} {} {} {})",
                                             m[0][3], m[1][3], m[2][3], m[3][3]));
    }
    return m;
  }
  glm::dvec3 t(0.0);
  glm::dquat r(1.0, 0.0, 0.0, 0.0);  // glm::dquat(w, x, y, z)
  glm::dvec3 s(1.0);
  if (!node.translation.empty()) {
    if (node.translation.size() != 3) {
      return ctx.invalid(object, fmt::format("translation has {} numbers, expected 3",
                                             node.translation.size()));
    }
    if (Status st = checkFinite(ctx, object, "translation", node.translation); !st) return st;
    t = {node.translation[0], node.translation[1], node.translation[2]};
  }
  if (!node.rotation.empty()) {
    if (node.rotation.size() != 4) {
      return ctx.invalid(object, fmt::format("rotation has {} numbers, expected 4",
                                             node.rotation.size()));
    }
    if (Status st = checkFinite(ctx, object, "rotation", node.rotation); !st) return st;
    // glTF stores quaternions as x, y, z, w.
    r = glm::dquat(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    const double len = glm::length(r);
    if (!(len > 1e-12)) return ctx.invalid(object, "rotation quaternion has zero length");
    r = r / len;  // exporters round; a non-unit quaternion would add scale and skew
  }
  if (!node.scale.empty()) {
    if (node.scale.size() != 3) {
      return ctx.invalid(object, fmt::format("scale has {} numbers, expected 3", node.scale.size()));
    }
    if (Status st = checkFinite(ctx, object, "scale", node.scale); !st) return st;
    s = {node.scale[0], node.scale[1], node.scale[2]};
  }
  glm::dmat4 m = glm::mat4_cast(r);
  m[0] *= s.x;
  m[1] *= s.y;
  m[2] *= s.z;
  m[3] = glm::dvec4(t, 1.0);
  return m;
}

}  // namespace

Expected<int> parseReceiveGi(const Context& ctx, const std::string& object, const tinygltf::Value& v) {
  if (v.IsString()) {
    const std::string& s = v.Get<std::string>();
    if (s == "lightmap") return int(ReceiveGi::kLightmap);
    if (s == "volume") return int(ReceiveGi::kVolume);
    if (s == "off") return int(ReceiveGi::kOff);
  }
  return ctx.invalid(object, "extras.lightlink.receive_gi must be \"lightmap\", \"volume\" or \"off\"");
}

Expected<NodeOverrides> nodeOverrides(const Context& ctx, int index) {
  NodeOverrides out;
  const tinygltf::Value& extras = ctx.model.nodes[static_cast<std::size_t>(index)].extras;
  if (!extras.IsObject() || !extras.Has("lightlink")) return out;
  const tinygltf::Value& ours = extras.Get("lightlink");
  const std::string object = describeNode(ctx.model, index);
  if (!ours.IsObject()) return ctx.invalid(object, "extras.lightlink must be an object");
  if (ours.Has("static")) {
    const tinygltf::Value& flag = ours.Get("static");
    if (!flag.IsBool()) return ctx.invalid(object, "extras.lightlink.static must be true or false");
    out.is_static = flag.Get<bool>() ? 1 : 0;
  }
  if (ours.Has("lightmap")) {
    const tinygltf::Value& flag = ours.Get("lightmap");
    if (!flag.IsBool()) return ctx.invalid(object, "extras.lightlink.lightmap must be true or false");
    out.lightmap = flag.Get<bool>() ? 1 : 0;
  }
  if (ours.Has("cast_shadows")) {
    const tinygltf::Value& flag = ours.Get("cast_shadows");
    if (!flag.IsBool()) return ctx.invalid(object, "extras.lightlink.cast_shadows must be true or false");
    out.cast_shadows = flag.Get<bool>() ? 1 : 0;
  }
  if (ours.Has("contribute_gi")) {
    const tinygltf::Value& flag = ours.Get("contribute_gi");
    if (!flag.IsBool()) return ctx.invalid(object, "extras.lightlink.contribute_gi must be true or false");
    out.contribute_gi = flag.Get<bool>() ? 1 : 0;
  }
  if (ours.Has("receive_gi")) {
    Expected<int> r = parseReceiveGi(ctx, object, ours.Get("receive_gi"));
    if (!r) return r.status();
    out.receive_gi = *r;
  }
  if (ours.Has("lightmap_scale")) {
    const tinygltf::Value& v = ours.Get("lightmap_scale");
    const double scale = v.IsNumber() ? v.GetNumberAsDouble() : std::nan("");
    if (!(scale >= 1.0 / 64.0 && scale <= 64.0))
      return ctx.invalid(object, "extras.lightlink.lightmap_scale must be a number in [1/64, 64]");
    out.lightmap_scale = static_cast<float>(scale);
  }
  return out;
}

Expected<std::vector<PlacedNode>> placeNodes(const Context& ctx) {
  const tinygltf::Model& model = ctx.model;
  const std::size_t node_count = model.nodes.size();

  std::vector<int> roots;
  if (!model.scenes.empty()) {
    const int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
    if (static_cast<std::size_t>(scene) >= model.scenes.size()) {
      return ctx.invalid("scene", fmt::format("default scene {} does not exist (the file has {})",
                                              scene, model.scenes.size()));
    }
    roots = model.scenes[static_cast<std::size_t>(scene)].nodes;
  } else {
    std::vector<char> is_child(node_count, 0);
    for (const tinygltf::Node& n : model.nodes) {
      for (int c : n.children) {
        if (c >= 0 && static_cast<std::size_t>(c) < node_count) is_child[static_cast<std::size_t>(c)] = 1;
      }
    }
    for (std::size_t i = 0; i < node_count; ++i) {
      if (!is_child[i]) roots.push_back(static_cast<int>(i));
    }
  }

  struct Pending {
    int node;
    glm::dmat4 parent_world;
    bool parent_static;
    int parent;
    float parent_scale = 1.0f;
    bool parent_probe_lit = false;
    int parent_cast_shadows = -1;
    int parent_contribute_gi = -1;
    int parent_receive_gi = -1;
  };
  std::vector<Pending> stack;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it) {
    stack.push_back({*it, glm::dmat4(1.0), true, -1});
  }

  std::vector<char> visited(node_count, 0);
  std::vector<PlacedNode> placed;
  placed.reserve(node_count);
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (p.node < 0 || static_cast<std::size_t>(p.node) >= node_count) {
      const std::string where = p.parent < 0 ? std::string("scene")
                                             : describeNode(model, p.parent);
      return ctx.invalid(where, fmt::format("refers to node {}, but the file has {} nodes",
                                            p.node, node_count));
    }
    const std::string object = describeNode(model, p.node);
    if (visited[static_cast<std::size_t>(p.node)]) {
      return ctx.invalid(object, "is reached twice: the node hierarchy has a cycle or a node "
                                 "with two parents (glTF requires a tree)");
    }
    visited[static_cast<std::size_t>(p.node)] = 1;

    Expected<glm::dmat4> local = localTransform(ctx, p.node);
    if (!local) return local.status();
    if (relativeDeterminant(*local) < kMinRelativeDeterminant) {
      return ctx.invalid(object, "transform is degenerate (a zero or collapsed scale axis)");
    }
    const glm::dmat4 world = p.parent_world * *local;
    if (!finiteMatrix(world) || !finiteMatrix(glm::dmat4(glm::mat4(world)))) {
      return ctx.invalid(object, "world transform is not finite in single precision");
    }
    if (relativeDeterminant(world) < kMinRelativeDeterminant) {
      return ctx.invalid(object, "world transform (parent * local) is degenerate");
    }
    Expected<NodeOverrides> flags = nodeOverrides(ctx, p.node);
    if (!flags) return flags.status();
    const bool is_static = flags->is_static < 0 ? p.parent_static : flags->is_static == 1;
    const float lightmap_scale = flags->lightmap_scale > 0.0f ? flags->lightmap_scale : p.parent_scale;
    const bool probe_lit = flags->lightmap < 0 ? p.parent_probe_lit : flags->lightmap == 0;
    const int cast_shadows = flags->cast_shadows < 0 ? p.parent_cast_shadows : flags->cast_shadows;
    const int contribute_gi = flags->contribute_gi < 0 ? p.parent_contribute_gi : flags->contribute_gi;
    const int receive_gi = flags->receive_gi < 0 ? p.parent_receive_gi : flags->receive_gi;

    const tinygltf::Node& node = model.nodes[static_cast<std::size_t>(p.node)];
    if (node.mesh >= 0 && static_cast<std::size_t>(node.mesh) >= model.meshes.size()) {
      return ctx.invalid(object, fmt::format("refers to mesh {}, but the file has {} meshes",
                                             node.mesh, model.meshes.size()));
    }
    if (node.mesh >= 0 && node.skin >= 0) {
      ctx.warn(object, "skin is ignored; the mesh is placed by the node transform (bind pose)");
    }
    placed.push_back({p.node, world, is_static, lightmap_scale, probe_lit, cast_shadows, contribute_gi, receive_gi});
    for (auto it = node.children.rbegin(); it != node.children.rend(); ++it) {
      stack.push_back({*it, world, is_static, p.node, lightmap_scale, probe_lit, cast_shadows, contribute_gi, receive_gi});
    }
  }
  return placed;
}

}  // namespace lightlink::scene::gltf
