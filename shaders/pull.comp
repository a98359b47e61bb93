// One level of the pull (nodes [u_begin, u_end) of one depth, dispatched deepest level
// first, seed 000 sec 4.1): an inner node's flux is the sum of its children's. Leaves keep
// the flux leaf_flux.comp wrote. Flux, not radiosity, goes up the tree: no area reads here.
#version 450
layout(local_size_x = 256) in;
#include "gpu_layout.h"
layout(std430, binding = kPuNodes) readonly buffer Nodes { ivec4 nodes[]; };
layout(std430, binding = kPuFlux) buffer Flux { vec4 flux[]; };
uniform uint u_begin;
uniform uint u_end;
void main() {
  uint n = u_begin + gl_GlobalInvocationID.x;
  if (n >= u_end) return;
  ivec4 node = nodes[n];
  if (node.x >= 0) flux[n] = flux[node.x] + flux[node.y];
}
