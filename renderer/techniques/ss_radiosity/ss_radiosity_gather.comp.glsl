// ss_radiosity gather pass (Briney et al., ShaderX7 6.4): the twin of gather_pixel in cpu.c.
// Every value that feeds a comparison or the output is `precise`, so nothing is contracted to FMA
// or reassociated and the CPU twin repeats it bit for bit; fetches are texel-snapped imageLoads.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SRAD_GATHER
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;      // linear view depth, 0 = none
layout(binding = 1, rgba32f) uniform readonly image2D normal_img;  // view-space normal, coverage
layout(binding = 2, rgba32f) uniform readonly image2D albedo_img;  // reflectivity
layout(binding = 3, rgba32f) uniform readonly image2D direct_img;  // direct radiance, object + 1
layout(binding = 4, rgba32f) uniform readonly image2D rot_img;     // 4x4 unit reflection normals
layout(binding = 5, rgba32f) uniform readonly image2D offset_img;  // samples x 1 ball points
layout(binding = 6, rgba32f) uniform writeonly image2D raw_img;    // bounce rgb, ao
// AO probes: view-space centre, visible area (pc.nprobes of them).
layout(set = 1, binding = 4, std430) readonly buffer Probes { vec4 probe[]; };

// The twin of probe_ao in cpu.c.
float probe_ao(float px, float py, float pz, vec3 n) {
  precise float prod = 1.0;
  precise float sum = 0.0;
  bool add = (pc.flags & OBS_SRAD_PROBES_ADD) != 0;
  for (int i = 0; i < pc.nprobes; i++) {
    vec4 c = probe[i];
    precise float vx = c.x - px;
    precise float vy = c.y - py;
    precise float vz = c.z - pz;
    precise float nv = n.x * vx + n.y * vy + n.z * vz;
    if (!(nv > 0.0)) continue;
    precise float vv = vx * vx + vy * vy + vz * vz;
    precise float cs = nv / sqrt(vv);
    cs = cs > 1.0 ? 1.0 : cs;
    precise float occ = c.w * cs / vv;
    if (add) {
      sum += occ;
    } else {
      precise float f = 1.0 - occ;
      prod *= f < 0.0 ? 0.0 : f;
    }
  }
  if (add) {
    precise float f = 1.0 - sum;
    return f < 0.0 ? 0.0 : f;
  }
  return prod;
}

int texel(float v, int n) {
  precise float f = floor(v);
  f = (f >= 0.0) ? f : 0.0;
  f = f > float(n - 1) ? float(n - 1) : f;
  return int(f);
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zp = imageLoad(depth_img, p).r;
  if (!(zp > 0.0)) {
    imageStore(raw_img, p, vec4(0.0, 0.0, 0.0, 1.0));
    return;
  }
  bool ortho = (pc.flags & OBS_SRAD_ORTHO) != 0;
  float fw = float(pc.width), fh = float(pc.height);
  precise float fx = float(p.x) + 0.5;
  precise float fy = float(p.y) + 0.5;
  precise float ndx = 2.0 * fx / fw - 1.0;
  precise float ndy = 1.0 - 2.0 * fy / fh;
  precise float px = ortho ? ndx * pc.half_w : ndx * pc.half_w * zp;
  precise float py = ortho ? ndy * pc.half_h : ndy * pc.half_h * zp;
  vec3 n = imageLoad(normal_img, p).xyz;
  vec3 rot = imageLoad(rot_img, ivec2(p.x & 3, p.y & 3)).xyz;
  precise float rad = pc.kernel_size / (1.0 + pc.attenuation * zp);
  float self_id = imageLoad(direct_img, p).w;
  precise float occ = 0.0;
  precise float br = 0.0;
  precise float bg = 0.0;
  precise float bb = 0.0;
  for (int k = 0; k < pc.samples; k++) {
    vec3 v = imageLoad(offset_img, ivec2(k, 0)).xyz;
    precise float d = rot.x * v.x + rot.y * v.y + rot.z * v.z;
    precise float tt = 2.0 * d;
    precise float ux = v.x - tt * rot.x;
    precise float uy = v.y - tt * rot.y;
    precise float uz = v.z - tt * rot.z;
    precise float dn = ux * n.x + uy * n.y + uz * n.z;
    if (dn < 0.0) {
      ux = -ux;
      uy = -uy;
      uz = -uz;
    }
    precise float ox = pc.directivity * n.x + pc.spread * ux;
    precise float oy = pc.directivity * n.y + pc.spread * uy;
    precise float oz = pc.directivity * n.z + pc.spread * uz;
    precise float sx = px + rad * ox;
    precise float sy = py + rad * oy;
    precise float sz = zp + rad * oz;
    if (!(sz > 0.0)) continue;
    precise float qx, qy;
    if (ortho) {
      qx = (sx / pc.half_w + 1.0) * 0.5 * fw;
      qy = (1.0 - sy / pc.half_h) * 0.5 * fh;
    } else {
      qx = (sx / (sz * pc.half_w) + 1.0) * 0.5 * fw;
      qy = (1.0 - sy / (sz * pc.half_h)) * 0.5 * fh;
    }
    ivec2 q = ivec2(texel(qx, pc.width), texel(qy, pc.height));
    float zs = imageLoad(depth_img, q).r;
    if (!(zs > 0.0)) continue;
    precise float dz = zp - zs;
    if (!(dz > 0.0)) continue;
    precise float wb = 1.0 - dz * pc.inv_bias;
    if (!(wb > 0.0)) continue;
    vec4 dq = imageLoad(direct_img, q);
    if ((pc.flags & OBS_SRAD_EXCLUDE_SELF) != 0 && dq.w == self_id) continue;
    vec3 ns = imageLoad(normal_img, q).xyz;
    precise float dd = n.x * ns.x + n.y * ns.y + n.z * ns.z;
    precise float gf = dd > OBS_SRAD_COPLANAR ? 0.0 : (1.0 - dd) * 0.5;
    precise float c = wb * gf;
    occ += c;
    br += c * dq.r;
    bg += c * dq.g;
    bb += c * dq.b;
  }
  vec3 a = imageLoad(albedo_img, p).rgb;
  precise float rr = br * pc.scale * a.r;
  precise float rg = bg * pc.scale * a.g;
  precise float rb = bb * pc.scale * a.b;
  precise float ao = clamp(1.0 - occ * pc.inv_samples, 0.0, 1.0);
  if (pc.nprobes > 0) ao = ao * probe_ao(px, py, zp, n);
  imageStore(raw_img, p, vec4(rr, rg, rb, ao));
}
