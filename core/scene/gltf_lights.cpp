#include "core/scene/gltf_lights.h"

#include <cmath>
#include <limits>

namespace lightlink::scene::gltf {
namespace {

constexpr double kHalfPi = 1.57079632679489661923;

Status checkNonNegative(const Context& ctx, const std::string& object, const char* field, double v) {
  if (!std::isfinite(v)) return ctx.invalid(object, fmt::format("{} is not finite ({})", field, v));
  // Finite in the file's double but +Inf in the float the Scene stores (e.g. 1e39): reject it
  // here, naming the field, instead of letting an infinite light reach the bake
  // (tests/stability, DESIGN.md sec 6).
  if (std::abs(v) > double(std::numeric_limits<float>::max()))
    return ctx.invalid(object, fmt::format("{} is not finite in single precision ({})", field, v));
  if (v < 0.0) return ctx.invalid(object, fmt::format("{} is negative ({})", field, v));
  return Status::ok();
}

// The light as the file states it, in the light's own frame (position/direction unset).
Expected<Light> convertLight(const Context& ctx, int index) {
  const tinygltf::Light& gl = ctx.model.lights[static_cast<std::size_t>(index)];
  const std::string object = describe("KHR_lights_punctual light", index, gl.name);
  Light light;
  light.name = gl.name.empty() ? fmt::format("light {}", index) : gl.name;
  if (gl.type == "point") {
    light.kind = Light::Kind::kPoint;
  } else if (gl.type == "spot") {
    light.kind = Light::Kind::kSpot;
  } else if (gl.type == "directional") {
    light.kind = Light::Kind::kDirectional;
  } else {
    return ctx.invalid(object, fmt::format("type '{}' is not point, spot or directional", gl.type));
  }
  if (!gl.color.empty()) {
    if (gl.color.size() != 3) {
      return ctx.invalid(object, fmt::format("color has {} numbers, expected 3", gl.color.size()));
    }
    for (std::size_t c = 0; c < 3; ++c) {
      if (Status s = checkNonNegative(ctx, object, c == 0 ? "color[0]" : c == 1 ? "color[1]" : "color[2]",
                                      gl.color[c]); !s) {
        return s;
      }
    }
    light.color = glm::vec3(gl.color[0], gl.color[1], gl.color[2]);
  }
  if (Status s = checkNonNegative(ctx, object, "intensity", gl.intensity); !s) return s;
  if (Status s = checkNonNegative(ctx, object, "range", gl.range); !s) return s;
  light.intensity = static_cast<float>(gl.intensity);
  light.range = static_cast<float>(gl.range);
  if (light.kind == Light::Kind::kSpot) {
    const double inner = gl.spot.innerConeAngle;
    const double outer = gl.spot.outerConeAngle;
    if (!std::isfinite(inner) || !std::isfinite(outer)) {
      return ctx.invalid(object, fmt::format("spot cone angles are not finite (inner {}, outer {})",
                                             inner, outer));
    }
    // glTF: 0 <= inner < outer <= pi/2. inner == outer is accepted as a hard-edged cone.
    if (inner < 0.0 || outer <= 0.0 || inner > outer || outer > kHalfPi + 1e-6) {
      return ctx.invalid(object, fmt::format("spot cone angles inner {} / outer {} rad violate "
                                             "0 <= inner <= outer <= pi/2", inner, outer));
    }
    light.inner_cone_angle = static_cast<float>(inner);
    light.outer_cone_angle = static_cast<float>(outer);
  }
  return light;
}

}  // namespace

Status loadLights(const Context& ctx, const std::vector<PlacedNode>& nodes) {
  const tinygltf::Model& model = ctx.model;
  std::vector<Light> lights;
  lights.reserve(model.lights.size());
  for (std::size_t i = 0; i < model.lights.size(); ++i) {
    Expected<Light> light = convertLight(ctx, static_cast<int>(i));
    if (!light) return light.status();
    lights.push_back(std::move(*light));
  }
  std::uint64_t placed_lights = 0;
  for (const PlacedNode& placed : nodes) {
    const tinygltf::Node& node = model.nodes[static_cast<std::size_t>(placed.node)];
    const auto ext = node.extensions.find("KHR_lights_punctual");
    if (ext == node.extensions.end()) continue;
    // Every relight evaluates every light: a graph placing more than the budget is refused.
    if (ctx.options.max_lights != 0 && ++placed_lights > ctx.options.max_lights)
      return {Code::kResourceExhausted,
              fmt::format("{}: the node graph places more than {} KHR_lights_punctual lights (max_lights)", ctx.file,
                          ctx.options.max_lights)};
    const std::string object = describeNode(model, placed.node);
    const tinygltf::Value& v = ext->second;
    if (!v.IsObject() || !v.Has("light") || !v.Get("light").IsNumber()) {
      return ctx.invalid(object, "KHR_lights_punctual has no light index");
    }
    const double index = v.Get("light").GetNumberAsDouble();
    if (!(index >= 0.0) || index >= static_cast<double>(lights.size()) || index != std::floor(index)) {
      return ctx.invalid(object, fmt::format("KHR_lights_punctual.light {} does not exist (the file "
                                             "has {} lights)", index, lights.size()));
    }
    Light light = lights[static_cast<std::size_t>(index)];
    light.gltf_node = placed.node;
    light.position = glm::vec3(placed.world_from_node[3]);
    // Normalised because node scale may stretch -Z; placeNodes rejected degenerate bases.
    light.direction = glm::vec3(glm::normalize(glm::dmat3(placed.world_from_node) *
                                               glm::dvec3(0.0, 0.0, -1.0)));
    ctx.scene.lights.push_back(std::move(light));
  }
  return Status::ok();
}

}  // namespace lightlink::scene::gltf
