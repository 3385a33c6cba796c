/* bench_raster.c - `prodygs bench raster`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int bench_raster(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("bench raster: not implemented yet");
}
