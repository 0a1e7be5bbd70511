/* The screen-space rule's cases (obs_screen_rule; docs/accuracy.md, "Screen-space radius"), run on
 * one backend by unit.test_ssao and unit.test_hbao, and by their Vulkan twins. */
#ifndef OBS_SCREEN_RULE_CASES_H
#define OBS_SCREEN_RULE_CASES_H

#include "obscura/obscura.h"

/* ssao on an open plane at radii from a few pixels down to 1e-12: no warning where the longest
 * offset reaches a pixel, the pixel warning (all covered pixels, the right smallest radius) below,
 * the depth warning as well below the depth precision. Prints "FAIL ..." lines; returns their
 * number. */
int obs_screen_rule_ssao_cases(obs_backend backend);

/* hbao on an open plane: no warning at a radius of a few pixels, the pixel warning with the share
 * of covered pixels where R projects under one texel (measured from the depth output) when that
 * is some or all of them, every such pixel 1, and the depth warning alone at a narrow field of
 * view where R is a pixel wide but within the depth precision. Returns the failures. */
int obs_screen_rule_hbao_cases(obs_backend backend);

#endif
