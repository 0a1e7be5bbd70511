/* The obscura job-server client subcommands: `obscura submit`, `jobs`, `job`, `cancel`, `fetch`,
 * `comparisons` and `compare` (libcurl). */
#ifndef OBSCURA_CLI_CLIENT_H
#define OBSCURA_CLI_CLIENT_H

#include <stdio.h>

/* `obscura submit SCENE.json [--server URL] ...` (argv[1] is "submit"). Returns the exit status:
 * 0 submitted (and, with --wait, succeeded), 2 bad input (local or a 4xx answer), 1 failure
 * (server unreachable, 5xx, job failed or cancelled, download failed). */
int cli_submit(int argc, char **argv);
/* `obscura jobs [--server URL] ...` (argv[1] is "jobs"). Same exit statuses. */
int cli_jobs(int argc, char **argv);
/* `obscura job ID`, `obscura cancel ID`, `obscura fetch ID -o DIR` and `obscura comparisons`
 * (jobcmds.c): one job shown, cancelled or downloaded, the comparisons listed. Same exit
 * statuses; a job that does not exist (404) or has already ended (cancel: 409) is bad input. */
int cli_job(int argc, char **argv);
int cli_cancel(int argc, char **argv);
int cli_fetch(int argc, char **argv);
int cli_comparisons(int argc, char **argv);
/* `obscura compare FILE ...` (argv[1] is "compare"): 0 when the comparison succeeded, 1 when it
 * failed (or the server could not be reached), 2 bad input. */
int cli_compare(int argc, char **argv);

#endif
