// Schlick's Fresnel transmittance for sss_single's two shaders, as sss_single.h's
// obs_sss_schlick_t: 1 - F at the cosine on the outer (less dense) side.
float schlick_t(float c, float eta) {
  float r0 = (eta - 1.0) / (eta + 1.0);
  r0 *= r0;
  float x = max(1.0 - abs(c), 0.0);
  float x2 = x * x;
  return 1.0 - (r0 + (1.0 - r0) * x2 * x2 * x);
}
