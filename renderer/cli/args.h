/* Helpers shared by the obscura subcommands: scene options, scene loading, progress bar. */
#ifndef OBSCURA_CLI_ARGS_H
#define OBSCURA_CLI_ARGS_H

#include <stdio.h>

#include "obscura/obscura.h"

#define EXIT_BAD_INPUT 2
#define CLI_MAX_OVERRIDES 64

/* The scene file and what changes it before validation. `ov[i].pointer` and `ov[i].value` (JSON
 * text: a bare --set word arrives quoted) are owned; the other strings borrow argv. Zero it before use; free with
 * cli_scene_opts_free (also valid on a zeroed struct). */
typedef struct cli_scene_opts {
  const char *scene, *technique, *backend;
  const char *base_dir; /* --base-dir: where the scene's relative files resolve (NULL: its own
                         * directory) */
  obs_override ov[CLI_MAX_OVERRIDES];
  size_t nov;
} cli_scene_opts;

/* Takes argv[*i] when it is --technique, --backend, --set or --base-dir with its value (advancing
 * *i past the value). Returns 1 when taken, 0 when argv[*i] is none of them, -1 after printing
 * what is wrong. */
int cli_scene_option(cli_scene_opts *o, int argc, char **argv, int *i);
/* The value following option argv[*i] (advancing *i), or NULL after printing "needs a value". */
const char *cli_option_value(int argc, char **argv, int *i);
void cli_scene_opts_free(cli_scene_opts *o);

/* Loads and validates the scene with --technique/--backend folded into the document before
 * validation (so their problems are reported like any other) and the --set overrides applied.
 * Returns 0 or an OBS_E* code with the problems in `err`. */
int cli_scene_load(const cli_scene_opts *o, obs_scene *sc, obs_err *err);

/* Prints the usage of subcommand `cmd`, or of all of them when `cmd` is NULL. Returns 0, or -1
 * (printing nothing) for an unknown subcommand. */
int cli_usage(FILE *f, const char *cmd);
/* After a specific mistake in `cmd`'s arguments (already printed), one line saying where its
 * options are (`obscura help CMD`); with NULL, where the commands are. */
void cli_hint(const char *cmd);
/* Whether the subcommand's arguments (argv[2..]) ask for help (--help or -h). */
int cli_wants_help(int argc, char **argv);

/* Exit status for a failed load: 2 for bad input or an unreadable file, 1 otherwise. */
int cli_load_exit_code(int rc);

/* A one-line progress bar on a terminal: draws "\r[####    ]  42%" on `f` when the whole percent
 * changes; and, for a program that watches the render (obscurad's MPI jobs), the fraction done
 * as text ("0.4213\n", rewritten in place) in file descriptor `fd` when its ten-thousandth
 * changes. */
typedef struct cli_progress {
  int tty;  /* draw only when set */
  int last; /* last percent drawn; start at -1 */
  FILE *f;  /* NULL: stderr */
  int fd;   /* --progress-file, or -1 (a zeroed struct writes nothing: fd 0 is never used) */
  int last_file; /* last ten-thousandth written; start at -1 */
} cli_progress;
/* Opens --progress-file `path` into p->fd (created or truncated, 0 written); -1 after printing
 * why not. */
int cli_progress_file(cli_progress *p, const char *path);
void cli_progress_draw(void *user, double fraction); /* an obs_progress_fn */

#endif
