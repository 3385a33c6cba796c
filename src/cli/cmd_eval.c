/* cmd_eval.c - `prodygs eval`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int cmd_eval(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("eval: not implemented yet");
}
