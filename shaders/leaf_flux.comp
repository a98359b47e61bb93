// Surfel radiosity to leaf flux: Phi_leaf = B_s * A_s (the pull sums flux, seed 000 sec 4.1).
#version 450
layout(local_size_x = 256) in;
#include "gpu_layout.h"
layout(std430, binding = kLfRadiosity) readonly buffer Radiosity { vec4 radiosity[]; };
layout(std430, binding = kLfArea) readonly buffer Area { float area[]; };
layout(std430, binding = kLfLeaf) readonly buffer Leaf { uint leaf_of_surfel[]; };
layout(std430, binding = kLfFlux) writeonly buffer Flux { vec4 flux[]; };
uniform uint u_count;
void main() {
  uint s = gl_GlobalInvocationID.x;
  if (s >= u_count) return;
  flux[leaf_of_surfel[s]] = vec4(radiosity[s].xyz * area[s], 0.0);
}
