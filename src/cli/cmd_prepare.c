/* cmd_prepare.c - `prodygs prepare`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int cmd_prepare(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("prepare: not implemented yet");
}
