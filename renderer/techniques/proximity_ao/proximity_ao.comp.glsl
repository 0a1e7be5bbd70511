// proximity_ao, reconstruction: per pixel of the rasterised G-buffer, the walk along the normal
// through every field whose box holds the point, the twin of accessibility() in
// cpu.c and obs_prox_occlusion / obs_prox_sample in
// proximity.c, operation for operation (`precise`: no fused multiply-adds). The
// fields are one 3D texture atlas read texel by texel (the CPU's trilinear, not the hardware's).
// One dispatch reads fields [f0, f1) and carries the combination in `acc` to the next, so no
// invocation runs more loop iterations than lavapipe allows. Pixels on an analytic sphere (drawn
// tessellated) take the ray's hit on the true sphere, as the CPU's ray caster does. Bindings,
// push block and the parameter buffer's rows are layout.h's, shared with vulkan.c.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "include/frame.glsl"
#define OBS_PROX_RECON_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = OBS_PROX_B_DEPTH, r32f) uniform readonly image2D g_depth;
layout(binding = OBS_PROX_B_NORMAL, rgba32f) uniform readonly image2D g_normal;
layout(binding = OBS_PROX_B_ALBEDO, rgba32f) uniform readonly image2D g_albedo;
layout(binding = OBS_PROX_B_ACC, rgba32f) uniform image2D acc;
layout(binding = OBS_PROX_B_SURF, rgba32f) uniform image2D surf; // written by the first dispatch
layout(set = 1, binding = 0) uniform sampler3D atlas;
// Rows of 4 floats (layout.h's OBS_PROX_H_* and OBS_PROX_F_*), written by vulkan.c.
layout(set = 1, binding = 4, std430) readonly buffer Data { vec4 rows[]; };

int first_point(int i) { return int(rows[OBS_PROX_H_FIRST + i / 4][i % 4]); }

vec2 disc(int j) {
  vec4 r = rows[OBS_PROX_H_DISC + j / 2];
  return (j & 1) == 0 ? r.xy : r.zw;
}

bool inside(vec3 q, vec3 dims) {
  return q.x >= 0.0 && q.x <= dims.x && q.y >= 0.0 && q.y <= dims.y && q.z >= 0.0 &&
         q.z <= dims.z;
}

float texel(ivec3 at, int x, int y, int z) { return texelFetch(atlas, at + ivec3(x, y, z), 0).r; }

// obs_prox_sample: trilinear between voxel centres, the edge voxels extended. Written without a
// loop over the axes, so the shader's counted loop iterations are the walk's alone.
float field_sample(ivec3 at, ivec3 dims, vec3 g) {
  precise vec3 u = g - 0.5;
  vec3 hi = vec3(dims - 1);
  u = mix(u, vec3(0.0), not(greaterThan(u, vec3(0.0)))); // NaN too, as the CPU's !(u > 0)
  u = mix(u, hi, greaterThan(u, hi));
  ivec3 i0 = ivec3(u), i1 = min(i0 + 1, dims - 1);
  precise vec3 w = u - vec3(i0);
  precise float c00, c01, c10, c11;
  float a = texel(at, i0.x, i0.y, i0.z), b = texel(at, i1.x, i0.y, i0.z);
  c00 = a + (b - a) * w.x;
  a = texel(at, i0.x, i1.y, i0.z), b = texel(at, i1.x, i1.y, i0.z);
  c01 = a + (b - a) * w.x;
  a = texel(at, i0.x, i0.y, i1.z), b = texel(at, i1.x, i0.y, i1.z);
  c10 = a + (b - a) * w.x;
  a = texel(at, i0.x, i1.y, i1.z), b = texel(at, i1.x, i1.y, i1.z);
  c11 = a + (b - a) * w.x;
  precise float y0 = c00 + (c01 - c00) * w.y;
  precise float y1 = c10 + (c11 - c10) * w.y;
  precise float r = y0 + (y1 - y0) * w.z;
  return r;
}

// obs_prox_occlusion: gp the point, gs the step, gt and gb the disc's axes, all in grid units.
float occlusion(ivec3 at, ivec3 dims, vec3 gp, vec3 gs, vec3 gt, vec3 gb) {
  const int n = pc.steps;
  const bool code = pc.mode == 0;
  vec4 rc = rows[OBS_PROX_H_RECON];
  vec3 fd = vec3(dims);
  precise float ao = 0.0;
  float prev = 0.0;
  float base = code ? 2.0 : 0.0;
  for (int i = 0; i < n; i++) {
    precise float d = base + float(i);
    float rad = float(i);
    precise vec3 c = gp + d * gs;
    precise float sum = 0.0;
    int read = 0;
    int j1 = first_point(i + 1);
    for (int j = first_point(i); j < j1; j++) {
      vec2 p = disc(j);
      precise float dx = p.x * rad, dy = p.y * rad;
      precise vec3 q = c + dx * gt + dy * gb;
      if (!inside(q, fd)) continue;
      sum += field_sample(at, dims, q);
      read++;
    }
    precise float value = code ? sum : read > 0 ? sum / float(read) : 0.0;
    if (value < prev) continue;
    precise float weight = code ? 1.0 : 1.0 - float(i) / float(n);
    ao += value * weight;
    if (value > rc.x) break;
    prev = value;
  }
  ao *= rc.y;
  ao /= float(n);
  if (!(ao > 0.0)) ao = 0.0;
  if (ao > 1.0) ao = 1.0;
  precise float r = ao * rc.z;
  return r;
}

// The ray through the pixel (view coordinates) against sphere s (view centre, radius): the
// nearest hit in front of the camera (the far one from inside), its depth and its normal facing
// the ray. The raster's facets are inscribed, so the ray meets the true sphere.
void sphere_hit(vec4 s, vec3 o, vec3 d, inout vec3 p, inout vec3 nrm) {
  precise vec3 co = s.xyz - o;
  precise float dd = dot(d, d);
  precise float tc = dot(co, d) / dd;
  precise vec3 q = co - tc * d;
  precise float h2 = s.w * s.w - dot(q, q);
  precise float h = sqrt(max(h2, 0.0) / dd);
  precise float t = tc - h;
  if (t < 0.0) t = tc + h;
  if (!(t >= 0.0)) return;
  precise vec3 hitp = o + t * d;
  vec3 nn = normalize(hitp - s.xyz);
  if (dot(nn, d) > 0.0) nn = -nn;
  p = hitp;
  nrm = nn;
}

void main() {
  ivec2 l = ivec2(gl_GlobalInvocationID.xy);
  if (l.x >= pc.region[2] || l.y >= pc.region[3]) return;
  ivec2 px = l + ivec2(pc.region[0], pc.region[1]);
  vec4 a = (pc.phase & OBS_PROX_PHASE_FIRST) != 0 ? vec4(0.0, 1.0, 0.0, 0.0)
                                                  : imageLoad(acc, l);
  vec4 nv = imageLoad(g_normal, px);
  bool hit = nv.w > 0.0;
  vec4 sf = vec4(0.0);
  if (hit) {
    int self = int(imageLoad(g_albedo, px).a) - 1;
    vec4 R = rows[OBS_PROX_H_RIGHT], U = rows[OBS_PROX_H_UP], F = rows[OBS_PROX_H_FWD];
    bool ortho = F.w > 0.5;
    precise float sx = (2.0 * (float(px.x) + 0.5) / float(pc.size[0]) - 1.0) * R.w;
    precise float sy = (1.0 - 2.0 * (float(px.y) + 0.5) / float(pc.size[1])) * U.w;
    // The ray (view coordinates) and the point on it the raster found.
    vec3 o = ortho ? vec3(sx, sy, 0.0) : vec3(0.0);
    vec3 d = ortho ? vec3(0.0, 0.0, 1.0) : vec3(sx, sy, 1.0);
    float z = imageLoad(g_depth, px).r;
    precise vec3 p = o + z * d;
    vec3 nview = nv.xyz;
    vec4 sph = rows[pc.objects + self];
    if (sph.w > 0.0) sphere_hit(sph, o, d, p, nview);
    precise vec3 n = nview.x * R.xyz + nview.y * U.xyz + nview.z * F.xyz;
    sf = vec4(n, p.z);
    // The disc's axes. n is rotated back from view space in float, so a wall's zero component
    // arrives as a few ulps of either sign where the CPU's is exact: obs_onb's guard takes both
    // as +0.
    vec3 t, b;
    obs_onb(n, t, b);
    for (int f = pc.f0; f < pc.f1; f++) {
      int r = OBS_PROX_H_COUNT + OBS_PROX_F_COUNT * f;
      vec4 og = rows[r + OBS_PROX_F_ORIGIN];
      if (pc.self_occlusion == 0 && int(og.w) == self) continue;
      vec4 gf = rows[r + OBS_PROX_F_FWD], gr = rows[r + OBS_PROX_F_RIGHT];
      vec4 gu = rows[r + OBS_PROX_F_UP];
      vec4 ex = rows[r + OBS_PROX_F_NX], ey = rows[r + OBS_PROX_F_NY];
      vec4 ez = rows[r + OBS_PROX_F_NZ];
      ivec3 dims = ivec3(ex.w, ey.w, ez.w);
      // The camera-relative point through the field's map, composed on the host in double.
      precise vec3 gp = og.xyz + p.x * gr.xyz + p.y * gu.xyz + p.z * gf.xyz;
      if (!inside(gp, vec3(dims))) continue;
      precise vec3 gs = n.x * ex.xyz + n.y * ey.xyz + n.z * ez.xyz;
      precise vec3 gt = t.x * ex.xyz + t.y * ey.xyz + t.z * ez.xyz;
      precise vec3 gb = b.x * ex.xyz + b.y * ey.xyz + b.z * ez.xyz;
      float occ = occlusion(ivec3(gf.w, gr.w, gu.w), dims, gp, gs, gt, gb);
      precise float keep = a.y * (1.0 - occ);
      precise float sum = a.x + occ;
      a.x = sum;
      a.y = keep;
      a.z += 1.0;
    }
  }
  if ((pc.phase & OBS_PROX_PHASE_FIRST) != 0) imageStore(surf, l, sf);
  if ((pc.phase & OBS_PROX_PHASE_LAST) != 0) {
    float total = pc.combine == 1 ? 1.0 - a.y : a.x;
    if (total > 1.0) total = 1.0;
    a.w = hit ? 1.0 - total : 1.0;
  }
  imageStore(acc, l, a);
}
