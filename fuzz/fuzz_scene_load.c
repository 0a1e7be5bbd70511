/* libFuzzer target: the scene loader (obs_scene_load_string) on arbitrary bytes, with the bundled
 * scenes directory as the base that mesh paths resolve against. A load either succeeds with a
 * complete scene or fails with at least one problem naming the document; anything else (a crash,
 * a sanitizer report, a leak, a failure without a message) is a finding. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/obscura.h"

static const char *scenes_dir(void) {
  const char *env = getenv("OBS_FUZZ_SCENES");
  return env && *env ? env : OBS_SOURCE_DIR "/scenes";
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char *text = malloc(size + 1);
  if (!text) return 0;
  memcpy(text, data, size);
  text[size] = '\0';
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, text, "fuzz.json", scenes_dir(), NULL, 0, &err);
  if (rc == 0) {
    if (!sc.technique || !sc.doc || !sc.params || sc.width < 1 || sc.height < 1 || sc.spp < 1 ||
        (sc.nobjects && !sc.objects)) {
      fprintf(stderr, "fuzz_scene_load: accepted an incomplete scene\n");
      abort();
    }
    obs_scene_free(&sc);
  } else {
    const char *msg = obs_err_message(&err);
    if (rc > 0 || err.count < 1 || strncmp(msg, "fuzz.json", 9)) {
      fprintf(stderr, "fuzz_scene_load: failure %d without a problem naming the document: %s\n",
              rc, msg);
      abort();
    }
  }
  obs_err_free(&err);
  free(text);
  return 0;
}
