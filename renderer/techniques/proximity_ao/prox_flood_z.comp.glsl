// Proximity-field flood, second half of an iteration: the block sum along z and the update
// P <- 0.5 (P + (S - P) inv26) of unoccupied voxels, the twin of flood_z in
// voxelise.c. Each voxel reads its own value and writes it in place (no other
// invocation of this pass reads it). inv26 is the host's float 1/26; `precise` keeps every
// product and sum a separate rounding, so the bits are the CPU's.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_PROX_FLOOD_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
layout(binding = OBS_PROX_FLOOD_B_VAL, r32f) uniform image3D val;
layout(binding = OBS_PROX_FLOOD_B_SXY, r32f) uniform readonly image3D sxy;
layout(binding = OBS_PROX_FLOOD_B_OCC, r32f) uniform readonly image3D occ;

// Voxels per axis.
ivec3 dims() { return ivec3(pc.dims[0], pc.dims[1], pc.dims[2]); }

float at(ivec3 p) {
  if (p.z < 0 || p.z >= pc.dims[2]) return 0.0;
  return imageLoad(sxy, p).r;
}

void main() {
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, dims()))) return;
  precise float s = (at(p - ivec3(0, 0, 1)) + at(p)) + at(p + ivec3(0, 0, 1));
  float c = imageLoad(val, p).r;
  precise float next = 0.5 * (c + (s - c) * pc.inv26);
  imageStore(val, p, vec4(imageLoad(occ, p).r > 0.5 ? 1.0 : next));
}
