/* Primary-ray generation for perspective and orthographic cameras. */
#ifndef OBS_CAMERA_H
#define OBS_CAMERA_H

#include "obscura/scene.h"

/* Precomputed camera frame. `forward` is the view axis used for linear depth. */
typedef struct obs_camera_rig {
  int ortho;
  double origin[3], forward[3], right[3], up[3];
  double half_w, half_h; /* tan-scaled (perspective) or world (orthographic) half extents */
  int width, height;
} obs_camera_rig;

void obs_camera_setup(const obs_camera *cam, int width, int height, obs_camera_rig *rig);
/* Ray through image position (fx, fy) in pixels (0,0 = top-left corner). dir is unit length. */
void obs_camera_ray(const obs_camera_rig *rig, double fx, double fy, double org[3], double dir[3]);

#endif
