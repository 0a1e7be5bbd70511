/* The CPU backend's operations table: always available; its device is the host CPU as
 * /proc/cpuinfo names it; its G-buffer is obs_gbuffer_cpu's. */
#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "obscura/backend.h"
#include "driver.h"

/* What the CPU builds for a technique's needs (needs.c). */
extern const obs_needs_builder obs_cpu_needs_builder;

static int cpu_available(void) { return 1; }

static char model[256];
static pthread_once_t model_once = PTHREAD_ONCE_INIT;

static void read_model(void) {
  snprintf(model, sizeof model, "unknown");
  FILE *f = fopen("/proc/cpuinfo", "r");
  if (!f) return;
  char line[512];
  while (fgets(line, sizeof line, f)) {
    if (strncmp(line, "model name", 10)) continue;
    char *v = strchr(line, ':');
    if (!v) break;
    v++;
    while (*v == ' ' || *v == '\t') v++;
    size_t len = strcspn(v, "\r\n");
    if (len) snprintf(model, sizeof model, "%.*s", (int)len, v);
    break;
  }
  fclose(f);
}

static const char *cpu_device_name(void) {
  pthread_once(&model_once, read_model);
  return model;
}

static const char *cpu_device_kind(void) { return "cpu"; }

const obs_backend_ops obs_backend_cpu_ops = {
    .id = OBS_BACKEND_CPU,
    .name = "cpu",
    .available = cpu_available,
    .device_name = cpu_device_name,
    .device_kind = cpu_device_kind,
    .gbuffer = obs_gbuffer_cpu,
    .needs = &obs_cpu_needs_builder,
    .volume_sides = 1,
};
