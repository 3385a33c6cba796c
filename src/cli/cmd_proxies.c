/* cmd_proxies.c - `prodygs proxies`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int cmd_proxies(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("proxies: not implemented yet");
}
