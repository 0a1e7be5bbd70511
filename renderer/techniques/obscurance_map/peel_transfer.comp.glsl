// Depth peeling of obscurance_map: the transfers between two consecutive layers A (nearer) and B
// of one bundle direction, accumulated per patch in 64-bit fixed point (two 32-bit words with an
// explicit carry: integer sums do not depend on the order the atomics land in, so a map has the
// same bits on every run). Layers are (patch id, b, window depth, reflectivity index); id -1 is
// background (the virtual layers before the first and after the last), -2 a surface without
// patches. b is the cosine of the front normal with the direction towards the viewer.
#version 450
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0, rgba32f) uniform readonly image2D la;
layout(binding = 1, rgba32f) uniform readonly image2D lb;
// Per patch 16 words: sum of each channel (lo, hi) x 3, sum of squares x 3, samples, 2 unused.
layout(std430, binding = 2) buffer Acc { uint acc[]; };
layout(std430, binding = 3) readonly buffer Refl { vec4 refl[]; };
layout(std430, binding = 4) buffer Count { uint covered[]; }; // per layer of a batch

layout(push_constant) uniform Push {
  float dmax;  // d_max over the depth range (window depth units)
  float tau;   // exp falloff's rate per window depth unit
  int falloff; // 0 binary, 1 sqrt, 2 exp
  int bleed;
  int res;
  uint bg_s[3]; // fixed-point value of "nothing within d_max" (host-rounded, as the CPU's)
  uint bg_q[3]; // and of its square
  uint layer;   // this layer's slot in covered
} pc;

const float ONE = 268435456.0; // 2^28, as the CPU estimators' OMAP_ONE

void add64(uint at, uint x) {
  uint old = atomicAdd(acc[at], x);
  if (old + x < old) atomicAdd(acc[at + 1u], 1u);
}

void add_bg(int pid) {
  uint base = uint(pid) * 16u;
  for (int c = 0; c < 3; c++) {
    add64(base + uint(2 * c), pc.bg_s[c]);
    add64(base + uint(6 + 2 * c), pc.bg_q[c]);
  }
  add64(base + 12u, 1u);
}

// Patch `pid` sees a surface of reflectivity index `r` at window distance d.
void add_seen(int pid, float d, int r) {
  if (!(d < pc.dmax)) {
    add_bg(pid);
    return;
  }
  float rho = pc.falloff == 0 ? 0.0 : pc.falloff == 1 ? sqrt(d / pc.dmax) : 1.0 - exp(-pc.tau * d);
  vec3 v = pc.bleed != 0 ? rho * refl[r].rgb : vec3(rho);
  uint base = uint(pid) * 16u;
  for (int c = 0; c < 3; c++) {
    add64(base + uint(2 * c), uint(v[c] * ONE + 0.5));
    add64(base + uint(6 + 2 * c), uint(v[c] * v[c] * ONE + 0.5));
  }
  add64(base + 12u, 1u);
}

void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= pc.res || px.y >= pc.res) return;
  vec4 a = imageLoad(la, px), b = imageLoad(lb, px);
  bool ha = a.x != -1.0, hb = b.x != -1.0;
  if (hb) atomicAdd(covered[pc.layer], 1u);
  int ia = int(a.x), ib = int(b.x);
  if (ha && hb) {
    // Pass 0 and pass 1 of the article at once: A faces away from the viewer (towards B) and B
    // faces the viewer (towards A); any other pair does not face and records nothing.
    if (a.y < 0.0 && b.y > 0.0) {
      float d = b.z - a.z;
      if (ia >= 0) add_seen(ia, d, int(b.w));
      if (ib >= 0) add_seen(ib, d, int(a.w));
    }
  } else if (ha) {
    if (a.y < 0.0 && ia >= 0) add_bg(ia); // the last layer, facing away: nothing behind it
  } else if (hb) {
    if (b.y > 0.0 && ib >= 0) add_bg(ib); // the first layer, facing the viewer: nothing in front
  }
}
