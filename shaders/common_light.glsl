// Unshadowed light evaluation (scene::irradianceFrom, glTF KHR_lights_punctual) and the
// shadow-map visibility test, for light_points.comp. Expects gpu_layout.h included first.

float spotAttenuation(GpuLight l, vec3 light_to_point) {
  if (l.kind_views.x != kLightSpot) return 1.0;
  float cos_angle = dot(l.direction_cos_outer.xyz, light_to_point);
  float cos_outer = l.direction_cos_outer.w, cos_inner = l.cos_inner_baked.x;
  if (cos_inner <= cos_outer) return cos_angle >= cos_outer ? 1.0 : 0.0;
  float t = clamp((cos_angle - cos_outer) / (cos_inner - cos_outer), 0.0, 1.0);
  return t * t;
}

float rangeWindow(GpuLight l, float d) {
  float range = l.position_range.w;
  if (!(range > 0.0)) return 1.0;
  float r = d / range;
  float w = clamp(1.0 - r * r * r * r, 0.0, 1.0);
  return w * w;
}

vec3 irradianceFrom(GpuLight l, vec3 p, vec3 n) {
  vec3 color = l.color_intensity.rgb;
  float intensity = l.color_intensity.w;
  if (l.kind_views.x == kLightDirectional) {
    float cos_theta = dot(n, -l.direction_cos_outer.xyz);
    return cos_theta > 0.0 ? color * intensity * cos_theta : vec3(0.0);
  }
  vec3 to_light = l.position_range.xyz - p;
  float d2 = dot(to_light, to_light);
  if (!(d2 > 0.0)) return vec3(0.0);
  float d = sqrt(d2);
  vec3 wi = to_light / d;
  float cos_theta = dot(n, wi);
  if (cos_theta <= 0.0) return vec3(0.0);
  float falloff = spotAttenuation(l, -wi) * rangeWindow(l, d);
  return color * (intensity * cos_theta / d2 * falloff);
}
