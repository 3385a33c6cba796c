/* cmd_render.c - `prodygs render`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int cmd_render(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("render: not implemented yet");
}
