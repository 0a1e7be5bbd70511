// analytic_ao's closed forms (Shopf et al., ShaderX7 6.3), shared by its compute pass
// (analytic_ao.comp.glsl) and its rasterised proxies (analytic_ao_raster.frag.glsl): the twin of
// occluders.c, operation for operation (every value that feeds the output is `precise`, so nothing
// is contracted to FMA and the CPU can repeat it). The including shader declares the occluders'
// storage buffer `occ` (OBS_AAO_VEC4S vec4s each, analytic_ao.h) and enables
// GL_EXT_control_flow_attributes first.

const float TWO_PI = 6.28318530717958647692;
const float COPLANAR = 1e-4;

float saturate_(float x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

float atan_pos(float t) {
  precise float base = 0.0;
  precise float x = t;
  if (t > 2.414213562373095) {
    base = 1.5707963267948966;
    x = -1.0 / t;
  } else if (t > 0.4142135623730950) {
    base = 0.7853981633974483;
    x = (t - 1.0) / (t + 1.0);
  }
  precise float z = x * x;
  precise float y = (((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z -
                     3.33329491539e-1) * z * x + x;
  precise float r = base + y;
  return r;
}

float angle_of(float s, float c) {
  precise float r;
  if (c > 0.0) r = atan_pos(s / c);
  else if (c < 0.0) r = 3.14159265358979323846 - atan_pos(s / -c);
  else r = 1.5707963267948966;
  return r;
}

float dot3(vec3 a, vec3 b) {
  precise float r = a.x * b.x + a.y * b.y + a.z * b.z;
  return r;
}

vec3 cross3(vec3 a, vec3 b) {
  precise vec3 c;
  c.x = a.y * b.z - a.z * b.y;
  c.y = a.z * b.x - a.x * b.z;
  c.z = a.x * b.y - a.y * b.x;
  return c;
}

float sphere_occlusion(int base, vec3 p, vec3 nrm) {
  vec4 c = occ[base];
  precise vec3 v;
  v.x = c.x - p.x;
  v.y = c.y - p.y;
  v.z = c.z - p.z;
  precise float r = occ[base + 1].z;
  precise float d = sqrt(dot3(v, v));
  if (!(d > 0.0)) return 0.0;
  precise float h = dot3(nrm, v);
  precise float q = r / d;
  precise float occl = (h / d) * (q * q) * saturate_((h + r) / (2.0 * r));
  return saturate_(occl);
}

// The contour sum with the text's sign (occluders.c, obs_aao_polygon_sum), over m <= 8 vertices.
float polygon_sum(vec3 v[8], int m, vec3 nrm) {
  vec3 u[8];
  [[dont_unroll]] for (int i = 0; i < 8; i++) {
    if (i >= m) break;
    precise float l = sqrt(dot3(v[i], v[i]));
    precise vec3 w;
    w.x = l > 0.0 ? v[i].x / l : 0.0;
    w.y = l > 0.0 ? v[i].y / l : 0.0;
    w.z = l > 0.0 ? v[i].z / l : 0.0;
    u[i] = w;
  }
  precise float s = 0.0;
  [[dont_unroll]] for (int i = 0; i < 8; i++) {
    if (i >= m) break;
    vec3 a = u[i], b = u[i + 1 < m ? i + 1 : 0];
    precise vec3 c = cross3(b, a);
    precise float cl = sqrt(dot3(c, c));
    if (!(cl > 0.0)) continue;
    precise float theta = angle_of(cl, dot3(a, b));
    s += theta * (dot3(nrm, c) / cl);
  }
  precise float r = s / TWO_PI;
  return r;
}

// One polygon of n <= 4 corners (indices into the occluder's points at `base` + 2).
float polygon_occlusion(int base, ivec4 idx, int n, vec3 p, vec3 nrm, bool front_only) {
  vec3 v[8];
  vec3 c[8];
  precise float reach = sqrt(dot3(p, p));
  [[dont_unroll]] for (int i = 0; i < 4; i++) {
    if (i >= n) break;
    vec3 q = occ[base + 2 + idx[i]].xyz;
    precise vec3 d;
    d.x = q.x - p.x;
    d.y = q.y - p.y;
    d.z = q.z - p.z;
    v[i] = d;
    precise float l = sqrt(dot3(d, d));
    if (l > reach) reach = l;
  }
  int i2 = n > 3 ? 2 : 1, i3 = n > 3 ? 3 : 2, i1 = n > 3 ? 1 : 0;
  precise vec3 e1, e2;
  e1.x = v[i2].x - v[0].x;
  e1.y = v[i2].y - v[0].y;
  e1.z = v[i2].z - v[0].z;
  e2.x = v[i3].x - v[i1].x;
  e2.y = v[i3].y - v[i1].y;
  e2.z = v[i3].z - v[i1].z;
  precise vec3 wn = cross3(e1, e2);
  precise float wl = sqrt(dot3(wn, wn));
  if (!(wl > 0.0)) return 0.0;
  precise float side = -dot3(wn, v[0]) / wl;
  if (abs(side) <= COPLANAR * reach && abs(dot3(nrm, wn)) > 0.5 * wl) return 0.0;
  if (front_only && side < 0.0) return 0.0;
  int m = 0;
  [[dont_unroll]] for (int i = 0; i < 4; i++) {
    if (i >= n) break;
    vec3 a = v[i], b = v[i + 1 < n ? i + 1 : 0];
    precise float da = dot3(nrm, a);
    precise float db = dot3(nrm, b);
    if (da >= 0.0) c[m++] = a;
    if ((da >= 0.0) != (db >= 0.0)) {
      precise float t = da / (da - db);
      precise vec3 x;
      x.x = a.x + t * (b.x - a.x);
      x.y = a.y + t * (b.y - a.y);
      x.z = a.z + t * (b.z - a.z);
      c[m++] = x;
    }
  }
  if (m < 3) return 0.0;
  return abs(polygon_sum(c, m, nrm));
}

const ivec4 BOX_FACES[6] = ivec4[6](ivec4(0, 4, 6, 2), ivec4(1, 3, 7, 5), ivec4(0, 1, 5, 4),
                                    ivec4(2, 6, 7, 3), ivec4(0, 2, 3, 1), ivec4(4, 5, 7, 6));

// Every polygon occluder as a list of faces read by one call site in a loop the compiler keeps:
// a polygon is one face, a non-planar quad its two triangles, a box its six faces (summed from
// 0 in the CPU's order). Unrolled, the box alone made a shader lavapipe took seconds to compile.
float occlusion(int base, vec3 p, vec3 nrm) {
  vec4 info = occ[base + 1];
  if (info.x == 0.0) return sphere_occlusion(base, p, nrm);
  bool box = info.x != 1.0, split = !box && info.w != 0.0;
  int faces = box ? 6 : (split ? 2 : 1);
  precise float s = 0.0;
  [[dont_unroll]] for (int f = 0; f < faces; f++) {
    ivec4 idx = box ? BOX_FACES[f] : (split && f == 1 ? ivec4(0, 2, 3, 0) : ivec4(0, 1, 2, 3));
    int n = box ? 4 : (split ? 3 : int(info.y));
    s += polygon_occlusion(base, idx, n, p, nrm, box);
  }
  return saturate_(s);
}

// The view-space point of G-buffer pixel px at linear depth z (gbuffer.h's projection).
vec3 aao_receiver(ivec2 px, float z, int width, int height, int ortho, float half_w, float half_h) {
  precise vec3 p;
  precise float fx = float(px.x) + 0.5;
  precise float fy = float(px.y) + 0.5;
  precise float nx = 2.0 * fx / float(width) - 1.0;
  precise float ny = 1.0 - 2.0 * fy / float(height);
  if (ortho != 0) {
    p.x = nx * half_w;
    p.y = ny * half_h;
  } else {
    p.x = nx * half_w * z;
    p.y = ny * half_h * z;
  }
  p.z = z;
  return p;
}
