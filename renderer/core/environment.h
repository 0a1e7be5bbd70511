/* Environment lighting for image-based techniques (volume_ao lights an isosurface from the
 * environment seen along its bent normal; ibl_shadows fits shadow-map visibility in SH; path_trace
 * light-samples maps): a cube map of linear RGB radiance built from a lat-long image, six face
 * images or a procedural sky; bilinear lookups; exact texel solid angles; the diffuse
 * (cosine-convolved) environment through nine spherical-harmonic coefficients, with a brute-force
 * quadrature as its reference; real SH up to band 3 and the projection onto them; and importance
 * sampling by luminance x sin theta (environment_sample.c). No Embree, no Vulkan: the layout below
 * is the one a Vulkan cube image uses, so a sampler there reads the same faces. */
#ifndef OBS_ENVIRONMENT_H
#define OBS_ENVIRONMENT_H

#include <stdint.h>

#include "obscura/error.h"
#include "obscura/scene.h"

/* Face order and orientation: the OpenGL/Vulkan cube-map convention. Face f is layer f of a Vulkan
 * cube image: +X, -X, +Y, -Y, +Z, -Z. A direction r = (rx, ry, rz) selects the face of its
 * largest-magnitude component ma (ties: x before y before z), then the Vulkan spec's table
 * ("Cube Map Face Selection") gives (sc, tc):
 *
 *   face  major  sc    tc    ma
 *   0     +X     -rz   -ry   rx
 *   1     -X     +rz   -ry   rx
 *   2     +Y     +rx   +rz   ry
 *   3     -Y     +rx   -rz   ry
 *   4     +Z     +rx   -ry   rz
 *   5     -Z     -rx   -ry   rz
 *
 * and s = (sc / |ma| + 1) / 2, t = (tc / |ma| + 1) / 2, both in [0, 1]. Texel (i, j) of a face
 * (column i along s, row j along t, row 0 at t = 0) covers s in [i, i + 1] / res and t in
 * [j, j + 1] / res; its centre is at ((i + 0.5) / res, (j + 0.5) / res). */
enum { OBS_ENV_PX, OBS_ENV_NX, OBS_ENV_PY, OBS_ENV_NY, OBS_ENV_PZ, OBS_ENV_NZ, OBS_ENV_FACE_COUNT };
#define OBS_ENV_MAX_RES 2048
/* The most supersamples along a face side when a constructor filters (n x res <= this). */
#define OBS_ENV_MAX_SAMPLES 2048

/* A cube map of 6 faces of res x res linear RGB radiance, all finite and non-negative. The struct
 * owns `data`: one allocation, face f at data + f * res * res * 3, texel (i, j) of face f at
 * data + ((f * res + j) * res + i) * 3, RGB interleaved (obs_env_texel). `mean` is the
 * solid-angle-weighted mean radiance, cached at construction. Every constructor fills a zeroed
 * struct; on failure it leaves it zeroed and owning nothing. Read-only use is thread-safe. */
typedef struct obs_env {
  int res;
  float *data;
  double mean[3];
} obs_env;

void obs_env_free(obs_env *e);

static inline float *obs_env_texel(const obs_env *e, int face, int i, int j) {
  return e->data + (((size_t)face * (size_t)e->res + (size_t)j) * (size_t)e->res + (size_t)i) * 3;
}

/* The unit direction through face coordinates (s, t) of face f (the inverse of the table above). */
void obs_env_face_dir(int face, double s, double t, double dir[3]);
/* The face a direction selects and its (s, t) in [0, 1]. Returns the face, or -1 for a zero or
 * non-finite direction (s, t untouched). `dir` need not be normalised. */
int obs_env_face_coords(const double dir[3], double *s, double *t);

/* Constructors. Each returns 0 or a negative OBS_E* code with a message naming the input (the
 * file, the pixel or texel, the parameter). res must be in [1, OBS_ENV_MAX_RES]; every value must
 * be finite and non-negative. */

/* A constant environment of radiance rgb (res 1). */
int obs_env_constant(obs_env *e, const double rgb[3], obs_err *err);

/* Converts an equirectangular (lat-long) image to a cube map of res x res faces. `rgb` is w x h
 * pixels, RGB interleaved, row 0 at the top: pixel (x, y) at rgb + (y * w + x) * 3, borrowed.
 * Convention (+Y up): the unit direction d is at
 *   u = 0.5 + atan2(dx, -dz) / (2 pi),   v = acos(dy) / pi,
 * and image position (u w, v h) (pixel (x, y) has its centre at u = (x + 0.5) / w,
 * v = (y + 0.5) / h). So the top row looks up (+Y), the bottom row down, the image centre looks
 * towards -Z, u = 0.75 towards +X, u = 0.25 towards -X and the left and right edges towards +Z.
 * Lookups are bilinear between pixel centres, wrapping in u and clamped in v. Each cube texel is
 * the solid-angle-weighted mean of n x n lookups at evenly spaced points of the texel, n the
 * smallest that spaces them no farther apart than half the image's pixel spacing, at least 2 and
 * at most OBS_ENV_MAX_SAMPLES / res (so a small bright source keeps its power when the cube map is
 * coarser than the image). Refused: w < 2, h < 1, a NULL image, a value not finite or negative
 * (named by pixel and channel). */
int obs_env_from_latlong(obs_env *e, const float *rgb, int w, int h, int res, obs_err *err);
/* Reads the R, G, B channels of the OpenEXR file `path` (other channels are ignored) and converts
 * it as obs_env_from_latlong does. Messages name the file. */
int obs_env_from_latlong_file(obs_env *e, const char *path, int res, obs_err *err);

/* Copies six res x res faces, each RGB interleaved in the layout of obs_env::data (texel (i, j) at
 * faces[f] + (j * res + i) * 3), in the face order and orientation above. Borrowed. */
int obs_env_from_faces(obs_env *e, const float *const faces[6], int res, obs_err *err);
/* Reads six square OpenEXR files of the same size with R, G, B channels, in face order (+X, -X,
 * +Y, -Y, +Z, -Z), each in the orientation above with its row 0 at t = 0. */
int obs_env_from_face_files(obs_env *e, const char *const paths[6], obs_err *err);

/* A procedural sky for scenes without files (+Y up). With h = d.y for the unit direction d:
 *   h >= 0:  horizon + (zenith - horizon) h
 *   h < 0:   horizon + (ground - horizon) smoothstep(0, 0.1, -h)   (a soft horizon, ~6 degrees)
 * plus, when sun_radius_deg > 0, sun_radiance w(a), a the angle between d and sun_dir:
 *   w(a) = 1 - smoothstep(0.9 r, 1.1 r, a),  r = sun_radius_deg in radians,
 * a disc of angular radius r with a softened rim (weight 1/2 at a = r). Continuous in d. */
typedef struct obs_env_sky_params {
  double zenith[3];       /* radiance straight up */
  double horizon[3];      /* radiance at the horizon, from above and below */
  double ground[3];       /* radiance below the soft horizon band */
  double sun_dir[3];      /* towards the sun, need not be normalised; ignored without a sun */
  double sun_radius_deg;  /* angular radius in (0, 45]; 0 = no sun */
  double sun_radiance[3]; /* radiance inside the disc (added to the sky) */
} obs_env_sky_params;

/* Blue zenith, pale horizon, dark brown ground, a warm sun of radius 2 degrees 45 degrees up and
 * to the side (towards +X, -Z) that gives a surface facing it about twice the sky's irradiance
 * in luminance (Rec. 709 weights). */
void obs_env_sky_default(obs_env_sky_params *p);
/* The sky's radiance along dir (need not be normalised; a zero or non-finite dir gives the horizon
 * colour). Pure. */
void obs_env_sky_radiance(const obs_env_sky_params *p, const double dir[3], double rgb[3]);
/* Fills a res x res cube map with the sky: each texel the solid-angle-weighted mean of n x n
 * evaluations at evenly spaced points of the texel, n = 2, or more when the sun is narrower than a
 * few texels: samples at most an eighth of the sun's radius apart (up to OBS_ENV_MAX_SAMPLES /
 * res), so its power is kept to about 1%. Refused: colours not finite and non-negative, a sun
 * radius outside [0, 45] degrees, a zero or non-finite sun direction with a sun. */
int obs_env_sky(obs_env *e, const obs_env_sky_params *p, int res, obs_err *err);

/* Radiance along dir (need not be normalised), bilinear between the texel centres of the face dir
 * selects, texel coordinates clamped at the face's edges: seams are not filtered across faces, so
 * within half a texel of an edge the value is that of the edge texels. A zero or non-finite dir
 * gives the mean radiance. Always finite. */
void obs_env_lookup(const obs_env *e, const float dir[3], float rgb[3]);

/* The exact solid angle of texel (i, j) of any face at resolution res (0 outside the face): with
 * A(x, y) = atan2(x y, sqrt(x^2 + y^2 + 1)) the area of the face's projection up to (x, y), the
 * texel spanning [x0, x1] x [y0, y1] of the face at distance 1 (x = 2 s - 1) has
 * A(x0, y0) - A(x0, y1) - A(x1, y0) + A(x1, y1). The 6 res^2 texels sum to 4 pi. */
double obs_env_texel_solid_angle(int res, int i, int j);
/* The solid-angle-weighted mean radiance (the cached value). */
void obs_env_mean(const obs_env *e, double rgb[3]);

/* Projects the environment onto the 9 real spherical harmonics of bands 0..2 (each texel at its
 * centre direction, weighted by its exact solid angle). Coefficient order and basis (d unit):
 *   0: Y00 = 0.282095           1: Y1-1 = 0.488603 y     2: Y10 = 0.488603 z
 *   3: Y11 = 0.488603 x         4: Y2-2 = 1.092548 xy    5: Y2-1 = 1.092548 yz
 *   6: Y20 = 0.315392 (3z^2-1)  7: Y21 = 1.092548 xz     8: Y22 = 0.546274 (x^2 - y^2)
 * (the exact constants sqrt(1/4pi), sqrt(3/4pi), sqrt(15/4pi), sqrt(5/16pi), sqrt(15/16pi)). */
void obs_env_sh9(const obs_env *e, double coeffs[9][3]);
/* The real spherical harmonics of bands 0..bands-1 (bands in 1..OBS_SH_MAX_BANDS, bands^2
 * coefficients) at unit direction d, in the order above, then band 3 (m = -3..3):
 *   9: 0.590044 y (3x^2 - y^2)    10: 2.890611 xyz            11: 0.457046 y (5z^2 - 1)
 *  12: 0.373176 z (5z^2 - 3)      13: 0.457046 x (5z^2 - 1)   14: 1.445306 z (x^2 - y^2)
 *  15: 0.590044 x (x^2 - 3y^2)
 * (exact constants sqrt(35/2pi)/4, sqrt(105/pi)/2, sqrt(21/2pi)/4, sqrt(7/pi)/4, sqrt(105/pi)/4).
 * Orthonormal over the sphere. */
#define OBS_SH_MAX_BANDS 4
#define OBS_SH_MAX_COEFFS 16
void obs_sh_basis(int bands, const double d[3], double *y);
/* The projection of the environment onto bands 0..bands-1 as obs_env_sh9 does (which is this
 * with bands 3): bands^2 RGB coefficients. A constant radiance c gives c 2 sqrt(pi) in the first
 * and 0 elsewhere. */
void obs_env_sh(const obs_env *e, int bands, double (*coeffs)[3]);
/* The diffuse-convolved environment at normal n from those coefficients (Ramamoorthi and Hanrahan
 * 2001, A0 = pi, A1 = 2 pi / 3, A2 = pi / 4), divided by pi: the outgoing radiance of a white
 * Lambertian surface (albedo 1) facing n, so a constant environment L gives L. The 9-term
 * approximation can dip below 0 away from bright sources; negatives are clamped to 0. n need not
 * be normalised; a zero or non-finite n gives the band-0 term (the mean radiance). */
void obs_env_sh_irradiance(const double coeffs[9][3], const float n[3], float rgb[3]);
/* The same quantity by brute force, the reference for the SH path: (1/pi) times the sum over all
 * texels of the texel's radiance times the integral of max(0, n . w) over the texel, each texel
 * taken as constant over its area. That integral is exact: a texel is a spherical quadrilateral
 * (its edges are great arcs), clipped at the plane n . w = 0 and integrated by Lambert's formula
 * for polygons, so a constant environment gives its value at any resolution. O(res^2) per call.
 * A zero or non-finite n gives the mean radiance. */
void obs_env_irradiance_ref(const obs_env *e, const float n[3], float rgb[3]);

/* Importance sampling of an environment (environment_sample.c): a w x h lat-long grid over the
 * cube map in obs_env_from_latlong's convention (pixel (x, y) spans u in [x, x + 1] / w and
 * v in [y, y + 1] / h, v = theta / pi from +Y), whose probability mass function is each pixel's
 * luminance (Rec. 709: 0.2126 R + 0.7152 G + 0.0722 B, looked up at its centre) times sin theta
 * at its centre, normalised: the marginal over rows and the conditional within each row kept as
 * cumulative sums (Colbert and Krivanek, ShaderX7 4.3; pbrt's Distribution2D). Within the chosen
 * pixel the point is uniform in (u, v), so the density in solid angle at a direction of polar
 * angle theta is pmf w h / (2 pi^2 sin theta). Owns its arrays; obs_env_dist_free releases. */
typedef struct obs_env_dist {
  int w, h;
  double total;   /* the sum of all pixel weights (0: nothing to sample) */
  double *row;    /* h + 1 entries: row[y] = sum of the weights of rows < y */
  double *col;    /* h (w + 1) entries: col[y (w + 1) + x] = sum of row y's weights before x */
} obs_env_dist;

/* Builds the distribution over a w x h grid (w in 2..4096, h in 1..2048). OBS_EINVAL names the
 * argument out of range; an environment without light gives total 0 (obs_env_dist_sample then
 * returns 0). */
int obs_env_dist_build(obs_env_dist *d, const obs_env *e, int w, int h, obs_err *err);
void obs_env_dist_free(obs_env_dist *d);
/* The grid both users build for a cube map of side res: 4 res x 2 res (about a cube texel per
 * pixel at the equator), clamped to 16 x 8 .. 1024 x 512. */
void obs_env_dist_grid(int res, int *w, int *h);
/* The probability of pixel (x, y) (0 outside the grid). */
double obs_env_dist_pmf(const obs_env_dist *d, int x, int y);
/* The unit direction at lat-long position (u, v) in [0, 1]^2. */
void obs_env_latlong_dir(double u, double v, double dir[3]);
/* Maps (u0, u1) in [0, 1)^2 to a direction: the row is the first whose cumulative weight exceeds
 * u0 times the total, the column likewise with u1 inside that row, and the remainders of u0 and
 * u1 place the point inside the pixel (so stratified inputs stay stratified). Returns the density
 * in solid angle (0 for an environment without light; dir is then +Y). */
double obs_env_dist_sample(const obs_env_dist *d, double u0, double u1, double dir[3]);
/* The density obs_env_dist_sample has at unit direction dir (0 where it never samples). */
double obs_env_dist_pdf(const obs_env_dist *d, const double dir[3]);
/* The folded Hammersley point i of n (Pharr and Humphreys 2004): (i + 0.5) / n and the folded
 * radical inverse of i in base 2, both in [0, 1). */
void obs_folded_hammersley(uint32_t i, uint32_t n, double *u0, double *u1);

/* The environment of `sc` (its `env`: a colour, a lat-long file, six face files or the sky) as a
 * cube map, scaled by its intensity (environment_scene.c). Messages start "<scene>: /environment:
 * ". */
int obs_env_from_scene(const obs_scene *sc, obs_env *e, obs_err *err);

#endif
