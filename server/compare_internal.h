/* What the comparison files share (compare_expand.c, compare_post.c, compare_get.c,
 * compare_metrics.c, compare_output.c): the expanded candidates and references of a request. Private to them. */
#ifndef SRV_COMPARE_INTERNAL_H
#define SRV_COMPARE_INTERNAL_H

#include <jansson.h>
#include <math.h>

#include "json_util.h"
#include "obscurad.h"

#define API "/api/v1"

/* JSON cannot carry NaN or infinities: such a number is shown as null. */
static inline json_t *num_or_null(double v) { return isfinite(v) ? json_real(v) : json_null(); }

/* One expanded candidate. */
typedef struct cand {
  int entry;              /* index into the request's candidates */
  const obs_technique *t;
  obs_backend backend;
  int backend_pos;        /* index in the entry's backend list, -1 when a single string */
  json_t *params;         /* this combination's parameter values (owned) */
  json_t *pos;            /* key -> index in that parameter's list (owned; only listed keys) */
  const char *against;    /* the entry's "against" (a reference technique), or NULL; borrowed */
  /* Filled once validated: */
  char *doc, *params_full, *ref_key;
  int width, height, spp;
  double work;
  obs_response response;
  int ref;                /* index into the references */
} cand;

typedef struct ref_job {
  const char *technique; /* the reference technique (a registry name) */
  char *doc, *key; /* key: the reference's params, canonical JSON */
  int width, height, spp;
  double work;
  obs_backend backend;
} ref_job;

typedef struct expansion {
  cand *c;
  int n, cap;
  ref_job *refs;
  int nrefs;
} expansion;

void srv_compare_expansion_free(expansion *x);
/* Reads the candidate entries into the expansion (structure only: values are checked later by
 * the renderer's own validation, once per combination). */
void srv_compare_expand(srv_app *app, obs_jpath *p, const json_t *cands, expansion *x);

#endif
