/* cmd_run.c - `prodygs run`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int cmd_run(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("run: not implemented yet");
}
