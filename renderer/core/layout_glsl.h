/* The few macros that let one header declare a parameter block for C and for GLSL at once: a
 * technique's layout.h (renderer/techniques/<name>/layout.h) is included by its C files and by
 * its shaders (glslc -I renderer/core), so a push-constant block, its binding numbers and its
 * limits are written once and cannot drift apart by position.
 *
 * A block is declared as
 *
 *   OBS_PUSH_BEGIN(obs_example_push)
 *     OBS_I32 width; OBS_I32 height;
 *     OBS_F32 radius;
 *     OBS_F32 weights[OBS_EXAMPLE_MAX];
 *   OBS_PUSH_END(obs_example_push)
 *
 * which C reads as `typedef struct obs_example_push {...} obs_example_push;` and GLSL as
 * `layout(push_constant) uniform obs_example_push_block {...} pc;`. Only 32-bit scalars and arrays
 * of them: push constants use std430, where those need 4-byte alignment and no padding in either
 * language (vec3/vec4 members would not). Keep a block within 128 bytes, the smallest push-constant
 * size Vulkan guarantees (OBS_PUSH_CHECK asserts it in C). */
#ifndef OBS_LAYOUT_GLSL_H
#define OBS_LAYOUT_GLSL_H

#ifdef VULKAN
#define OBS_I32 int
#define OBS_U32 uint
#define OBS_F32 float
#define OBS_PUSH_BEGIN(T) layout(push_constant) uniform T##_block {
#define OBS_PUSH_END(T) \
  }                     \
  pc;
#define OBS_PUSH_CHECK(T)
#else
#include <stdint.h>
#define OBS_I32 int32_t
#define OBS_U32 uint32_t
#define OBS_F32 float
#define OBS_PUSH_BEGIN(T) typedef struct T {
#define OBS_PUSH_END(T) \
  }                     \
  T;
#define OBS_PUSH_CHECK(T) \
  _Static_assert(sizeof(T) <= 128, #T " exceeds the 128 push-constant bytes Vulkan guarantees");
#endif

#endif
