/* bench_iteration.c - `prodygs bench iteration`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int bench_iteration(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("bench iteration: not implemented yet");
}
