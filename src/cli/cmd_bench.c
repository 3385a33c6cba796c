/* cmd_bench.c - `prodygs bench KIND ...`: dispatches to the benchmark of each stage. */
#include "cli/cli.h"

#include <stdio.h>
#include <string.h>

int bench_raster(int argc, char **argv);
int bench_proxy(int argc, char **argv);
int bench_iteration(int argc, char **argv);
int bench_deform(int argc, char **argv);
int bench_loss(int argc, char **argv);
int bench_flow(int argc, char **argv);
int bench_nn(int argc, char **argv);

#define BENCH_KINDS "raster, proxy, iteration, deform, loss, flow, nn"

int cmd_bench(int argc, char **argv)
{
    if (argc < 2) return cli_usage_error("bench: missing benchmark; usage: prodygs bench KIND [options] (KIND: " BENCH_KINDS ")");
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0) {
        printf("usage: prodygs bench KIND [options]\n\n"
               "Speed benchmarks; each prints one JSON line on stdout.\n\n"
               "kinds:\n"
               "  raster     rasterizer forward/backward on random Gaussians\n"
               "  proxy      per-frame proxy fit + render\n"
               "  iteration  one fine-stage training iteration, split by part\n"
               "  deform     HexPlane + MLP deformation forward/backward\n"
               "  loss       image losses (L1, SSIM) forward/backward\n"
               "  flow       optical flow between two frames\n"
               "  nn         one forward pass of a network (--model FILE.onnx)\n\n"
               "prodygs bench KIND --help lists the options of each.\n");
        return 0;
    }
    if (strcmp(argv[1], "raster") == 0) return bench_raster(argc - 1, argv + 1);
    if (strcmp(argv[1], "proxy") == 0) return bench_proxy(argc - 1, argv + 1);
    if (strcmp(argv[1], "iteration") == 0) return bench_iteration(argc - 1, argv + 1);
    if (strcmp(argv[1], "deform") == 0) return bench_deform(argc - 1, argv + 1);
    if (strcmp(argv[1], "loss") == 0) return bench_loss(argc - 1, argv + 1);
    if (strcmp(argv[1], "flow") == 0) return bench_flow(argc - 1, argv + 1);
    if (strcmp(argv[1], "nn") == 0) return bench_nn(argc - 1, argv + 1);
    return cli_usage_error("bench: unknown benchmark '%s' (" BENCH_KINDS ")", argv[1]);
}
