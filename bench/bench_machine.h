/* What the benchmarks print about the machine: the CPU model and the instruction set each kernel
 * runs under the current OBSCURA_ISA / OBSCURA_GATHER settings (renderer/core/simd.h), so a figure
 * can be matched to the path that produced it. */
#ifndef OBS_BENCH_MACHINE_H
#define OBS_BENCH_MACHINE_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/backend.h"
#include "raytrace.h"
#include "simd.h"

/* The CPU as its backend names it (the "model name" of /proc/cpuinfo, or "unknown"). */
static inline void bench_cpu_model(char *buf, size_t size) {
  snprintf(buf, size, "%s", obs_backend_ops_get(OBS_BACKEND_CPU)->device_name());
}

/* The path label used in goal lines, e.g. "level avx2: spans avx2/loads, Embree AVX2". */
static inline void bench_isa_label(char *buf, size_t size) {
  const int isa = obs_simd_isa();
  snprintf(buf, size, "level %s: spans %s%s, Embree %s", obs_simd_isa_name(isa),
           isa >= OBS_ISA_AVX2 ? "avx2" : "scalar",
           isa >= OBS_ISA_AVX2 ? (obs_simd_gather_loads() ? "/loads" : "/gathers") : "",
           obs_rt_embree_isa());
}

/* The Vulkan device's name, or NULL where there is none (lavapipe is a CPU rasteriser: its times
 * are CPU times, and the benchmarks say so). */
static inline const char *bench_vulkan_device(void) {
  const obs_backend_ops *vk = obs_backend_ops_get(OBS_BACKEND_VULKAN);
  return vk->available() ? vk->device_name() : NULL;
}

/* Two lines: the CPU and its best level, then what each kernel runs. */
static inline void bench_print_machine(void) {
  char cpu[256];
  bench_cpu_model(cpu, sizeof cpu);
  const char *cap = getenv("OBSCURA_ISA");
  const int isa = obs_simd_isa();
  printf("machine: %s; CPU level %s, OBSCURA_ISA=%s -> %s\n", cpu,
         obs_simd_isa_name(obs_simd_cpu_isa()), cap && *cap ? cap : "(unset: native)",
         obs_simd_isa_name(isa));
  char config[64];
  obs_rt_device_config(0, config, sizeof config);
  printf("kernels: tile loops %s; ssao/hbao spans %s%s; Embree %s kernels (rtcNewDevice \"%s\")\n",
         isa >= OBS_ISA_AVX2 ? "x86-64-v3" : "x86-64 baseline",
         isa >= OBS_ISA_AVX2 ? "avx2 (8 lanes)" : "scalar",
         isa < OBS_ISA_AVX2        ? ""
         : obs_simd_gather_loads() ? ", table lookups as scalar loads"
                                   : ", table lookups by vgatherdps",
         obs_rt_embree_isa(), config);
}

#endif
