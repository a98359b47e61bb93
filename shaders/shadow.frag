// Writes the depth metric of light_points.comp: distance to the light (point, spot) or
// distance along the light direction (directional). Both faces are drawn (no culling), as
// the CPU's shadow rays stop at either side of a triangle.
#version 450
in vec3 v_world;
uniform vec3 u_eye;
uniform vec3 u_dir;
uniform int u_ortho;
layout(location = 0) out float o_metric;
void main() { o_metric = u_ortho != 0 ? dot(v_world - u_eye, u_dir) : length(v_world - u_eye); }
