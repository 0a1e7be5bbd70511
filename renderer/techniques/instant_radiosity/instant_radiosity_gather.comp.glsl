// instant_radiosity gather pass (Szecsi, ShaderX7 6.6): each pixel sums the VPLs of its class of
// the 4x4 interleaving through the article's clamped form factor; the twin of gather_pixel in
// cpu.c. Every value that feeds a comparison or the output is `precise`, so nothing is contracted
// to FMA or reassociated and the CPU twin repeats it bit for bit.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_IRAD_GATHER
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;     // linear view depth, 0 = none
layout(binding = 1, rgba32f) uniform readonly image2D normal_img; // view-space normal, coverage
layout(binding = 2, rgba32f) uniform writeonly image2D raw_img;   // irradiance rgb, visibility
layout(binding = 3, r32f) uniform readonly image2D pyr_img;       // depth min-pyramid atlas
layout(binding = 4, r32f) uniform readonly image2D cube_img;      // distance cube, 6 faces
// The VPLs, OBS_IRAD_VPL_VEC4 vec4 each: view-space position; normal, two-sided flag; coefficient.
layout(set = 1, binding = 4, std430) readonly buffer Vpls { vec4 vpl[]; };

// The twins of smooth01, project, cube_at and approx_vis in cpu.c.
float smooth01(float e0, float e1, float x) {
  precise float t = (x - e0) / (e1 - e0);
  t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
  precise float r = t * t * (3.0 - 2.0 * t);
  return r;
}

float occlusion(float z, float dz) {
  precise float b0 = pc.bias * z;
  precise float b1 = 2.0 * pc.bias * z;
  precise float t0 = pc.thickness * z;
  precise float t1 = 2.0 * pc.thickness * z;
  precise float in_ = smooth01(b0, b1, dz);
  precise float out_ = smooth01(t0, t1, dz);
  precise float r = in_ * (1.0 - out_);
  return r;
}

vec2 project(float x, float y, float z) {
  precise float fw = float(pc.width);
  precise float fh = float(pc.height);
  precise float qx, qy;
  if ((pc.flags & OBS_IRAD_ORTHO) != 0) {
    qx = (x / pc.half_w + 1.0) * 0.5 * fw;
    qy = (1.0 - y / pc.half_h) * 0.5 * fh;
  } else {
    qx = (x / (z * pc.half_w) + 1.0) * 0.5 * fw;
    qy = (1.0 - y / (z * pc.half_h)) * 0.5 * fh;
  }
  return vec2(qx, qy);
}

int pyramid_offset(int l) {
  int off = 0;
  for (int k = 0; k < l; k++) off += (pc.width + (1 << k) - 1) >> k;
  return off;
}

float cube_at(float vx, float vy, float vz) {
  float ax = abs(vx), ay = abs(vy), az = abs(vz);
  int f;
  precise float a, b;
  if (ax >= ay && ax >= az) {
    f = vx < 0.0 ? 1 : 0;
    a = vy / ax;
    b = vz / ax;
  } else if (ay >= az) {
    f = vy < 0.0 ? 3 : 2;
    a = vx / ay;
    b = vz / ay;
  } else {
    f = vz < 0.0 ? 5 : 4;
    a = vx / az;
    b = vy / az;
  }
  precise float R = float(OBS_IRAD_CUBE);
  precise float fi = floor((a + 1.0) * 0.5 * R);
  precise float fj = floor((b + 1.0) * 0.5 * R);
  fi = fi >= 0.0 ? (fi > R - 1.0 ? R - 1.0 : fi) : 0.0;
  fj = fj >= 0.0 ? (fj > R - 1.0 ? R - 1.0 : fj) : 0.0;
  return imageLoad(cube_img, ivec2(f * OBS_IRAD_CUBE + int(fi), int(fj))).r;
}

float approx_vis(float px, float py, float pz, vec3 r) {
  bool ortho = (pc.flags & OBS_IRAD_ORTHO) != 0;
  precise float zn = ortho ? 0.0 : pz * 0.015625;
  precise float tc = r.z < zn ? (pz - zn) / (pz - r.z) : 1.0;
  precise float ex = px + tc * (r.x - px);
  precise float ey = py + tc * (r.y - py);
  precise float ez = pz + tc * (r.z - pz);
  vec2 a = project(px, py, pz);
  vec2 b = project(ex, ey, ez);
  precise float dx = b.x - a.x;
  precise float dy = b.y - a.y;
  precise float len = sqrt(dx * dx + dy * dy);
  precise float fw = float(pc.width);
  precise float fh = float(pc.height);
  precise float ue = 1.0;
  if (dx > 0.0) ue = min(ue, (fw - a.x) / dx);
  if (dx < 0.0) ue = min(ue, -a.x / dx);
  if (dy > 0.0) ue = min(ue, (fh - a.y) / dy);
  if (dy < 0.0) ue = min(ue, -a.y / dy);
  precise float vis = 1.0;
  for (int i = 0; i < OBS_IRAD_STEPS; i++) {
    precise float s = float(2 << i);
    if (!(s < len - 2.0)) break;
    precise float u = s / len;
    if (!(u < ue)) break;
    precise float zs = ortho ? pz + u * (ez - pz) : 1.0 / ((1.0 - u) / pz + u / ez);
    int l = i > 0 ? (i - 1 < OBS_IRAD_LEVELS - 1 ? i - 1 : OBS_IRAD_LEVELS - 1) : 0;
    int wl = (pc.width + (1 << l) - 1) >> l;
    int hl = (pc.height + (1 << l) - 1) >> l;
    precise float sx = a.x + u * dx;
    precise float sy = a.y + u * dy;
    int tx = int(sx) >> l;
    int ty = int(sy) >> l;
    tx = tx < 0 ? 0 : tx < wl - 1 ? tx : wl - 1;
    ty = ty < 0 ? 0 : ty < hl - 1 ? ty : hl - 1;
    float m = imageLoad(pyr_img, ivec2(pyramid_offset(l) + tx, ty)).r;
    vis *= 1.0 - occlusion(zs, zs - m);
  }
  if (ue < 1.0 || tc < 1.0) {
    precise float te = ue;
    if (!ortho && ue < 1.0) te = ue * pz / ((1.0 - ue) * ez + ue * pz);
    precise float t0 = (ue < 1.0 ? te : 1.0) * tc;
    for (int k = 1; k <= OBS_IRAD_CUBE_SAMPLES; k++) {
      precise float t = t0 + (1.0 - t0) * (float(k) / float(OBS_IRAD_CUBE_SAMPLES + 1));
      precise float vx = px + t * (r.x - px) - pc.cube_x;
      precise float vy = py + t * (r.y - py) - pc.cube_y;
      precise float vz = pz + t * (r.z - pz) - pc.cube_z;
      precise float d = sqrt(vx * vx + vy * vy + vz * vz);
      if (!(d > 0.0)) continue;
      precise float e0 = pc.bias * d;
      precise float e1 = 2.0 * pc.bias * d;
      vis *= 1.0 - smooth01(e0, e1, d - cube_at(vx, vy, vz));
    }
  }
  return vis;
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zp = imageLoad(depth_img, p).r;
  if (!(zp > 0.0) || pc.classes < 1) {
    imageStore(raw_img, p, vec4(0.0, 0.0, 0.0, 1.0));
    return;
  }
  bool ortho = (pc.flags & OBS_IRAD_ORTHO) != 0;
  precise float fx = float(p.x) + 0.5;
  precise float fy = float(p.y) + 0.5;
  precise float ndx = 2.0 * fx / float(pc.width) - 1.0;
  precise float ndy = 1.0 - 2.0 * fy / float(pc.height);
  precise float px = ortho ? ndx * pc.half_w : ndx * pc.half_w * zp;
  precise float py = ortho ? ndy * pc.half_h : ndy * pc.half_h * zp;
  vec3 n = imageLoad(normal_img, p).xyz;
  int cls = ((p.y & 3) * 4 + (p.x & 3)) % pc.classes;
  precise float er = 0.0;
  precise float eg = 0.0;
  precise float eb = 0.0;
  precise float all_l = 0.0;
  precise float kept = 0.0;
  for (int k = pc.start[cls]; k < pc.start[cls + 1]; k++) {
    vec4 r0 = vpl[OBS_IRAD_VPL_VEC4 * k];
    vec4 r1 = vpl[OBS_IRAD_VPL_VEC4 * k + 1];
    vec4 r2 = vpl[OBS_IRAD_VPL_VEC4 * k + 2];
    precise float vx = r0.x - px;
    precise float vy = r0.y - py;
    precise float vz = r0.z - zp;
    precise float d2 = vx * vx + vy * vy + vz * vz;
    precise float nv = n.x * vx + n.y * vy + n.z * vz;
    precise float mv = -(r1.x * vx + r1.y * vy + r1.z * vz);
    if (r1.w > 0.5) mv = abs(mv);
    if (!(nv > 0.0) || !(mv >= 0.0)) continue;
    precise float n2 = mv * mv;
    precise float f;
    if (n2 < pc.nc2) {
      precise float dl2 = d2 - n2 + pc.nc2;
      f = nv / sqrt(d2) * sqrt(pc.nc2 / dl2) / dl2;
    } else {
      f = (nv / d2) * (mv / d2);
    }
    precise float cr = r2.x * f;
    precise float cg = r2.y * f;
    precise float cb = r2.z * f;
    precise float lum = 0.2126 * cr + 0.7152 * cg + 0.0722 * cb;
    all_l += lum;
    if ((pc.flags & OBS_IRAD_APPROX) != 0) {
      precise float v = approx_vis(px, py, zp, r0.xyz);
      cr *= v;
      cg *= v;
      cb *= v;
      lum *= v;
    }
    er += cr;
    eg += cg;
    eb += cb;
    kept += lum;
  }
  precise float vis = all_l > 0.0 ? kept / all_l : 1.0;
  imageStore(raw_img, p, vec4(er, eg, eb, vis));
}
