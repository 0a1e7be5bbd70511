/* Helpers shared by the cmocka unit tests: temp dirs, scene loading from inline JSON, rendering. */
#ifndef OBS_TESTUTIL_H
#define OBS_TESTUTIL_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "obscura/obscura.h"

/* Numerical checks (bits across thread counts, scale invariance, statistical calibration) repeat
 * in a sanitizer build the code paths the plain checks run there, and what they assert is shown
 * by the release build: under OBS_TEST_SANITIZED=1 (tests/CMakeLists.txt sets it for the
 * sanitizer builds) this skips the calling cmocka test, with its reason. */
void obs_test_numeric_only(void);
/* Whether this is a sanitizer build's run (OBS_TEST_SANITIZED=1). */
int obs_test_sanitized(void);
/* 1 in an instruction-set variant (OBS_TEST_ISA_VARIANT=1, a level below this CPU's own). */
int obs_test_isa_variant(void);

/* A fresh directory under $OBS_TMP (or /tmp) for this test; returned string is static per call
 * site until the next call. */
const char *obs_test_tmpdir(const char *tag);
/* DIR/NAME (static buffer, overwritten by the next call). */
const char *obs_test_path(const char *dir, const char *name);
/* Whether anything exists at `path`. */
int obs_test_file_exists(const char *path);
/* The next value of a xorshift32 sequence whose state is *s (nonzero). */
uint32_t obs_test_rand(uint32_t *s);
/* The next value of that sequence as a double in [0, 1) (24 bits). */
static inline double obs_test_unit(uint32_t *s) { return (obs_test_rand(s) >> 8) * 0x1p-24; }
/* Path of a file in the source tree (static buffer, overwritten by the next call). */
const char *obs_test_src(const char *rel);
/* Loads `json` as the document `name` into `sc` (asserting success; the loader's message is
 * printed when it fails). The caller frees `sc`. */
void obs_test_load(const char *json, const char *name, obs_scene *sc);
/* Loads `json` (asserting success) and renders it with `threads` threads (asserting success). */
void obs_test_render(const char *json, int threads, obs_result *res);
/* The channels of technique t's primary output in `img` (at most 3) and the range its values must
 * lie in: [0, 1] for an OBS_OUTPUT_UNIT output, [0, inf) for RGB radiance, otherwise any finite
 * value. Returns how many channels `img` has of it (0: none). */
int obs_test_primary_channels(const obs_technique *t, const obs_image *img, const float *ch[3],
                              double *lo, double *hi);
/* printf into a static buffer (overwritten by the next call): scene documents in tests. */
const char *obs_test_fmt(const char *f, ...) __attribute__((format(printf, 1, 2)));
/* Every channel of `img` finite and technique t's primary output in its declared range; prints
 * one "FAIL <what>: ..." line per problem and returns their number. */
int obs_test_check_sane(const char *what, const obs_technique *t, const obs_image *img);
/* Asserts every value of every channel is finite. */
void obs_test_assert_finite(const obs_image *img);
/* Asserts that `part` (a render of region r) holds `whole`'s bits inside r, channel by channel,
 * and 0 outside it. */
void obs_test_assert_region(const obs_image *whole, const obs_image *part, obs_region r);

/* The members of a ball object of radius r at (x, y, z) for technique t, into buf: an analytic
 * sphere, or for a technique that renders volumes a procedural sphere volume of that size. */
/* The material members (",\"material\":{...}") of a test object for technique t: grey, and
 * filled with the marble preset for techniques that scatter inside media (OBS_NEED_MEDIUM). */
const char *obs_test_medium_material(const obs_technique *t);
/* A directional light (",{...}", to follow another light in a list) for techniques that scatter
 * inside media, which light with punctual lights only; "" for the others. */
const char *obs_test_punctual_light(const obs_technique *t);
void obs_test_ball(const obs_technique *t, double x, double y, double z, double r, char *buf,
                   size_t n);

#endif
