// Proximity-field flood, first half of an iteration: each voxel's 3x3 block sum in x and y, the
// twin of flood_xy in voxelise.c (((x-1 + x) + x+1) per row, then the rows the same
// way along y; outside the grid 0), so the sums are the CPU's bits.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_PROX_FLOOD_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
layout(binding = OBS_PROX_FLOOD_B_VAL, r32f) uniform readonly image3D cur;
layout(binding = OBS_PROX_FLOOD_B_SXY, r32f) uniform writeonly image3D sxy;

// Voxels per axis.
ivec3 dims() { return ivec3(pc.dims[0], pc.dims[1], pc.dims[2]); }

float at(ivec3 p) {
  if (any(lessThan(p, ivec3(0))) || any(greaterThanEqual(p, dims()))) return 0.0;
  return imageLoad(cur, p).r;
}

// Row y's sum along x; a row outside the grid sums to 0, as the CPU's missing row does.
float row(ivec3 p) {
  precise float s = (at(p - ivec3(1, 0, 0)) + at(p)) + at(p + ivec3(1, 0, 0));
  return s;
}

void main() {
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, dims()))) return;
  precise float s = (row(p - ivec3(0, 1, 0)) + row(p)) + row(p + ivec3(0, 1, 0));
  imageStore(sxy, p, vec4(s));
}
