/* ibl_shadows' backend-neutral set-up: the importance-sampled shadow directions, the
 * Tikhonov-regularised pseudo-inverse that turns shadow-map visibility into SH coefficients, the
 * environment's SH and the shading from fitted coefficients (docs/techniques/ibl_shadows.md). */
#include <math.h>
#include <string.h>

#include "ibl_shadows.h"

#define PI 3.14159265358979323846

const char *const obs_ibl_shadows_extra_names[OBS_IBL_EXTRA] = {
    "radiance.R", "radiance.G", "radiance.B", "bent_normal.X", "bent_normal.Y", "bent_normal.Z"};

/* Cyclic Jacobi eigen-decomposition of the symmetric n x n matrix a (destroyed; its diagonal
 * ends as the eigenvalues), eigenvectors in the columns of v. Sweeps in a fixed order, so the
 * result depends on the input only. */
static void jacobi(double a[OBS_SH_MAX_COEFFS][OBS_SH_MAX_COEFFS], int n,
                   double v[OBS_SH_MAX_COEFFS][OBS_SH_MAX_COEFFS]) {
  for (int i = 0; i < n; i++)
    for (int j = 0; j < n; j++) v[i][j] = i == j;
  for (int sweep = 0; sweep < 64; sweep++) {
    double off = 0, diag = 0;
    for (int i = 0; i < n; i++) {
      diag += a[i][i] * a[i][i];
      for (int j = i + 1; j < n; j++) off += a[i][j] * a[i][j];
    }
    if (!(off > 1e-30 * diag)) break;
    for (int p = 0; p < n; p++)
      for (int q = p + 1; q < n; q++) {
        if (a[p][q] == 0) continue;
        double th = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        double t = (th >= 0 ? 1 : -1) / (fabs(th) + sqrt(th * th + 1));
        double c = 1 / sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < n; k++) {
          double akp = a[k][p], akq = a[k][q];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < n; k++) {
          double apk = a[p][k], aqk = a[q][k];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (int k = 0; k < n; k++) {
          double vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
  }
}

int obs_ibl_pinv(const double (*dir)[3], int m, int bands, double alpha,
                 float yplus[OBS_SH_MAX_COEFFS][OBS_IBL_MAX_MAPS], obs_err *err) {
  if (m < 1 || m > OBS_IBL_MAX_MAPS || bands < 1 || bands > OBS_SH_MAX_BANDS || !(alpha >= 0))
    return obs_err_set(err, OBS_EINVAL,
                       "ibl_shadows: pseudo-inverse of %d directions, %d bands, alpha %g: out of "
                       "range (1..%d, 1..%d, >= 0)",
                       m, bands, alpha, OBS_IBL_MAX_MAPS, OBS_SH_MAX_BANDS);
  const int n = bands * bands;
  static const int N = OBS_SH_MAX_COEFFS;
  double y[OBS_IBL_MAX_MAPS][OBS_SH_MAX_COEFFS], a[OBS_SH_MAX_COEFFS][OBS_SH_MAX_COEFFS];
  double v[OBS_SH_MAX_COEFFS][OBS_SH_MAX_COEFFS];
  for (int j = 0; j < m; j++) obs_sh_basis(bands, dir[j], y[j]);
  for (int r = 0; r < N; r++)
    for (int c = 0; c < N; c++) {
      double s = 0;
      if (r < n && c < n)
        for (int j = 0; j < m; j++) s += y[j][r] * y[j][c];
      a[r][c] = s;
    }
  jacobi(a, n, v);
  double top = 0;
  for (int k = 0; k < n; k++) top = fmax(top, a[k][k]);
  /* M = sum over kept eigenpairs of v_k v_k^T / (s_k^2 + alpha^2); Y+ = M Y^T. */
  double mm[OBS_SH_MAX_COEFFS][OBS_SH_MAX_COEFFS];
  memset(mm, 0, sizeof mm);
  for (int k = 0; k < n; k++) {
    double l = a[k][k];
    if (!(l > 1e-12 * top)) continue;
    double f = 1 / (l + alpha * alpha);
    for (int r = 0; r < n; r++)
      for (int c = 0; c < n; c++) mm[r][c] += v[r][k] * v[c][k] * f;
  }
  for (int r = 0; r < N; r++)
    for (int j = 0; j < OBS_IBL_MAX_MAPS; j++) {
      double s = 0;
      if (r < n && j < m)
        for (int c = 0; c < n; c++) s += mm[r][c] * y[j][c];
      yplus[r][j] = (float)s;
    }
  return 0;
}

int obs_ibl_setup_make(const obs_env *env, const obs_ibl_shadows_params *p, obs_ibl_setup *s,
                       obs_err *err) {
  memset(s, 0, sizeof *s);
  if (!env || !env->data)
    return obs_err_set(err, OBS_EINVAL, "ibl_shadows: the scene has no environment to light with");
  if (p->shadow_maps < 1 || p->shadow_maps > OBS_IBL_MAX_MAPS)
    return obs_err_set(err, OBS_EINVAL, "ibl_shadows: shadow_maps must be 1..%d (got %d)",
                       OBS_IBL_MAX_MAPS, p->shadow_maps);
  int w, h;
  obs_env_dist_grid(env->res, &w, &h);
  obs_env_dist d;
  int rc = obs_env_dist_build(&d, env, w, h, err);
  if (rc) return rc;
  s->m = p->shadow_maps;
  s->n = p->sh_order * p->sh_order;
  for (int i = 0; i < s->m; i++) {
    double u0, u1;
    obs_folded_hammersley((uint32_t)i, (uint32_t)s->m, &u0, &u1);
    /* A dark environment has no distribution: the directions are then uniform over the sphere
     * (cos theta = 1 - 2 u0), which still gives the ao and the bent normal. */
    if (d.total > 0)
      obs_env_dist_sample(&d, u0, u1, s->dir[i]);
    else
      obs_env_latlong_dir(u1, acos(1 - 2 * u0) / PI, s->dir[i]);
  }
  obs_env_dist_free(&d);
  rc = obs_ibl_pinv((const double(*)[3])s->dir, s->m, p->sh_order, p->tikhonov, s->yplus, err);
  if (!rc) obs_env_sh(env, p->sh_order, s->env_sh);
  return rc;
}

void obs_ibl_shade(const obs_ibl_setup *s, const float *w, const float rho[3],
                   const float n_world[3], float rgb[3], float *ao, float bent[3]) {
  for (int c = 0; c < 3; c++) {
    double sum = 0;
    for (int k = 0; k < s->n; k++) sum += (double)w[k] * s->env_sh[k][c];
    double v = rho[c] * sum / PI;
    rgb[c] = v > 0 ? (float)v : 0.0f;
  }
  double a = 2 * w[0] / sqrt(PI);
  *ao = (float)(a < 0 ? 0 : a > 1 ? 1 : a);
  double b[3] = {0, 0, 0}, l = 0;
  if (s->n >= 4) {
    b[0] = w[3], b[1] = w[1], b[2] = w[2];
    l = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  }
  for (int k = 0; k < 3; k++) bent[k] = l > 0 ? (float)(b[k] / l) : n_world[k];
}
