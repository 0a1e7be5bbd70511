/* Proximity fields (Menexi and Papaioannou, "Pre-calculated Volumetric Illumination for Real-time
 * Graphics"): per object, a voxel grid over its object-space box grown by the propagation radius,
 * voxelised (every voxel the surface touches holds 1) and flooded outward, and the reconstruction
 * of ambient occlusion from such fields along a surface normal. Backend-independent: the CPU
 * floods here; a backend may flood on its own device (obs_prox_flood_fn) with the same values. */
#ifndef OBS_PROXIMITY_H
#define OBS_PROXIMITY_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>

#include "geometry.h"
#include "obscura/error.h"
#include "obscura/scene.h"

/* The reference box whose diagonal r_p is a fraction of, from the surface objects' world boxes in
 * frame 0: per axis the largest extent over all objects (the thesis's "maximal box"), the largest
 * single object's box, or the union of all. */
enum { OBS_PROX_BOX_MAXIMAL, OBS_PROX_BOX_LARGEST, OBS_PROX_BOX_UNION };

/* How the grids are laid out (docs/techniques/proximity_ao.md, "Pre-processing"). */
typedef struct obs_prox_layout {
  double fraction; /* r_p = fraction x the reference box's diagonal (world units) */
  int box;         /* the reference box: OBS_PROX_BOX_* */
  int res;         /* voxels per axis of the largest grid side (>= 1) */
  int min_res;     /* the fewest voxels per axis (clamped to res) */
} obs_prox_layout;

/* One object's field. Voxel (i, j, k) covers grid coordinates [i, i+1] x [j, j+1] x [k, k+1];
 * grid coordinates g = (object-space point - lo) / voxel; values sit at voxel centres. */
typedef struct obs_prox_field {
  size_t object;      /* index into scene->objects */
  int dims[3];
  double lo[3];       /* object-space corner of the grid: the object's box less r_p per axis */
  double voxel[3];    /* voxel sides, object space */
  int iterations;     /* N_p = ceil(r_p / voxel diagonal in world units) */
  size_t count;       /* dims[0] x dims[1] x dims[2] */
  size_t occupied_count;
  uint8_t *occupied;  /* 1 per voxel the surface touches, x fastest; owned */
  float *value;       /* the flooded field, x fastest; owned */
} obs_prox_field;
/* A field's bytes per voxel: its value and its occupancy. */
#define OBS_PROX_VOXEL_BYTES (sizeof(float) + sizeof(uint8_t))

/* Every surface object's field (volumes have none). Owns its fields. */
typedef struct obs_prox_fields {
  obs_prox_field *f;
  size_t n;
  double rp;          /* the propagation radius, world units (frame 0) */
  double voxelise_ms, flood_ms;
  size_t bytes;       /* memory of the fields (values and occupancy) */
} obs_prox_fields;

/* Floods field `f` in place: f->iterations times, every unoccupied voxel takes
 * P <- 0.5 (P + (S - P) / 26), S the sum of the 3x3x3 block around it (outside the grid counts
 * 0), summed as ((x-1 + x) + x+1) along x, then the same along y, then along z, and / 26 taken
 * as x OBS_PROX_INV26; occupied voxels keep 1. Double-buffered (every voxel reads the previous
 * iteration). Returns 0 or a negative code. */
typedef int (*obs_prox_flood_fn)(void *user, obs_prox_field *f, int threads, obs_err *err);
#define OBS_PROX_INV26 (1.0f / 26.0f)

/* The CPU flood (threaded); `user` unused. */
int obs_prox_flood_cpu(void *user, obs_prox_field *f, int threads, obs_err *err);

/* The propagation radius r_p of `sc` under `lay` (world units): `fraction` of the diagonal of
 * the reference box (lay->box) of the surface objects' world boxes in frame 0, each box from the
 * points its shape declares (a mesh file's box as imported at validation). */
double obs_prox_radius(const obs_scene *sc, const obs_prox_layout *lay);

/* Lays out, voxelises (exact triangle-box and sphere-box overlap with voxels grown by
 * OBS_PROX_VOXEL_MARGIN; threaded) and
 * floods (with `flood`, or the CPU's when NULL) every surface object of `sc` in frame 0's
 * placement. Messages name the scene. On failure `out` holds nothing. */
int obs_prox_build(const obs_scene *sc, const obs_prox_layout *lay, int threads,
                   obs_prox_flood_fn flood, void *flood_user, obs_prox_fields *out,
                   obs_err *err);
void obs_prox_fields_free(obs_prox_fields *fs);
/* Appends one object per field to `built` (a JSON array; obs_render_ctx.built): its object,
 * dims, occupied voxels, flood iterations and bytes (values and occupancy). */
void obs_prox_fields_built(const obs_prox_fields *fs, json_t *built);

/* Occupancy of one field from object-space triangles (3 floats per vertex) and the layout already
 * in `f` (dims, lo, voxel; occupied allocated and zeroed): for tests and the builder. */
void obs_prox_voxelise_mesh(obs_prox_field *f, const obs_mesh *m, int threads);
/* The same for a sphere (object-space centre and radius). */
void obs_prox_voxelise_sphere(obs_prox_field *f, const double c[3], double r, int threads);
/* Voxels are voxelised as boxes grown by this fraction of a voxel on every side: a surface
 * on a voxel face (a flat object centred in an even grid) touches both neighbours, and stays
 * touching them when rounding moves it by less than the margin (a translated scene). */
#define OBS_PROX_VOXEL_MARGIN 1e-3
/* The exact overlap of the triangle (a, b, c) with the closed box centre +- half (separating
 * axes, Akenine-Moeller 2001). */
int obs_prox_tri_box(const double centre[3], const double half[3], const double a[3],
                     const double b[3], const double c[3]);

/* The world -> grid map of field `f` for object `o` placed by its transform in `frame`:
 * g = m x (w, 1) in grid coordinates (voxel centres at +0.5). */
void obs_prox_world_to_grid(const obs_prox_field *f, const obs_object *o, int frame,
                            double m[3][4]);

/* Whether grid point g lies in the field's box [0, dims] (closed): where the walk reads, and
 * which fields a surface point lies in. */
static inline int obs_prox_inside(const obs_prox_field *f, const float g[3]) {
  return g[0] >= 0.0f && g[0] <= (float)f->dims[0] && g[1] >= 0.0f &&
         g[1] <= (float)f->dims[1] && g[2] >= 0.0f && g[2] <= (float)f->dims[2];
}

/* The field's trilinear value at grid point g (voxel centres at integer + 0.5), the point
 * inside the grid's box [0, dims]; near the faces the edge voxels' values extend. */
float obs_prox_sample(const obs_prox_field *f, const float g[3]);

/* Reconstruction of one field's occlusion at a surface point (docs/techniques/proximity_ao.md,
 * "Reconstruction"). */
enum { OBS_PROX_THESIS_CODE = 0, OBS_PROX_CORRECTED = 1 };
enum { OBS_PROX_ADDITIVE = 0, OBS_PROX_MULTIPLICATIVE = 1 };
#define OBS_PROX_MAX_STEPS 64
/* Disc points per step i: floor(i / 2); all steps: the sum of those. */
#define OBS_PROX_DISC_POINTS ((OBS_PROX_MAX_STEPS / 2) * (OBS_PROX_MAX_STEPS / 2 - 1) + \
                              (OBS_PROX_MAX_STEPS % 2) * (OBS_PROX_MAX_STEPS / 2))
typedef struct obs_prox_recon {
  int steps;          /* N */
  int mode;           /* OBS_PROX_THESIS_CODE or OBS_PROX_CORRECTED */
  float stop_value;   /* a step's value above this ends the walk (a surface reached) */
  float scale_before, scale_after;
  int isa;            /* simd.h level the reads run at (the same bits at every level) */
  /* The unit-disc points of step i start at disc[first[i]]: floor(i/2) of them, (x, y). */
  int first[OBS_PROX_MAX_STEPS + 1];
  float disc[OBS_PROX_DISC_POINTS][2];
  /* Per point, what every pixel shares: its distance along the step (in steps: i + 2 for the
   * thesis's code, i corrected) and its disc offset times the disc's radius in steps (i). Padded
   * to a multiple of 8 with zeros for the eight-lane reads. */
  float along[OBS_PROX_DISC_POINTS + 8], across_t[OBS_PROX_DISC_POINTS + 8],
      across_b[OBS_PROX_DISC_POINTS + 8];
} obs_prox_recon;

/* The disc points: step i's angles stratified over floor(i/2) sectors, radii sqrt(u), both
 * jittered from `seed` (the thesis's PerturbPoint is not given). Same for every pixel. Reads run
 * at the process's instruction-set level (obs_simd_isa). */
void obs_prox_recon_init(obs_prox_recon *r, int steps, int mode, float stop_value,
                         float scale_before, float scale_after, uint32_t seed);
/* The eight-lane walk's copy of field `f`: for voxel (x, y, z) the pair v(x, y, z),
 * v(x, min(y + 1, dy - 1), z) at float 2x + 2(dx + 1) y + 2(dx + 1) dy z, x and z padded with a
 * copy of their last voxel. One 16-byte read at (x, y, z) then holds the four x-y corners of a
 * trilinear read, clamped at the grid's faces as obs_prox_sample clamps them, and the other
 * slice's four sit one slice further: 8 bytes per voxel of the padded grid. Built over
 * `threads` for a walk `r` that reads eight points at a time; NULL where it reads one at a time
 * (below AVX2) or memory is short (the walk then reads `value`, with the same bits). Caller
 * frees. obs_prox_corners_count: its floats. */
size_t obs_prox_corners_count(const obs_prox_field *f);
float *obs_prox_corners(const obs_prox_field *f, const obs_prox_recon *r, int threads);

/* Occlusion in [0, scale_after] from field `f` at a point whose grid coordinates are `gp`, the
 * step R/N along the normal mapped into grid coordinates `gs`, and the disc axes of radius
 * R/N (two unit vectors orthogonal to the normal, times R/N, mapped) `gt`, `gb`. Point k of the
 * walk is read at (gp + along[k] gs) + across_t[k] gt + across_b[k] gb. `corners`:
 * obs_prox_corners of `f`, read eight points at a time where r->isa allows; NULL: read one by
 * one from f->value. Same bits either way. */
float obs_prox_occlusion(const obs_prox_field *f, const float *corners, const obs_prox_recon *r,
                         const float gp[3], const float gs[3], const float gt[3],
                         const float gb[3]);

#endif
