#include "core/scene/light_eval.h"

#include <cmath>

namespace lightlink::scene {

float spotAttenuation(const Light& light, glm::vec3 light_to_point) {
  if (light.kind != Light::Kind::kSpot) return 1.0f;
  const float cos_angle = glm::dot(light.direction, light_to_point);
  const float cos_outer = std::cos(light.outer_cone_angle);
  const float cos_inner = std::cos(light.inner_cone_angle);
  if (cos_inner <= cos_outer) return cos_angle >= cos_outer ? 1.0f : 0.0f;  // hard-edged cone
  const float t = glm::clamp((cos_angle - cos_outer) / (cos_inner - cos_outer), 0.0f, 1.0f);
  return t * t;
}

float rangeWindow(const Light& light, float distance_m) {
  if (!(light.range > 0.0f)) return 1.0f;
  const float r = distance_m / light.range;
  const float w = glm::clamp(1.0f - r * r * r * r, 0.0f, 1.0f);
  return w * w;
}

glm::vec3 irradianceFrom(const Light& light, glm::vec3 point, glm::vec3 normal) {
  if (light.kind == Light::Kind::kDirectional) {
    const float cos_theta = glm::dot(normal, -light.direction);
    return cos_theta > 0.0f ? light.color * light.intensity * cos_theta : glm::vec3(0.0f);
  }
  const glm::vec3 to_light = light.position - point;
  const float d2 = glm::dot(to_light, to_light);
  if (!(d2 > 0.0f)) return glm::vec3(0.0f);
  const float d = std::sqrt(d2);
  const glm::vec3 wi = to_light / d;
  const float cos_theta = glm::dot(normal, wi);
  if (cos_theta <= 0.0f) return glm::vec3(0.0f);
  const float falloff = spotAttenuation(light, -wi) * rangeWindow(light, d);
  return light.color * (light.intensity * cos_theta / d2 * falloff);
}

}  // namespace lightlink::scene
