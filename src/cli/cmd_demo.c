/* cmd_demo.c - `prodygs demo`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int cmd_demo(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("demo: not implemented yet");
}
