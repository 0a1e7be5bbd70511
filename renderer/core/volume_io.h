/* Reading volume files into obs_volume (volume.h): NRRD through teem, raw bricks of a stated
 * shape and type, and the .den density files of VolPack (the MRI head Debian ships in
 * libvolpack1-dev's examples). Values are normalised to [0, 1]. */
#ifndef OBS_VOLUME_IO_H
#define OBS_VOLUME_IO_H

#include "obscura/error.h"
#include "volume.h"

typedef enum { OBS_VOLUME_FILE_NRRD, OBS_VOLUME_FILE_RAW, OBS_VOLUME_FILE_DEN } obs_volume_file;
typedef enum { OBS_VOLUME_UINT8, OBS_VOLUME_UINT16, OBS_VOLUME_FLOAT32 } obs_volume_type;

/* What to read. `path` is the caller's (already resolved and checked). */
typedef struct obs_volume_source {
  obs_volume_file format;
  const char *path;
  int dims[3];          /* raw: required; the others take the file's */
  obs_volume_type type; /* raw: the sample type, little-endian */
  /* Voxel spacing: raw requires it; NRRD takes the file's axis spacings where finite and
   * positive, .den and the rest 1; a positive value here overrides the file's. */
  double spacing[3];
  /* Normalisation: with lo < hi, v -> clamp((v - lo) / (hi - lo)); else the type's range (uint8
   * /255, uint16 /65535, signed integers from their minimum) or, for floating-point data, the
   * data's own minimum and maximum. */
  double range[2];
} obs_volume_source;

/* Reads `s` into `v` (initialised by the call). OBS_EIO when the file cannot be read, OBS_EINVAL
 * naming the file when its contents do not fit (size, dimension, header), OBS_ENOMEM. */
int obs_volume_read(const obs_volume_source *s, obs_volume *v, obs_err *err);

/* The shape of `s` without reading its samples: the dims (the file's header, or raw's stated
 * ones, checked against the file's size) and the spacing read_volume would use. The same errors
 * as obs_volume_read for a header or size that does not fit. */
int obs_volume_probe(const obs_volume_source *s, int dims[3], double spacing[3], obs_err *err);

#endif
