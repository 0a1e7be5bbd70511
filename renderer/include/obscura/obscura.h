/* Umbrella header for the obscura renderer's public C API. */
#ifndef OBSCURA_H
#define OBSCURA_H

#include "obscura/backend.h"
#include "obscura/error.h"
#include "obscura/image.h"
#include "obscura/metric_table.h"
#include "obscura/metrics.h"
#include "obscura/path.h"
#include "obscura/patches.h"
#include "obscura/render.h"
#include "obscura/scene.h"
#include "obscura/technique.h"

#define OBSCURA_VERSION "0.1.0"

#endif
