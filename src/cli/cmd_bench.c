/* cmd_bench.c - `prodygs bench KIND ...`: dispatches to the benchmark of each stage. */
#include "cli/cli.h"

#include <string.h>

int bench_raster(int argc, char **argv);
int bench_proxy(int argc, char **argv);
int bench_iteration(int argc, char **argv);
int bench_deform(int argc, char **argv);
int bench_loss(int argc, char **argv);
int bench_flow(int argc, char **argv);

int cmd_bench(int argc, char **argv)
{
    if (argc < 2) return cli_usage_error("bench: usage: prodygs bench raster|proxy|iteration [options]");
    if (strcmp(argv[1], "raster") == 0) return bench_raster(argc - 1, argv + 1);
    if (strcmp(argv[1], "proxy") == 0) return bench_proxy(argc - 1, argv + 1);
    if (strcmp(argv[1], "iteration") == 0) return bench_iteration(argc - 1, argv + 1);
    if (strcmp(argv[1], "deform") == 0) return bench_deform(argc - 1, argv + 1);
    if (strcmp(argv[1], "loss") == 0) return bench_loss(argc - 1, argv + 1);
    if (strcmp(argv[1], "flow") == 0) return bench_flow(argc - 1, argv + 1);
    return cli_usage_error("bench: unknown benchmark '%s' (raster, proxy, iteration)", argv[1]);
}
