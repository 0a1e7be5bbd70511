/* The usage texts of the obscura subcommands: `obscura --help` prints them all, `obscura CMD
 * --help` (or `obscura help CMD`) prints CMD's own, and a mistake in CMD's arguments is followed
 * by one line saying so (cli_hint), not by the whole text. */
#include <stdio.h>
#include <string.h>

#include "args.h"
#include "http.h"

typedef struct usage {
  const char *cmd, *synopsis, *help;
} usage;

static const usage usages[] = {
    {"render",
     "  obscura render SCENE.json [-o DIR] [--technique NAME] [--backend cpu|vulkan|auto]\n"
     "                 [--set /json/pointer=VALUE]... [--threads N] [--quiet]\n"
     "                 [--distribute image|data [--no-ghost]] [--base-dir DIR]\n"
     "                 [--progress-file FILE]\n",
     "Renders the scene here and writes its outputs, summary.json and PNGs into DIR (default "
     "out;\nwithout -o it refuses to replace another scene's outputs there: -o out replaces them).\n"
     "--technique keeps the document's params for its own technique; another starts from its\n"
     "defaults with lengths fitted to the scene's size (a note says which); --set wins.\n"
     "Under mpirun the image is split in tiles across the ranks and rank 0 writes DIR, the same\n"
     "files bit for bit; --threads is per rank (docs/mpi.md). --distribute data splits the\n"
     "volumes instead (volume techniques, cpu backend): each rank reads and renders one brick of\n"
     "them with a ghost zone as wide as the AO distance (none with --no-ghost, to see why it is\n"
     "there) and rank 0 composites the images front to back by depth.\n"
     "--base-dir resolves the scene's relative files (volumes, environment maps, meshes) against\n"
     "DIR instead of the document's directory; --progress-file keeps the fraction done in FILE\n"
     "(\"0.4213\", rewritten in place) for a program that watches the render.\n"},
    {"validate",
     "  obscura validate SCENE.json [--technique NAME] [--set /json/pointer=VALUE]...\n"
     "                 [--base-dir DIR]\n",
     "Checks the scene as render would, without rendering.\n"},
    {"techniques", "  obscura techniques [--markdown | --schema | --openapi | --docs NAME]\n",
     "The registry as JSON, or texts generated from it: the guaranteed-range table, the technique\n"
     "part of scene.schema.json, the OpenAPI block, the parameter table of\n"
     "docs/techniques/NAME.md.\n"},
    {"submit",
     "  obscura submit SCENE.json [--server URL] [--technique NAME] [--backend cpu|vulkan|auto]\n"
     "                 [--set /json/pointer=VALUE]... [--priority N] [--label TEXT] [--wait]\n"
     "                 [-o DIR] [--budget MS]\n",
     "Validates the scene here, sends it to obscurad and prints the job's dashboard page.\n"
     "--wait follows the job to its end; -o DIR (implies --wait) downloads its outputs.\n"
     "--budget MS sends technique auto with time_budget_ms: the server picks, from its measured\n"
     "comparisons of the bundled scene of this file's name (at this image size), the most\n"
     "accurate configuration whose median time fits MS, and the CLI prints the pick.\n"},
    {"jobs",
     "  obscura jobs [--server URL] [--state S] [--technique T] [--backend B] [--limit N]\n"
     "                 [--after ID] [--all] [--json]\n",
     "Lists the newest jobs (default 50) with their scene and render time. --after ID starts\n"
     "below job ID (the \"next\" a listing ends with); --all follows every page to the oldest.\n"},
    {"job", "  obscura job ID [--server URL] [--json]\n",
     "One job: its state, technique, scene, image, timings, the mean of its primary output,\n"
     "warnings, error and outputs; --json prints it as the API gives it.\n"},
    {"cancel", "  obscura cancel ID [--server URL]\n",
     "Cancels a queued or running job (a running render stops between tiles); exit 2 when the\n"
     "job has already ended.\n"},
    {"fetch", "  obscura fetch ID -o DIR [--server URL]\n",
     "Downloads every output of a succeeded job into DIR (created when missing).\n"},
    {"comparisons", "  obscura comparisons [--server URL] [--limit N] [--json]\n",
     "Lists the newest comparisons (default 50): state, candidates done, scene, label.\n"},
    {"compare", "  obscura compare FILE|- [--server URL] [--no-wait] [--json]\n",
     "Sends the comparison request in FILE (JSON, schema/openapi.yaml ComparisonRequest; - reads\n"
     "standard input), prints its dashboard page and follows it to its end: per candidate the\n"
     "median time and the error against the reference, then the Pareto set. --json prints the\n"
     "finished comparison as the API gives it. Exit 0 when it succeeded, 1 when it failed.\n"},
    {"diff",
     "  obscura diff A B [--channel NAME] [--mask CHANNEL|none] [--ppd N] [--json] [-o DIR]\n",
     "Every metric of the table (obscura metrics) for A against the reference B: two EXR files\n"
     "or two output folders (their primary EXR, from summary.json). --channel: a scalar channel,\n"
     "an RGB output (radiance for radiance.R/G/B) or directions (bent_normal); default the output\n"
     "a comparison of the folders' techniques compares, else ao. --mask: pixels where B's\n"
     "channel > 0 (default alpha when B has it). --ppd: FLIP's pixels per degree (67). -o DIR\n"
     "writes error.exr/png (A - B) and flip.exr/png. Exit 0, 2 for bad input.\n"},
    {"metrics", "  obscura metrics [--json | --markdown | --openapi]\n",
     "The metric table: name, label, unit, which way is better, range, what it needs, definition\n"
     "(JSON), or the copies generated from it (docs/metrics.md's table, OpenAPI's Metrics).\n"},
};

static void common(FILE *f) {
  fputs(
      "VALUE is JSON (a number, true, false, null, \"text\", [..], {..}) or else a bare word,\n"
      "taken as a string: --set /technique/params/samples=256 --set\n"
      "/technique/params/falloff=sqrt. Quote what must stay a string but reads as JSON:\n"
      "--set '/objects/0/name=\"8\"'.\n"
      "The client commands (submit, jobs, job, cancel, fetch, comparisons, compare) talk to\n"
      "--server, else $OBSCURA_SERVER, else " CLI_DEFAULT_SERVER
      " (scripts/run), sending\n$OBSCURA_TOKEN as a bearer token when set.\n"
      "Exit codes: 0 ok, 2 bad input, 1 failure.\n",
      f);
}

int cli_usage(FILE *f, const char *cmd) {
  size_t n = sizeof usages / sizeof usages[0];
  for (size_t i = 0; cmd && i < n; i++) {
    if (strcmp(usages[i].cmd, cmd)) continue;
    fprintf(f, "usage:\n%s\n%s", usages[i].synopsis, usages[i].help);
    common(f);
    return 0;
  }
  if (cmd) return -1;
  fputs("usage:\n", f);
  for (size_t i = 0; i < n; i++) fputs(usages[i].synopsis, f);
  fputs("  obscura help [CMD]  (or obscura CMD --help)\n  obscura --version\n", f);
  common(f);
  return 0;
}

void cli_hint(const char *cmd) {
  if (cmd)
    fprintf(stderr, "obscura: 'obscura help %s' shows its options\n", cmd);
  else
    fprintf(stderr, "obscura: 'obscura help' lists the commands\n");
}

int cli_wants_help(int argc, char **argv) {
  for (int i = 2; i < argc; i++)
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) return 1;
  return 0;
}
