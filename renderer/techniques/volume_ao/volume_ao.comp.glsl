// volume_ao on Vulkan, one invocation per pixel: what shade_pixel of cpu.c does,
// in float. Camera rays through the rig, the nearest isosurface hit over all volumes (clip to the
// box, half-voxel steps, macrocell skipping, bisection: volume_march.c), the
// gradient normal, AO directions from the same sample streams as the CPU's obs_sampler2d
// (renderer/core/sampling.c, ported bit for bit), marched through every volume
// (obs_volume_grid_crossing), the bent normal, direct lights, the ibl methods and the colormap.
// The host (vulkan.c) lays out the parameter buffer (its rows, the bindings and the push block are
// layout.h's) and hands world space over relative to a reference point Q on the view axis, so no
// coordinate the shader sees is large.
//
// One dispatch shades pixel sample `sample` with AO directions [dir0, dir1): the host splits the
// directions so that no invocation runs more loop iterations than the device allows (lavapipe:
// 65535, obs_vk_loop_limit). The sample's open count, sums and replicates carry over in st0..st2
// and the pixel's sums in acc0..acc2 and st2.w, added in the CPU's order, so the split does not
// change a bit. The AO's standard error comes from the directions' replicates as on the CPU
// (sampling.h obs_rqmc, mcerr.h), in float where the CPU sums in double. Every loop
// with a data-dependent trip count bumps `iters`; past the limit the invocation flags st1.w and the
// host refuses the result. Loops over the three axes are written out: constant loops are unrolled
// and cost nothing, but a loop with an early exit might not be.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "include/frame.glsl"
#include "layout.h"

layout(local_size_x = 8, local_size_y = 8) in;

// Per pixel: sums over the samples, turned into the outputs by the last dispatch
// (OBS_VAO_PH_FINAL).
layout(set = 0, binding = OBS_VAO_B_ACC0, rgba32f) uniform image2D acc0; // R, G, B, ao
layout(set = 0, binding = OBS_VAO_B_ACC1, rgba32f) uniform image2D acc1; // bent normal, depth
layout(set = 0, binding = OBS_VAO_B_ACC2, rgba32f) uniform image2D acc2; // normal, hits (alpha)
// Per pixel, for the sample in progress: open directions, their environment sum; their sum, and
// in w the loop-limit flag (kept over the whole render).
layout(set = 0, binding = OBS_VAO_B_ST0, rgba32f) uniform image2D st0;
layout(set = 0, binding = OBS_VAO_B_ST1, rgba32f) uniform image2D st1;
// Per pixel: the sample in progress's open directions in its current replicate, the Welford mean
// and sum of squares of its replicates' means; in w the pixel's AO variance over its samples (at
// the end its standard error).
layout(set = 0, binding = OBS_VAO_B_ST2, rgba32f) uniform image2D st2;
layout(set = 1, binding = 0) uniform sampler3D vol_atlas;  // samples, linear (or nearest: flags)
layout(set = 1, binding = 1) uniform sampler3D cell_atlas; // macrocell maxima, read by texel
layout(set = 1, binding = 2) uniform sampler2DArray env_faces; // the cube map's faces as layers
layout(set = 1, binding = 4, std430) readonly buffer Params { vec4 P[]; };

const float PI = 3.14159265358979323846;
const float INF = 1.0 / 0.0; // +infinity (IEEE: the compiler folds it)

uint iters = 0u; // iterations of data-dependent loops so far (see the top)

vec4 V(int k, int row) { return P[OBS_VAO_H_COUNT + k * OBS_VAO_V_COUNT + row]; }
int light_base() { return OBS_VAO_H_COUNT + pc.nvol * OBS_VAO_V_COUNT; }
int cmap_base() { return light_base() + OBS_VAO_L_COUNT * pc.nlights; }

// Rows [row, row + 3) of volume k as an affine map: a point, and the linear part alone.
vec3 map_point(int k, int row, vec3 p) {
  vec4 a = V(k, row), b = V(k, row + 1), c = V(k, row + 2);
  return vec3(dot(a.xyz, p) + a.w, dot(b.xyz, p) + b.w, dot(c.xyz, p) + c.w);
}
vec3 map_dir(int k, int row, vec3 d) {
  return vec3(dot(V(k, row).xyz, d), dot(V(k, row + 1).xyz, d), dot(V(k, row + 2).xyz, d));
}

// The CPU's normalize3: unchanged when the length is 0 or not finite.
vec3 normalize3(vec3 v) {
  float l = length(v);
  return l > 0.0 && !isinf(l) ? v / l : v;
}

// ---- sample streams (renderer/core/sampling.c) ----

uint hash32(uint x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}
uint hash_combine(uint a, uint b) { return hash32(a ^ (b + 0x9e3779b9u + (a << 6) + (a >> 2))); }
float u32_to_unit(uint x) { return float(x >> 8) * (1.0 / 16777216.0); }
uint laine_karras(uint x, uint s) {
  x += s;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}
uint sobol1_reversed(uint i) {
  uint r = 0u, w = 1u;
  for (; i != 0u; i >>= 1, w ^= w << 1) {
    iters++;
    r ^= w & (0u - (i & 1u));
  }
  return r;
}
// i's base-3 digits mirrored: the reversed digits as an integer over 3^digits, one rounding
// (the CPU sums in double, then rounds once to float: the same float but in freak ties).
float radical_inverse3(uint i) {
  uint rev = 0u, pw = 1u;
  for (int n = 0; i != 0u && n < 20; n++) {
    iters++;
    rev = rev * 3u + i % 3u;
    i /= 3u;
    pw *= 3u;
  }
  return float(rev) / float(pw);
}
uvec2 sampler_init(uint x, uint y, uint pixel_sample, uint stream) {
  uint h = hash_combine(hash_combine(hash32(x), y), pixel_sample);
  h = hash_combine(hash_combine(h, stream), pc.seed);
  return uvec2(h, hash32(h ^ 0xa511e9b3u));
}
vec2 sampler_get(uvec2 s, uint i) {
  if (pc.sampler_kind == OBS_VAO_SAMPLER_SOBOL)
    return vec2(u32_to_unit(bitfieldReverse(laine_karras(i, s.x))),
                u32_to_unit(bitfieldReverse(laine_karras(sobol1_reversed(i), s.y))));
  if (pc.sampler_kind == OBS_VAO_SAMPLER_HALTON) {
    float a = float(bitfieldReverse(i)) * (1.0 / 4294967296.0) + u32_to_unit(s.x);
    float b = radical_inverse3(i) + u32_to_unit(s.y);
    a -= a >= 1.0 ? 1.0 : 0.0;
    b -= b >= 1.0 ? 1.0 : 0.0;
    return vec2(a < 1.0 ? a : 0.99999994, b < 1.0 ? b : 0.99999994);
  }
  return vec2(u32_to_unit(hash_combine(s.x, i)), u32_to_unit(hash_combine(s.y, i)));
}
// obs_rqmc: the n directions form R replicates of consecutive directions, each its own scramble.
uint rqmc_reps() {
  uint n = max(pc.samples, 1u);
  return pc.sampler_kind == OBS_VAO_SAMPLER_RANDOM || n < 4u ? n : 4u; // OBS_RQMC_REPLICATES
}
uint rqmc_first(uint r) {
  uint R = rqmc_reps(), base = pc.samples / R, extra = pc.samples % R;
  return r * base + min(r, extra);
}
// The replicate of direction i (returned) and i's index j in it.
uint rqmc_locate(uint i, out uint j) {
  if (pc.sampler_kind == OBS_VAO_SAMPLER_RANDOM) {
    j = i;
    return 0u;
  }
  uint R = rqmc_reps(), base = pc.samples / R, extra = pc.samples % R, big = extra * (base + 1u);
  if (i < big) {
    j = i % (base + 1u);
    return i / (base + 1u);
  }
  j = (i - big) % base;
  return extra + (i - big) / base;
}
uvec2 rqmc_stream(uvec2 s0, uint r) {
  if (r == 0u) return s0;
  uint a = hash_combine(s0.x, 0x51ed270bu + r);
  return uvec2(a, hash32(a ^ 0xa511e9b3u));
}

vec3 sample_cosine(vec2 uv) {
  float r = sqrt(uv.x), phi = 6.28318530717958647692 * uv.y;
  return vec3(r * cos(phi), r * sin(phi), sqrt(uv.x < 1.0 ? 1.0 - uv.x : 0.0));
}
// ---- the field (obs_volume_sample) ----

// Texel t of the volume at its corner `at` of the atlas, held at the edges (CPU: clamped to the
// voxel centres), interpolated in the shader: the device cannot filter floats.
float field_manual(int k, vec3 p) {
  vec3 n = V(k, OBS_VAO_V_DIMS).xyz;
  vec3 u = clamp(p / V(k, OBS_VAO_V_SPACING).xyz - 0.5, vec3(0.0), n - 1.0);
  ivec3 ni = ivec3(n), i = min(ivec3(u), max(ni - 2, ivec3(0)));
  ivec3 i1 = i + ivec3(greaterThan(ni, ivec3(1))), at = ivec3(V(k, OBS_VAO_V_AT).xyz);
  vec3 w = mix(vec3(0.0), u - vec3(i), greaterThan(ni, ivec3(1)));
#define F(a, b, c) texelFetch(vol_atlas, at + ivec3(a, b, c), 0).r
  float c00 = F(i.x, i.y, i.z) + w.x * (F(i1.x, i.y, i.z) - F(i.x, i.y, i.z));
  float c10 = F(i.x, i1.y, i.z) + w.x * (F(i1.x, i1.y, i.z) - F(i.x, i1.y, i.z));
  float c01 = F(i.x, i.y, i1.z) + w.x * (F(i1.x, i.y, i1.z) - F(i.x, i.y, i1.z));
  float c11 = F(i.x, i1.y, i1.z) + w.x * (F(i1.x, i1.y, i1.z) - F(i.x, i1.y, i1.z));
#undef F
  float c0 = c00 + w.y * (c10 - c00), c1 = c01 + w.y * (c11 - c01);
  return c0 + w.z * (c1 - c0);
}

// The trilinear field at data-space point p of volume k. Sample i sits at (i + 0.5) spacing,
// which is texel centre i + 0.5 of the volume's part of the atlas: the hardware's trilinear
// filter between texel centres is the CPU's between voxel centres, and clamping to the outer
// centres holds the field at the box's faces (and keeps the filter off the neighbours' texels).
float field(int k, vec3 p) {
  if ((pc.flags & OBS_VAO_FLAG_VOL_MANUAL) != 0) return field_manual(k, p);
  vec3 c = clamp(p / V(k, OBS_VAO_V_SPACING).xyz, vec3(0.5), V(k, OBS_VAO_V_DIMS).xyz - 0.5);
  return textureLod(vol_atlas, (c + V(k, OBS_VAO_V_AT).xyz) * P[OBS_VAO_H_ATLAS].xyz, 0.0).r;
}

// ---- marching (volume_march.c) ----

// Component-wise and / or of boolean vectors (GLSL has none).
bvec3 both(bvec3 a, bvec3 b) { return bvec3(uvec3(a) & uvec3(b)); }
bvec3 either(bvec3 a, bvec3 b) { return bvec3(uvec3(a) | uvec3(b)); }

// The ray's parameter range inside the box [0, extent] (slabs), as the CPU's clip_box: an axis
// the ray runs parallel to must hold o inside, the others narrow [t0, t1].
bool clip_box(int k, vec3 o, vec3 d, inout float t0, inout float t1) {
  vec3 hi = V(k, OBS_VAO_V_EXTENT).xyz;
  bvec3 flat_ = equal(d, vec3(0.0));
  if (any(both(flat_, either(lessThan(o, vec3(0.0)), greaterThan(o, hi))))) return false;
  vec3 ta = (0.0 - o) / d, tb = (hi - o) / d;
  vec3 lo = min(ta, tb), up = max(ta, tb);
  // Parallel axes (0 / 0 or x / 0) narrow nothing.
  lo = mix(lo, vec3(-INF), flat_);
  up = mix(up, vec3(INF), flat_);
  t0 = max(t0, max(lo.x, max(lo.y, lo.z)));
  t1 = min(t1, min(up.x, min(up.y, up.z)));
  return t0 <= t1;
}

// The macrocell holding q: whether its maximum is below iso, and its box (infinite on the sides
// where it is the volume's outer cell, whose field is held beyond the faces).
bool cell_below(int k, vec3 q, out vec3 lo, out vec3 hi) {
  vec3 sp = V(k, OBS_VAO_V_SPACING).xyz, n = V(k, OBS_VAO_V_DIMS).xyz;
  vec3 cn = V(k, OBS_VAO_V_CELLS).xyz;
  float cell = V(k, OBS_VAO_V_CELLS).w;
  vec3 u = min(max(q / sp - 0.5, vec3(0.0)), max(n - 1.0, vec3(0.0)));
  ivec3 ci = min(ivec3(u / cell), ivec3(cn) - 1), last = ivec3(cn) - 1;
  lo = mix((vec3(ci) * cell + 0.5) * sp, vec3(-INF), equal(ci, ivec3(0)));
  hi = mix((vec3(ci + 1) * cell + 0.5) * sp, vec3(INF), equal(ci, last));
  return texelFetch(cell_atlas, ivec3(V(k, OBS_VAO_V_CELL_AT).xyz) + ci, 0).r <
         V(k, OBS_VAO_V_EXTENT).w;
}

// Where the ray leaves the cell [lo, hi] (infinite sides never).
float cell_exit(vec3 o, vec3 d, vec3 lo, vec3 hi) {
  vec3 up = mix(vec3(INF), (hi - o) / d, both(greaterThan(d, vec3(0.0)), notEqual(hi, vec3(INF))));
  vec3 dn = mix(vec3(INF), (lo - o) / d, both(lessThan(d, vec3(0.0)), notEqual(lo, vec3(-INF))));
  vec3 e = min(up, dn);
  return min(e.x, min(e.y, e.z));
}

// obs_volume_first_hit: the first t in [t0, t1] where the field along o + t d reaches iso.
bool first_hit(int k, vec3 o, vec3 d, float t0, float t1, out float t) {
  t = 0.0;
  if (!clip_box(k, o, d, t0, t1) || isinf(t0) || isinf(t1)) return false;
  float len = length(d), smin = V(k, OBS_VAO_V_SPACING).w, iso = V(k, OBS_VAO_V_EXTENT).w;
  if (!(len > 0.0)) return false;
  float dt = 0.5 * smin / len, tol = 1e-3 * smin / len;
  float ta = t0;
  if (field(k, o + ta * d) >= iso) {
    t = ta;
    return true;
  }
  while (ta < t1) {
    iters++;
    vec3 lo, hi;
    if (cell_below(k, o + ta * d, lo, hi)) {
      float e = cell_exit(o, d, lo, hi);
      if (e > ta) { // nothing reaches iso before the cell's exit
        if (e >= t1) return false;
        ta = max(e, ta + 1e-6 * dt);
        if (field(k, o + ta * d) >= iso) {
          t = ta;
          return true;
        }
        continue;
      }
    }
    float tb = min(ta + dt, t1);
    if (!(tb > ta)) return false;
    if (field(k, o + tb * d) >= iso) {
      while (tb - ta > tol) {
        iters++;
        float tm = 0.5 * (ta + tb);
        if (!(tm > ta && tm < tb)) break;
        if (field(k, o + tm * d) >= iso)
          tb = tm;
        else
          ta = tm;
      }
      t = tb;
      return true;
    }
    ta = tb;
  }
  return false;
}

// obs_volume_normal: central differences half a voxel apart, down the gradient.
float central_difference(int k, vec3 p, vec3 h) { return (field(k, p + h) - field(k, p - h)); }

vec3 gradient_normal(int k, vec3 p) {
  vec3 h = 0.5 * V(k, OBS_VAO_V_SPACING).xyz;
  vec3 g = vec3(central_difference(k, p, vec3(h.x, 0.0, 0.0)),
                central_difference(k, p, vec3(0.0, h.y, 0.0)),
                central_difference(k, p, vec3(0.0, 0.0, h.z))) / (2.0 * h);
  float l = length(g);
  return l > 0.0 && !isinf(l) ? -g / l : vec3(0.0, 0.0, 1.0);
}

bool crosses(float prev, float cur, float iso) {
  return pc.crossing == 0 ? prev < iso && cur > iso : (prev < iso) != (cur < iso);
}

// obs_volume_grid_crossing: samples at start + i step, i = 0 .. last, read 0 outside the box.
bool grid_crossing(int k, vec3 o, vec3 d) {
  if (pc.last < 0) return false;
  float start = P[OBS_VAO_H_MARCH].x, step = P[OBS_VAO_H_MARCH].y;
  float t0 = start, t1 = P[OBS_VAO_H_MARCH].z;
  if (!clip_box(k, o, d, t0, t1)) return false;
  float iso = V(k, OBS_VAO_V_EXTENT).w, last = float(pc.last);
  // In float first: a tiny step makes these quotients far larger than any int.
  int ia = int(min(max(ceil((t0 - start) / step), 0.0), last + 1.0));
  int ib = int(min(floor((t1 - start) / step), last));
  float prev = 0.0;
  if (ia == 0) {
    prev = field(k, o + start * d);
    ia = 1;
  }
  for (int i = ia; i <= ib; i++) {
    iters++;
    float t = start + float(i) * step;
    vec3 q = o + t * d, lo, hi;
    if (prev < iso && cell_below(k, q, lo, hi)) {
      // Every sample in this cell is below iso like prev: jump past its last grid sample.
      float e = cell_exit(o, d, lo, hi);
      float j = floor((e - start) / step);
      if (start + j * step > e) j -= 1.0;
      if (j > float(i)) {
        i = j >= float(ib) ? ib : int(j);
        prev = -1.0;
        continue;
      }
    }
    float cur = field(k, q);
    if (crosses(prev, cur, iso)) return true;
    prev = cur;
    // A step below float's spacing at t puts the next samples on this same t: equal values
    // never cross, so skip to the last of them (checked: the grid's t is monotone in i).
    float tn = uintBitsToFloat(floatBitsToUint(t) + 1u);
    if (t > 0.0 && step < tn - t) {
      float j = min(floor((0.5 * (t + tn) - start) / step) - 2.0, float(ib));
      if (j > float(i) && start + j * step == t) i = int(j);
    }
  }
  return ib < pc.last && crosses(prev, 0.0, iso);
}

// ---- lighting ----

// obs_env_lookup: the face the direction selects (ties: x, then y, then z) and a bilinear lookup
// between its texel centres, clamped at the face's edges (seams are not filtered across).
vec3 env_radiance(vec3 w) {
  if (pc.env_res == 0) return vec3(1.0);
  vec3 a = abs(w);
  if (any(isinf(a)) || any(isnan(a)) || (a.x == 0.0 && a.y == 0.0 && a.z == 0.0))
    return P[OBS_VAO_H_ENV_MEAN].xyz;
  int f;
  float sc, tc, ma;
  if (a.x >= a.y && a.x >= a.z) {
    f = w.x >= 0.0 ? 0 : 1;
    ma = a.x, sc = f == 0 ? -w.z : w.z, tc = -w.y;
  } else if (a.y >= a.z) {
    f = w.y >= 0.0 ? 2 : 3;
    ma = a.y, sc = w.x, tc = f == 2 ? w.z : -w.z;
  } else {
    f = w.z >= 0.0 ? 4 : 5;
    ma = a.z, sc = f == 4 ? w.x : -w.x, tc = -w.y;
  }
  vec2 st = clamp(0.5 * (vec2(sc, tc) / ma + 1.0), 0.0, 1.0);
  if ((pc.flags & OBS_VAO_FLAG_ENV_MANUAL) == 0)
    return textureLod(env_faces, vec3(st, float(f)), 0.0).rgb;
  float r = float(pc.env_res);
  vec2 fx = clamp(st * r - 0.5, 0.0, r - 1.0);
  ivec2 i0 = ivec2(fx), i1 = min(i0 + 1, ivec2(pc.env_res - 1));
  vec2 wt = fx - vec2(i0);
  vec3 p00 = texelFetch(env_faces, ivec3(i0.x, i0.y, f), 0).rgb;
  vec3 p10 = texelFetch(env_faces, ivec3(i1.x, i0.y, f), 0).rgb;
  vec3 p01 = texelFetch(env_faces, ivec3(i0.x, i1.y, f), 0).rgb;
  vec3 p11 = texelFetch(env_faces, ivec3(i1.x, i1.y, f), 0).rgb;
  vec3 top = p00 + wt.x * (p10 - p00), bot = p01 + wt.x * (p11 - p01);
  return top + wt.y * (bot - top);
}

// obs_env_sh_irradiance: the diffuse environment at n from its SH9 coefficients, over pi.
vec3 sh_irradiance(vec3 n) {
  const float band[9] = float[9](1.0, 2.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0, 0.25, 0.25, 0.25, 0.25,
                                 0.25);
  float m = max(abs(n.x), max(abs(n.y), abs(n.z)));
  bool ok = m > 0.0 && !isinf(m) && !isnan(n.x + n.y + n.z);
  vec3 d = ok ? normalize(n / m) : vec3(0.0);
  float y[9] = float[9](0.28209479177387814, 0.4886025119029199 * d.y, 0.4886025119029199 * d.z,
                        0.4886025119029199 * d.x, 1.0925484305920792 * d.x * d.y,
                        1.0925484305920792 * d.y * d.z,
                        0.31539156525252005 * (3.0 * d.z * d.z - 1.0),
                        1.0925484305920792 * d.x * d.z,
                        0.5462742152960396 * (d.x * d.x - d.y * d.y));
  vec3 sum = vec3(0.0);
  for (int k = 0; k < 9; k++)
    sum += band[k] * P[OBS_VAO_H_SH + k].xyz * (ok || k == 0 ? y[k] : 0.0);
  return max(sum, vec3(0.0));
}

// Point and directional lights at x (Q-relative world) with normal n, seen along v: diffuse
// irradiance over pi, and the Blinn-Phong highlight.
void direct_light(vec3 x, vec3 n, vec3 v, out vec3 diffuse, out vec3 spec) {
  diffuse = vec3(0.0);
  spec = vec3(0.0);
  for (int i = 0; i < pc.nlights; i++) {
    iters++;
    vec4 a = P[light_base() + OBS_VAO_L_COUNT * i + OBS_VAO_L_POS];
    vec3 em = P[light_base() + OBS_VAO_L_COUNT * i + OBS_VAO_L_EMISSION].xyz, l;
    float e = 1.0;
    if (a.w == 0.0) {
      l = a.xyz - x;
      float d2 = dot(l, l);
      if (!(d2 > 0.0) || isinf(d2)) continue;
      e = 1.0 / d2;
      l = normalize3(l);
    } else {
      l = -a.xyz;
    }
    float ndl = dot(n, l);
    if (!(ndl > 0.0)) continue;
    float hl = 0.0;
    if (pc.blinn != 0) {
      float s = P[OBS_VAO_H_MARCH].w, ndh = max(0.0, dot(n, normalize3(l + v)));
      hl = P[OBS_VAO_H_ATLAS].w * (s + 8.0) / (8.0 * PI) * pow(ndh, s);
    }
    diffuse += em * e * ndl / PI;
    spec += hl * em * e * ndl;
  }
}

// obs_scene_volume_color: the colormap's piecewise-linear ramp, held at its ends.
vec3 colormap(int k, float value) {
  int n = int(V(k, OBS_VAO_V_DIMS).w), c = cmap_base() + int(V(k, OBS_VAO_V_AT).w);
  if (n == 0) return vec3(1.0);
  int i = 0;
  while (i < n && P[c + i].x < value) {
    iters++;
    i++;
  }
  if (i == 0 || i == n) return P[c + (i == 0 ? 0 : n - 1)].yzw;
  vec4 a = P[c + i - 1], b = P[c + i];
  return a.yzw + (value - a.x) / (b.x - a.x) * (b.yzw - a.yzw);
}

// ---- one pixel sample ----

// What the sample's directions found so far: open directions, their sum and environment sum.
struct Dirs {
  float open;
  vec3 sum, env;
  float part, wmean, wm2; // the current replicate's open directions; Welford over replicates
};

// march_ao's loop over directions [dir0, dir1) about world normal n from data point p of volume
// a; other volumes are marched at the same parameter through the (Q-relative) world.
void march_chunk(int a, vec3 p, vec3 n, uvec2 px, inout Dirs r) {
  vec3 xw = map_point(a, OBS_VAO_V_TO_WORLD, p), t1, t2;
  obs_onb(n, t1, t2);
  uvec2 smp = sampler_init(px.x, px.y, uint(pc.pixel_sample), 1u);
  for (uint i = pc.dir0; i < pc.dir1; i++) {
    iters++;
    uint j, rep = rqmc_locate(i, j);
    vec3 l = sample_cosine(sampler_get(rqmc_stream(smp, rep), j));
    vec3 w = l.x * t1 + l.y * t2 + l.z * n;
    vec3 da = normalize3(map_dir(a, OBS_VAO_V_TO_DATA, w));
    bool blocked = false;
    for (int b = 0; b < pc.nvol && !blocked; b++) {
      iters++;
      if (b == a)
        blocked = grid_crossing(b, p, da);
      else
        blocked = grid_crossing(b, map_point(b, OBS_VAO_V_TO_DATA, xw),
                                map_dir(b, OBS_VAO_V_TO_DATA, map_dir(a, OBS_VAO_V_TO_WORLD, da)));
    }
    if (!blocked) r.part += 1.0;
    bool rnd = pc.sampler_kind == OBS_VAO_SAMPLER_RANDOM;
    if (rnd || i + 1u == rqmc_first(rep + 1u)) { // the replicate's last
      uint first = rnd ? i : rqmc_first(rep);
      float y = r.part / float(i + 1u - first);
      float cnt = float(rnd ? i + 1u : rep + 1u), d = y - r.wmean;
      r.wmean += d / cnt;
      r.wm2 += d * (y - r.wmean);
      r.part = 0.0;
    }
    if (blocked) continue;
    r.open += 1.0;
    r.sum += w;
    if (pc.ibl == OBS_VAO_IBL_REFERENCE) r.env += env_radiance(w);
  }
}

// shade_hit once the sample's directions are all marched: its colour and what it adds to the
// pixel's sums (a0: R, G, B, ao; a1: bent normal, depth; a2: normal, hits).
void shade_hit(int k, vec3 p, vec3 nd, vec3 n, vec3 x, vec3 dir, float depth, Dirs r,
               inout vec4 a0, inout vec4 a1, inout vec4 a2, inout float var) {
  float ao = r.wmean, R = float(rqmc_reps());
  // mcerr.h: the replicates' spread, or when they all agree the floor 1.5 / (n + 2), at most 0.5,
  // marked as agreed: var holds minus the sum while no sample had a spread (obs_mcerr_pixel).
  if (r.wm2 > 0.0 && R > 1.0) {
    var = abs(var) + r.wm2 / (R * (R - 1.0));
  } else {
    float floor_ = min(0.5, 1.5 / (float(pc.samples) + 2.0));
    var = var > 0.0 ? var + floor_ * floor_ : var - floor_ * floor_;
  }
  vec3 bent = r.open > 0.0 ? normalize3(r.sum) : n, env = r.env / float(pc.samples);
  vec3 diffuse, spec, ibl = vec3(0.0);
  direct_light(x, n, -dir, diffuse, spec);
  if (pc.ibl == OBS_VAO_IBL_LOOKUP)
    ibl = ao * env_radiance(bent);
  else if (pc.ibl == OBS_VAO_IBL_IRRADIANCE)
    ibl = ao * ((pc.flags & OBS_VAO_FLAG_ENV) != 0 ? sh_irradiance(bent) : vec3(1.0));
  else if (pc.ibl == OBS_VAO_IBL_REFERENCE)
    ibl = env;
  // The colour just inside the surface: the field one voxel in against the gradient.
  vec3 alb = vec3(1.0);
  if (V(k, OBS_VAO_V_DIMS).w > 0.0) alb = colormap(k, field(k, p - V(k, OBS_VAO_V_SPACING).w * nd));
  a0 += vec4(alb * (diffuse + ibl) + spec, ao);
  a1 += vec4(bent, depth);
  a2 += vec4(n, 1.0);
}

void main() {
  ivec2 g = ivec2(gl_GlobalInvocationID.xy);
  if (g.x >= pc.band[2] || g.y >= pc.band[3]) return;
  ivec2 pix = ivec2(pc.band[0], pc.band[1]) + g;
  ivec2 at = pix - ivec2(pc.origin[0], pc.origin[1]);
  if (pc.pilot != 0) {
    pix = min((ivec2(pc.cell0[0], pc.cell0[1]) + g) * pc.pilot + pc.pilot / 2,
              ivec2(pc.size[0], pc.size[1]) - 1);
    at = g;
  }
  uvec2 px = uvec2(pix);
  bool first = (pc.phase & OBS_VAO_PH_FIRST_CHUNK) != 0;
  bool last = (pc.phase & OBS_VAO_PH_LAST_CHUNK) != 0;
  bool fresh = first && (pc.phase & OBS_VAO_PH_FIRST_SAMPLE) != 0;
  vec4 a0 = fresh ? vec4(0.0) : imageLoad(acc0, at), a1 = fresh ? vec4(0.0) : imageLoad(acc1, at);
  vec4 a2 = fresh ? vec4(0.0) : imageLoad(acc2, at), s1 = fresh ? vec4(0.0) : imageLoad(st1, at);
  vec4 s0 = first ? vec4(0.0) : imageLoad(st0, at);
  vec4 s2 = fresh ? vec4(0.0) : imageLoad(st2, at);
  if (first) s1.xyz = vec3(0.0), s2.xyz = vec3(0.0);
  Dirs r = Dirs(s0.x, s1.xyz, s0.yzw, s2.x, s2.y, s2.z);
  float var = s2.w;

  // The camera ray of this pixel sample meets Q's depth plane at `org` (Q-relative), ray
  // parameter tp from the eye (or, orthographic, from the image plane).
  vec3 F = P[OBS_VAO_H_FWD].xyz, R = P[OBS_VAO_H_RIGHT].xyz, U = P[OBS_VAO_H_UP].xyz;
  float tq = P[OBS_VAO_H_FWD].w;
  vec2 j = vec2(0.5);
  if (pc.spp > 1) j = sampler_get(sampler_init(px.x, px.y, 0u, 0u), uint(pc.pixel_sample));
  float sx = (2.0 * (float(pix.x) + j.x) / float(pc.size[0]) - 1.0) * P[OBS_VAO_H_RIGHT].w;
  float sy = (1.0 - 2.0 * (float(pix.y) + j.y) / float(pc.size[1])) * P[OBS_VAO_H_UP].w;
  vec3 w = pc.ortho != 0 ? F : F + sx * R + sy * U, org = sx * R + sy * U;
  float len = length(w), tp = tq;
  vec3 dir = w / len;
  if (pc.ortho == 0) {
    org *= tq;
    tp = tq * len;
  }
  float best = INF;
  int hit = -1;
  vec3 hp = vec3(0.0);
  for (int k = 0; k < pc.nvol; k++) {
    iters++;
    vec3 o = map_point(k, OBS_VAO_V_TO_DATA, org), d = map_dir(k, OBS_VAO_V_TO_DATA, dir);
    float t;
    if (first_hit(k, o, d, -tp, best, t) && t < best) {
      best = t;
      hit = k;
      hp = o + t * d;
    }
  }
  if (hit < 0) {
    if (last) a0.w += 1.0;
  } else {
    vec3 nd = gradient_normal(hit, hp);
    vec3 n = normalize3(vec3(dot(V(hit, OBS_VAO_V_NORMAL).xyz, nd),
                             dot(V(hit, OBS_VAO_V_NORMAL + 1).xyz, nd),
                             dot(V(hit, OBS_VAO_V_NORMAL + 2).xyz, nd)));
    if (dot(n, dir) > 0.0) n = -n;
    march_chunk(hit, hp, n, px, r);
    float t = best + tp;
    if (last)
      shade_hit(hit, hp, nd, n, org + best * dir, dir, pc.ortho != 0 ? t : t / len, r, a0, a1, a2,
                var);
  }
  if (pc.iter_limit != 0u && iters > pc.iter_limit) s1.w = 1.0;
  if ((pc.phase & OBS_VAO_PH_FINAL) != 0) {
    float inv = 1.0 / float(pc.spp), hits = a2.w;
    a0 *= inv;
    a1 = hits > 0.0 ? vec4(normalize3(a1.xyz), a1.w / hits) : vec4(0.0);
    a2 = vec4(hits > 0.0 ? normalize3(a2.xyz) : vec3(0.0), hits * inv);
    var = sign(var) * sqrt(abs(var)) * inv; // now the standard error, negated where agreed
  }
  imageStore(acc0, at, a0);
  imageStore(acc1, at, a1);
  imageStore(acc2, at, a2);
  imageStore(st0, at, vec4(r.open, r.env));
  imageStore(st1, at, vec4(r.sum, s1.w));
  imageStore(st2, at, vec4(r.part, r.wmean, r.wm2, var));
}
