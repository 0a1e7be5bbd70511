// sss_single's shadow_maps on Vulkan, one invocation per pixel: Listing 6.5.1 as cpu_maps.c's
// walk() runs it, in float. The host (vulkan.c, sss_maps.c) casts the camera rays, the device has
// rasterised the light-view maps (sss_maps.comp.glsl); this pass reads one pixel sample's hit,
// walks M deterministic path lengths down the refracted view ray for every light, looks each up
// in the light's maps (jittered with the CPU's hash), refines to 2M where 20-85 % of the samples
// are dim, and writes the radiance.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "layout.h"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = OBS_SSS_B_POS, rgba32f) uniform readonly image2D gpos;
layout(set = 0, binding = OBS_SSS_B_NRM, rgba32f) uniform readonly image2D gnrm;
layout(set = 0, binding = OBS_SSS_B_DIR, rgba32f) uniform readonly image2D gdir;
layout(set = 0, binding = OBS_SSS_B_OUT, rgba32f) uniform writeonly image2D outimg;
layout(set = 1, binding = 0) uniform sampler2DArray maps;
layout(set = 1, binding = 4, std430) readonly buffer Table { vec4 rows[]; };

const float PI = 3.14159265358979323846;

float hg(float mu, float g) {
  float d = 1.0 + g * g - 2.0 * g * mu;
  return (1.0 - g * g) / (4.0 * PI * d * sqrt(d));
}

#include "sss_fresnel.inc.glsl"

vec3 refract_in(vec3 d, vec3 n, float eta) {
  float ci = max(-dot(d, n), 0.0);
  float r = 1.0 / eta, k = 1.0 - r * r * (1.0 - ci * ci);
  float ct = sqrt(max(k, 0.0));
  return normalize(r * d + (r * ci - ct) * n);
}

float refracted_length(float si, float ci, float eta) {
  float c = abs(ci), r = 1.0 / eta;
  return si * c / sqrt(1.0 - r * r * (1.0 - c * c));
}

uint pcg(uint v) {
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

float jitter_u(uint x, uint y, uint s, uint l, uint k) {
  uint h = pcg(pc.seed ^ pcg(x));
  h = pcg(h ^ y);
  h = pcg(h ^ (s * 64u + l));
  h = pcg(h ^ k);
  return float(h >> 8) * (1.0 / 16777216.0);
}

float lum(vec3 c) { return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b; }

// The texel of light l's map under x, jittered; -1 outside.
ivec2 texel(int lr, vec3 x, float ju, float jv) {
  vec4 p0 = rows[lr], p1 = rows[lr + 1];
  vec3 centre = rows[lr + 3].xyz, right = rows[lr + 4].xyz, up = rows[lr + 5].xyz;
  vec3 fwd = rows[lr + 6].xyz;
  float half_ = p1.w, u, v;
  if (p0.w > 0.5) {
    vec3 q = x - p0.xyz;
    float z = dot(q, fwd);
    if (!(z > 0.0)) return ivec2(-1);
    u = dot(q, right) / (z * half_), v = dot(q, up) / (z * half_);
  } else {
    vec3 q = x - centre;
    u = dot(q, right) / half_, v = dot(q, up) / half_;
  }
  float fx = (u + 1.0) * 0.5 * float(pc.map_size) + ju;
  float fy = (v + 1.0) * 0.5 * float(pc.map_size) + jv;
  if (!(fx >= 0.0 && fy >= 0.0 && fx < float(pc.map_size) && fy < float(pc.map_size)))
    return ivec2(-1);
  return ivec2(int(fx), int(fy));
}

// Light l's m path samples into acc; returns how many were dim.
int walk(int l, int obj, vec3 p, vec3 t, int m, uvec2 px, inout vec3 acc) {
  int orow = obj * OBS_SSS_OBJ_ROWS;
  vec3 sigma_t = rows[orow + 1].xyz;
  float sigma_min = rows[orow + 1].w, g = rows[orow + 2].x, eta = rows[orow + 2].y;
  int lr = pc.nobjects * OBS_SSS_OBJ_ROWS + l * OBS_SSS_LIGHT_ROWS;
  vec4 p0 = rows[lr];
  vec3 ldir = rows[lr + 1].xyz, power = rows[lr + 2].xyz;
  int dim = 0;
  for (int k = 0; k < m; k++) {
    float xi = (float(k) + 0.5) / float(m), so = -log(xi) / sigma_min;
    vec3 xs = p + t * so;
    float ju = 0.0, jv = 0.0;
    if (pc.jitter > 0.0) {
      ju = (2.0 * jitter_u(px.x, px.y, uint(pc.pixel_sample), uint(l), uint(2 * k)) - 1.0) * pc.jitter;
      jv = (2.0 * jitter_u(px.x, px.y, uint(pc.pixel_sample), uint(l), uint(2 * k + 1)) - 1.0) *
           pc.jitter;
    }
    ivec2 tx = texel(lr, xs, ju, jv);
    int base = l * OBS_SSS_LAYERS;
    vec4 xi_id = tx.x < 0 ? vec4(-1.0) : texelFetch(maps, ivec3(tx, base + OBS_SSS_LAYER_POS), 0);
    if (tx.x < 0 || int(xi_id.w) != obj) {
      dim++;
      continue;
    }
    vec3 n = texelFetch(maps, ivec3(tx, base + OBS_SSS_LAYER_NRM), 0).xyz;
    vec3 et = texelFetch(maps, ivec3(tx, base + OBS_SSS_LAYER_IRR), 0).xyz;
    float si = length(xs - xi_id.xyz), e = 1.0;
    vec3 wl = ldir;
    if (p0.w > 0.5) {
      vec3 d = xi_id.xyz - p0.xyz;
      float dl = length(d);
      wl = d / dl;
      e = 1.0 / (dl * dl);
    }
    float ci = -dot(wl, n);
    float si_p = refracted_length(si, ci, eta);
    vec3 wi = refract_in(wl, n, eta);
    float ph = hg(-dot(wi, t), g);
    vec3 light = et * exp(-sigma_t * si_p);
    acc += ph * light * exp(-(sigma_t - sigma_min) * so) / sigma_min;
    if (lum(light) < 0.05 * lum(power * e)) dim++;
  }
  return dim;
}

void main() {
  ivec2 q = ivec2(gl_GlobalInvocationID.xy);
  if (q.x >= pc.width || q.y >= pc.height) return;
  vec4 hp = imageLoad(gpos, q);
  int obj = int(hp.w);
  vec3 rad = vec3(0.0);
  if (obj >= 0) {
    vec3 n = imageLoad(gnrm, q).xyz, d = imageLoad(gdir, q).xyz;
    int orow = obj * OBS_SSS_OBJ_ROWS;
    vec3 sigma_s = rows[orow].xyz;
    float eta = rows[orow + 2].y;
    float fto = schlick_t(dot(d, n), eta);
    vec3 t = refract_in(d, n, eta);
    for (int l = 0; l < pc.nlights; l++) {
      int m = pc.samples;
      vec3 acc = vec3(0.0);
      int dim = walk(l, obj, hp.xyz, t, m, uvec2(q), acc);
      float share = float(dim) / float(m);
      if (pc.adaptive != 0 && share >= 0.20 && share <= 0.85) {
        m *= 2;
        acc = vec3(0.0);
        walk(l, obj, hp.xyz, t, m, uvec2(q), acc);
      }
      rad += sigma_s * fto * acc / float(m);
    }
  }
  imageStore(outimg, q, vec4(rad, 0.0));
}
