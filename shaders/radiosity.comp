// Node radiosity once per pull, over all nodes in one dispatch: B = Phi * (1 / A) (0 for a
// zero-area node), the (R, G, B, 0) quadruples cache lighting reads (reflected radiosity:
// no cache reads emitted radiosity through its links).
#version 450
layout(local_size_x = 256) in;
#include "gpu_layout.h"
layout(std430, binding = kPuNodes) readonly buffer Nodes { ivec4 nodes[]; };
layout(std430, binding = kPuFlux) readonly buffer Flux { vec4 flux[]; };
layout(std430, binding = kPuRad) writeonly buffer Rad { vec4 rad[]; };
uniform uint u_count;
void main() {
  uint n = gl_GlobalInvocationID.x;
  if (n >= u_count) return;
  rad[n] = vec4(flux[n].xyz * intBitsToFloat(nodes[n].z), 0.0);
}
