/* cmd_train.c - `prodygs train`: not implemented yet (see the open issues). */
#include "cli/cli.h"

int cmd_train(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_usage_error("train: not implemented yet");
}
