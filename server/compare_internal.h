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
  /* Further measurements of the candidate's job (srv_new_measure): against the common reference
   * (-1: none, or not the quantity the candidate estimates), and each other output its technique
   * declares a reference for (obs_reference_alt), with that reference. */
  int common_ref;
  char *common_key;
  int alt_ref[8], nalt;
  char *alt_key[8];
  const char *alt_output[8]; /* a compared_outputs pair's output; NULL for reference_alts */
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
  int common; /* the common reference's index in refs, -1: none asked for */
} expansion;

/* What defines a reference (compare_refs.c): the values of its technique's reference keys in its
 * params (a new object). */
json_t *srv_compare_definition(const char *technique, const json_t *params);
/* A reference's label from its technique, definition and response ("rt_ao: weighting cosine,
 * falloff binary, ...; mapped through ssao_hemi"); malloc'ed, NULL when out of memory. */
char *srv_compare_label(const char *technique, const json_t *definition, const char *response);
/* Ranks n candidates within groups of one reference: group[i] names candidate i's reference
 * (NULL: none, it takes no part), metrics[i] its metrics object, pts[i] its place on the
 * time/error plane; each holder[i] gets "pareto". Returns the groups ([{reference, candidates,
 * pareto, ranking}]) with *pareto (every group's optimal candidates by ascending time) and
 * *ranking (one group's, or all groups' merged). */
json_t *srv_compare_rank(json_t *const *holder, json_t *const *metrics, const char *const *group,
                         const obs_pareto_point *pts, size_t n, json_t **pareto, json_t **ranking);

void srv_compare_expansion_free(expansion *x);
/* Reads the candidate entries into the expansion (structure only: values are checked later by
 * the renderer's own validation, once per combination). */
void srv_compare_expand(srv_app *app, obs_jpath *p, const json_t *cands, expansion *x);

#endif
