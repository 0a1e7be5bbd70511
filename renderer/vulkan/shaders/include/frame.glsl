// The sampling frame shared by the shaders that sample about a normal: obs_onb of
// renderer/core/sampling.h (Duff et al. 2017 with its guard; the reasons are written there), the
// same operations in the same order, `precise` so nothing is fused, hence the CPU's bits.
// Included with GL_GOOGLE_include_directive: #include "include/frame.glsl".
#ifndef OBS_FRAME_GLSL
#define OBS_FRAME_GLSL

const float OBS_ONB_FLAT = 9.5367431640625e-7; // 2^-20

void obs_onb(vec3 n, out vec3 t, out vec3 b) {
  // A component within 2^-20 of 0 is +0 (either sign of zero included), then the sign of z.
  float x = abs(n.x) < OBS_ONB_FLAT ? 0.0 : n.x;
  float y = abs(n.y) < OBS_ONB_FLAT ? 0.0 : n.y;
  float z = abs(n.z) < OBS_ONB_FLAT ? 0.0 : n.z;
  float sign = z < 0.0 ? -1.0 : 1.0;
  precise float a = -1.0 / (sign + z);
  precise float c = x * y * a;
  precise vec3 tt = vec3(1.0 + sign * x * x * a, sign * c, -sign * x);
  precise vec3 bb = vec3(c, sign + y * y * a, -y);
  t = tt;
  b = bb;
}

#endif
