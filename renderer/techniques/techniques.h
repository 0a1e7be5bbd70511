/* What the technique folders share: the descriptors (each may name another as its reference),
 * the screen-space outputs and the obscurance model's parameter entries. */
#ifndef OBS_TECHNIQUES_H
#define OBS_TECHNIQUES_H

#include "driver.h"
#include "obscura/backend.h"
#include "obscura/technique.h"

/* Every registered descriptor (generated from the folders; each folder's own header declares its
 * run functions). */
#include "technique_list.h"

/* The outputs the screen-space drivers write (obs_screen_outputs), declared by every screen-space
 * technique alike. */
#include "gbuffer.h"

/* The obscurance model's parameters (core/obscurance.h), the same in every obscurance technique
 * (per pixel, per patch): entries for d_max (a length), falloff, tau and color_bleeding, landing in
 * the members of those names through P(member) (offsetof in the technique's params struct). */
/* The obscurance techniques' W without colour bleeding against rt_ao with the same falloff (a
 * comparison candidate's "against": "rt_ao"): the same quantity, W = (1/pi) int rho cos. */
extern const obs_reference_alt obs_obscurance_w_alts[];

#define OBS_OBSCURANCE_MODEL_PARAMS(P)                                                           \
  {.name = "d_max", .type = OBS_PARAM_DOUBLE, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,        \
   .max = 1e30, .def = 1,                                                                        \
   .description = "distance d_max of the falloff in scene units: surfaces farther away do not "  \
                  "obscure (they count as open)",                                                \
   .offset = P(d_max), .size_default = 0.2},                                                     \
      {.name = "falloff", .type = OBS_PARAM_ENUM, .choices = obs_falloff_names,                  \
       .def = OBS_FALLOFF_SQRT,                                                                  \
       .description = "obscurance function rho(d): sqrt = sqrt(d/d_max) (the article's), exp = " \
                      "1-exp(-tau d) within d_max, binary = 0 within d_max (ambient occlusion)", \
       .offset = P(falloff)},                                                                    \
      {.name = "tau", .type = OBS_PARAM_DOUBLE, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,      \
       .max = 1e30, .def = 1, .description = "decay rate of the exp falloff, per scene unit",    \
       .offset = P(tau)},                                                                        \
      {.name = "color_bleeding", .type = OBS_PARAM_BOOL, .def = 1,                               \
       .description = "weigh each direction by the reflectivity R(Q) of the surface it meets "   \
                      "within d_max (R_ave when none): W becomes RGB; false: W alone, the same " \
                      "in every channel",                                                        \
       .offset = P(color_bleeding)}

#endif
