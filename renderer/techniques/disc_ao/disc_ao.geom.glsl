// disc_ao's proxies (Bookout, ShaderX7 6.8): per disc, a screen-aligned quad covering its
// influence sphere, or the back faces of the smallest square pyramid holding the half of that
// sphere the disc can occlude. Every receiver the CPU twin's reach test admits is covered, so the
// fragment shader's own test decides, as on the CPU.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "layout.h"
layout(points) in;
layout(triangle_strip, max_vertices = 18) out;
layout(location = 0) in vec4 v_c[];
layout(location = 1) in vec4 v_n[];
layout(location = 0) flat out vec4 f_c;
layout(location = 1) flat out vec4 f_n;

bool ortho() { return (pc.flags & OBS_DISC_FLAG_ORTHO) != 0; }

// View space (gbuffer.h: x right, y up, z forward) to clip space; window depth is unused.
vec4 clip(vec3 q) {
  if (ortho()) return vec4(q.x / pc.half_w, -q.y / pc.half_h, 0.5, 1.0);
  return vec4(q.x / pc.half_w, -q.y / pc.half_h, 0.5 * q.z, q.z);
}

void emit(vec4 p) {
  gl_Position = p;
  f_c = v_c[0];
  f_n = v_n[0];
  EmitVertex();
}

// The rectangle of the sphere's box in normalised device coordinates. Its x/z and y/z are
// extreme at the box's nearest or farthest depth. A sphere that reaches the camera plane gets
// the whole screen (the article's abs(z) moves it in front instead, which leaves receivers near
// the camera uncovered); one wholly behind the camera reaches no receiver.
void quad(vec3 c, float r) {
  vec2 lo, hi;
  if (ortho()) {
    if (c.z + r < 0.0) return;
    lo = vec2((c.x - r) / pc.half_w, -(c.y + r) / pc.half_h);
    hi = vec2((c.x + r) / pc.half_w, -(c.y - r) / pc.half_h);
  } else {
    float zn = c.z - r, zf = c.z + r;
    if (zf <= 0.0) return;
    if (zn <= 0.0) {
      lo = vec2(-1.0);
      hi = vec2(1.0);
    } else {
      float x0 = c.x - r, x1 = c.x + r, y0 = c.y - r, y1 = c.y + r;
      lo = vec2(min(x0 / zn, x0 / zf) / pc.half_w, -max(y1 / zn, y1 / zf) / pc.half_h);
      hi = vec2(max(x1 / zn, x1 / zf) / pc.half_w, -min(y0 / zn, y0 / zf) / pc.half_h);
    }
  }
  lo = max(lo, vec2(-2.0));
  hi = min(hi, vec2(2.0));
  if (!(lo.x < hi.x) || !(lo.y < hi.y)) return;
  // The strip (-1,-1), (-1,1), (1,-1), (1,1): two triangles that cover the whole rectangle.
  emit(vec4(lo.x, lo.y, 0.5, 1.0));
  emit(vec4(lo.x, hi.y, 0.5, 1.0));
  emit(vec4(hi.x, lo.y, 0.5, 1.0));
  emit(vec4(hi.x, hi.y, 0.5, 1.0));
  EndPrimitive();
}

// Triangle (p0, p1, p2) of a convex solid around `mid` when the eye sees its inside: the face a
// pixel's ray leaves the solid by, one per covered pixel.
void back_face(vec3 p0, vec3 p1, vec3 p2, vec3 mid) {
  vec3 m = cross(p1 - p0, p2 - p0);
  if (dot(m, p0 - mid) < 0.0) m = -m;
  float facing = ortho() ? m.z : dot(m, p0);
  if (!(facing > 0.0)) return;
  emit(clip(p0));
  emit(clip(p1));
  emit(clip(p2));
  EndPrimitive();
}

// Of the square pyramids with base centre c on the disc's plane and apex on its axis whose sides
// are at distance r from c, the smallest: base half-width sqrt(3/2) r, height sqrt(3) r.
void pyramid(vec3 c, vec3 n, float r) {
  vec3 a = (pc.flags & OBS_DISC_FLAG_BACK) != 0 ? -n : n;
  vec3 t = normalize(abs(a.x) < 0.9 ? cross(a, vec3(1.0, 0.0, 0.0)) : cross(a, vec3(0.0, 1.0, 0.0)));
  vec3 b = cross(a, t);
  float hb = 1.2247449 * r, h = 1.7320508 * r;
  vec3 q0 = c + hb * (t + b), q1 = c + hb * (b - t), q2 = c - hb * (t + b), q3 = c + hb * (t - b);
  vec3 apex = c + h * a, mid = c + 0.25 * h * a;
  back_face(q0, q1, q2, mid);
  back_face(q0, q2, q3, mid);
  back_face(q0, q1, apex, mid);
  back_face(q1, q2, apex, mid);
  back_face(q2, q3, apex, mid);
  back_face(q3, q0, apex, mid);
}

void main() {
  float r = sqrt(v_n[0].w) * OBS_DISC_PROXY_MARGIN;
  if ((pc.flags & OBS_DISC_FLAG_PYRAMID) != 0)
    pyramid(v_c[0].xyz, v_n[0].xyz, r);
  else
    quad(v_c[0].xyz, r);
}
