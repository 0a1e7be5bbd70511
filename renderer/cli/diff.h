/* The image-comparison subcommands: obscura diff and obscura metrics (diff.c). */
#ifndef OBSCURA_CLI_DIFF_H
#define OBSCURA_CLI_DIFF_H

int cli_diff(int argc, char **argv);
int cli_metrics(int argc, char **argv);

#endif
