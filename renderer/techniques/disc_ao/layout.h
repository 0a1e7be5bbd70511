/* disc_ao's push-constant block and bindings, declared once for vulkan.c and the shaders
 * disc_ao.vert.glsl, disc_ao.geom.glsl and disc_ao.frag.glsl (renderer/core/layout_glsl.h). One
 * block serves the geometry and fragment stages. */
#ifndef OBS_DISC_AO_LAYOUT_H
#define OBS_DISC_AO_LAYOUT_H

#include "layout_glsl.h"

/* flags */
#define OBS_DISC_FLAG_ORTHO 1   /* orthographic camera */
#define OBS_DISC_FLAG_PYRAMID 2 /* proxy pyramid instead of quad */
#define OBS_DISC_FLAG_BACK 4    /* discs occlude the receivers behind them (the listing) */
/* Storage images the fragment shader reads: the G-buffer's depth and normal. */
#define OBS_DISC_B_DEPTH 0
#define OBS_DISC_B_NORMAL 1
#define OBS_DISC_BINDINGS 2
/* The proxies' margin over the influence radius, so rounding in the projection never leaves
 * out a receiver the CPU twin reaches. */
#define OBS_DISC_PROXY_MARGIN 1.001

OBS_PUSH_BEGIN(obs_disc_ao_push)
  OBS_I32 width; OBS_I32 height;
  OBS_I32 flags; /* OBS_DISC_FLAG_* */
  OBS_F32 half_w; OBS_F32 half_h; /* the G-buffer's projection (gbuffer.h) */
OBS_PUSH_END(obs_disc_ao_push)
OBS_PUSH_CHECK(obs_disc_ao_push)

#endif
