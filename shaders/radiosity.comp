// Node radiosity once per pull, over all nodes in one dispatch: B = Phi * (1 / A) (0 for a
// zero-area node), the (R, G, B, 0) quadruples cache lighting reads. FULL also writes
// reflected + emitted radiosity, what grid caches read when surfaces emit.
#version 450
layout(local_size_x = 256) in;
#include "gpu_layout.h"
layout(std430, binding = kPuNodes) readonly buffer Nodes { ivec4 nodes[]; };
layout(std430, binding = kPuFlux) readonly buffer Flux { vec4 flux[]; };
layout(std430, binding = kPuRad) writeonly buffer Rad { vec4 rad[]; };
#ifdef FULL
layout(std430, binding = kPuRadEmit) readonly buffer RadEmit { vec4 rad_emit[]; };
layout(std430, binding = kPuRadFull) writeonly buffer RadFull { vec4 rad_full[]; };
#endif
uniform uint u_count;
void main() {
  uint n = gl_GlobalInvocationID.x;
  if (n >= u_count) return;
  vec4 r = vec4(flux[n].xyz * intBitsToFloat(nodes[n].z), 0.0);
  rad[n] = r;
#ifdef FULL
  rad_full[n] = r + rad_emit[n];
#endif
}
