/* cmd_info.c - `prodygs info`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int cmd_info(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("info: not implemented yet");
}
