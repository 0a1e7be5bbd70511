/* Camera frames and primary rays, computed in double so huge or tiny scenes keep their precision. */
#include "camera.h"

#include <math.h>

#include "normalize.h"

/* A zero vector stays zero: the validator refuses the cameras that would give one. */
static void normalize(double v[3]) { (void)obs_normalize3d(v); }

static void cross(const double a[3], const double b[3], double o[3]) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}

void obs_camera_setup(const obs_camera *cam, int width, int height, obs_camera_rig *rig) {
  double up[3] = {cam->up.x, cam->up.y, cam->up.z};
  rig->origin[0] = cam->position.x;
  rig->origin[1] = cam->position.y;
  rig->origin[2] = cam->position.z;
  rig->forward[0] = cam->look_at.x - cam->position.x;
  rig->forward[1] = cam->look_at.y - cam->position.y;
  rig->forward[2] = cam->look_at.z - cam->position.z;
  normalize(rig->forward);
  /* right = forward x up: with +y up and +z forward, image right is -x (right-handed world). up
   * may be as small as 1e-300 or as large as 1e30: it is scaled (exactly, by a power of two) to
   * unit size first, so the cross product neither underflows nor overflows. */
  obs_prescale3d(up);
  cross(rig->forward, up, rig->right);
  normalize(rig->right);
  cross(rig->right, rig->forward, rig->up);
  rig->ortho = cam->type == OBS_CAMERA_ORTHOGRAPHIC;
  rig->width = width;
  rig->height = height;
  double aspect = (double)width / (double)height;
  if (rig->ortho) {
    rig->half_h = 0.5 * cam->height;
  } else {
    rig->half_h = tan(0.5 * cam->fov_y * 3.14159265358979323846 / 180.0);
  }
  rig->half_w = rig->half_h * aspect;
}

void obs_camera_ray(const obs_camera_rig *rig, double fx, double fy, double org[3],
                    double dir[3]) {
  double sx = (2.0 * fx / rig->width - 1.0) * rig->half_w;
  double sy = (1.0 - 2.0 * fy / rig->height) * rig->half_h;
  for (int k = 0; k < 3; k++) {
    if (rig->ortho) {
      org[k] = rig->origin[k] + sx * rig->right[k] + sy * rig->up[k];
      dir[k] = rig->forward[k];
    } else {
      org[k] = rig->origin[k];
      dir[k] = rig->forward[k] + sx * rig->right[k] + sy * rig->up[k];
    }
  }
  normalize(dir);
}
