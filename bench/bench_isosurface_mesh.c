/* isosurface_mesh's extraction time per grid size on scenes/volume_head.json's data (VolPack's
 * MRI head, 128 x 128 x 84, the isovalue of the scene), on the CPU (one and two threads) and on
 * the Vulkan
 * device (lavapipe here: a CPU rasteriser, so its times are CPU times), next to ShaderX7 1.1's
 * Table 1.1.1 (a 256^3 head extracted on 32^3 and 64^3 grids). Both extractors give the same
 * mesh; the bench checks the counts. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_machine.h"
#include "isosurface.h"
#include "obscura/obscura.h"
#include "volume_scene.h"
#include "vk.h"
#include "../renderer/techniques/isosurface_mesh/isosurface_mesh.h"

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

int main(int argc, char **argv) {
  const char *path = argc > 1 ? argv[1] : OBS_SOURCE_DIR "/scenes/volume_head.json";
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  if (obs_scene_load_file(&sc, path, NULL, 0, &err)) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    return 1;
  }
  const obs_shape *s = &sc.objects[0].shape;
  obs_volume v;
  if (obs_scene_volume_read_shape(s, &v, &err)) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    return 1;
  }
  bench_print_machine();
  obs_vk *vk = NULL;
  obs_err verr = OBS_ERR_INIT;
  if (obs_vk_acquire(&vk, 0, &verr)) {
    printf("vulkan: none (%s)\n", obs_err_message(&verr));
    vk = NULL;
  } else {
    printf("vulkan: %s (device passes' time; wall time with uploads and readbacks)\n",
           obs_backend_ops_get(OBS_BACKEND_VULKAN)->device_name());
  }
  obs_err_free(&verr);
  printf("data: %s, %d x %d x %d samples, isovalue %.3g; CPU median of 5 runs (1 and 2 "
         "threads); Vulkan median of 3 (1 at grid 256), refine 0 and 1 only\n", path,
         v.n[0], v.n[1], v.n[2], s->volume.isovalue);
  printf("%-6s %-7s %14s %10s %10s %10s %10s %10s %14s %14s\n", "grid", "refine", "lattice",
         "triangles", "vertices", "CPU ms", "CPU2 ms", "Mtri/s", "Vulkan dev ms",
         "Vulkan wall ms");
  static const int grids[] = {32, 64, 128, 256};
  for (int r = 0; r <= OBS_ISO_REFINE_MAX; r++)
    for (size_t g = 0; g < sizeof grids / sizeof grids[0]; g++) {
      if (r > 1 && grids[g] > 128) continue; /* 27 samples a cell: seconds a run */
      double ms[5], ms2[5];
      obs_iso_mesh m, m2;
      memset(&m, 0, sizeof m);
      memset(&m2, 0, sizeof m2);
      for (int k = 0; k < 5; k++) {
        obs_iso_mesh_free(&m);
        obs_iso_mesh_free(&m2);
        double t0 = obs_now_ms();
        if (obs_iso_extract(&v, (float)s->volume.isovalue, grids[g], r, &m, &err)) {
          fprintf(stderr, "%s\n", obs_err_message(&err));
          return 1;
        }
        ms[k] = obs_now_ms() - t0;
        t0 = obs_now_ms();
        if (obs_iso_extract_threads(&v, (float)s->volume.isovalue, grids[g], r, 2, &m2, &err)) {
          fprintf(stderr, "%s\n", obs_err_message(&err));
          return 1;
        }
        ms2[k] = obs_now_ms() - t0;
        if (m2.ntris != m.ntris || m2.nverts != m.nverts ||
            memcmp(m2.idx, m.idx, 3 * m.ntris * sizeof *m.idx)) {
          fprintf(stderr, "two threads' mesh differs from one thread's\n");
          return 1;
        }
      }
      obs_iso_mesh_free(&m2);
      qsort(ms, 5, sizeof ms[0], cmp_double);
      qsort(ms2, 5, sizeof ms2[0], cmp_double);
      double dev[5] = {0}, wall[5] = {0};
      int runs = vk && r <= 1 ? (grids[g] >= 256 ? 1 : 3) : 0;
      for (int k = 0; k < runs; k++) {
        obs_iso_mesh d;
        double t0 = obs_now_ms();
        if (obs_isosurface_mesh_vk_extract(vk, &v, (float)s->volume.isovalue, grids[g], r, &d,
                                           &dev[k], &err)) {
          fprintf(stderr, "%s\n", obs_err_message(&err));
          return 1;
        }
        wall[k] = obs_now_ms() - t0;
        if (d.ntris != m.ntris || d.nverts != m.nverts) {
          fprintf(stderr, "the device's mesh differs from the CPU's\n");
          return 1;
        }
        obs_iso_mesh_free(&d);
      }
      qsort(dev, (size_t)runs, sizeof dev[0], cmp_double);
      qsort(wall, (size_t)runs, sizeof wall[0], cmp_double);
      char lat[32];
      snprintf(lat, sizeof lat, "%dx%dx%d", m.lat.c[0], m.lat.c[1], m.lat.c[2]);
      printf("%-6d %-7d %14s %10zu %10zu %10.1f %10.1f %10.2f %14.1f %14.1f\n", grids[g], r, lat,
             m.ntris, m.nverts, ms[2], ms2[2], m.ntris / ms[2] / 1e3, runs ? dev[runs / 2] : NAN,
             runs ? wall[runs / 2] : NAN);
      obs_iso_mesh_free(&m);
    }
  printf("ShaderX7 1.1, Table 1.1.1 (head, 256^3 data; times include rendering the surface):\n"
         "  64^3: GPU 6.3 ms (122K faces), CPU 66.8 ms (130K); 32^3: GPU 2 ms (26K), CPU 9.3 ms "
         "(27K)\n");
  if (vk) obs_vk_release(vk);
  obs_volume_free(&v);
  obs_scene_free(&sc);
  obs_err_free(&err);
  return 0;
}
