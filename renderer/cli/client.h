/* The obscura job-server client subcommands: `obscura submit`, `obscura jobs` and
 * `obscura compare` (libcurl). */
#ifndef OBSCURA_CLI_CLIENT_H
#define OBSCURA_CLI_CLIENT_H

#include <stdio.h>

/* `obscura submit SCENE.json [--server URL] ...` (argv[1] is "submit"). Returns the exit status:
 * 0 submitted (and, with --wait, succeeded), 2 bad input (local or a 4xx answer), 1 failure
 * (server unreachable, 5xx, job failed or cancelled, download failed). */
int cli_submit(int argc, char **argv);
/* `obscura jobs [--server URL] ...` (argv[1] is "jobs"). Same exit statuses. */
int cli_jobs(int argc, char **argv);
/* `obscura compare FILE ...` (argv[1] is "compare"): 0 when the comparison succeeded, 1 when it
 * failed (or the server could not be reached), 2 bad input. */
int cli_compare(int argc, char **argv);

#endif
