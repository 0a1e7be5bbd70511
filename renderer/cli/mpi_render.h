/* `obscura render` split in tiles across the ranks mpirun started (docs/mpi.md). Only
 * mpi_render.c sees MPI: the rest of the CLI, and the renderer, stay MPI-free. */
#ifndef OBSCURA_CLI_MPI_RENDER_H
#define OBSCURA_CLI_MPI_RENDER_H

#include "args.h"
#include "obscura/obscura.h"

/* One process's part in the MPI job; opaque. */
typedef struct cli_mpi cli_mpi;

/* The ranks mpirun started this process among and its own, from the environment Open MPI sets
 * (OMPI_COMM_WORLD_SIZE, OMPI_COMM_WORLD_RANK): 1 and 0 when not started by mpirun. MPI is not
 * touched, so a plain run never initialises it. */
int cli_mpi_env_size(void);
int cli_mpi_env_rank(void);

/* Initialises MPI (threads: MPI_THREAD_MULTIPLE asked, MPI_THREAD_SERIALIZED enough) and sets
 * *out (free with cli_mpi_finish). On failure *out is NULL and MPI is finalised. */
int cli_mpi_init(cli_mpi **out, obs_err *err);
int cli_mpi_rank(const cli_mpi *m);
/* Render threads per rank when --threads is not given: the cores this process may run on (mpirun
 * binds each rank to its share), not every core of the machine. */
int cli_mpi_threads(void);

/* Whether rank 0's progress bar has a terminal to go to: mpirun's stderr, where it forwards the
 * ranks' (Open MPI gives a rank a pipe for stderr, and a pseudo-terminal for stdout whatever
 * mpirun's own are). Asked of the parent process, mpirun itself on mpirun's node (Linux /proc);
 * 0 elsewhere. */
int cli_mpi_tty(void);

/* Collective, after each rank loaded the scene: `code` is this rank's exit code for its load (0:
 * loaded; `err` holds why not). Prints this rank's problems when they are news (rank 0's always,
 * a worker's when rank 0 loaded) and returns the code every rank exits with (0: all loaded). */
int cli_mpi_loaded(cli_mpi *m, int code, const obs_err *err);

/* Collective: renders the scene, the image split in tiles across the ranks when the technique
 * renders per pixel, else by rank 0 alone (with a warning in the result). With opts->brick.count
 * above 0 (`--distribute data`) it is split by data instead: rank r renders brick r of size of
 * the volumes over the whole image (opts->brick.no_ghost kept) and rank 0 composites every rank's
 * image front to back by depth (mpi_composite.h); a failure to render a brick (a technique
 * without volumes) is reported by rank 0 and returned on every rank. Returns 0 with the whole
 * result in `res` on rank 0 (ranks and rays over every rank) and an empty `res` on the others.
 * Before any rank renders it may fail as obs_render would: on rank 0 with the problem in `err`, on
 * the others with `err` empty (rank 0 reports it). A failure once rendering started ends the
 * whole job (MPI_Abort) after printing it, so no rank waits for another forever. `pr` is rank 0's
 * progress bar (may be NULL). */
int cli_mpi_render(cli_mpi *m, obs_scene *sc, const obs_render_opts *opts, cli_progress *pr,
                   obs_result *res, obs_err *err);

/* Finalises MPI and frees `m` (NULL: nothing). */
void cli_mpi_finish(cli_mpi *m);

#endif
