/* bench_proxy.c - `prodygs bench proxy`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int bench_proxy(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("bench proxy: not implemented yet");
}
