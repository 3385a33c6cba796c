/* main.c - `prodygs` entry point: dispatches to the subcommands. */
#include "cli/cli.h"
#include "deform/gemm_amx.h"
#include "nn/nn_ops.h"
#include "splat/raster.h"

#include <stdio.h>
#include <string.h>

typedef struct {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *summary;
} command;

static const command commands[] = {
    { "run",     cmd_run,     "whole pipeline: depth prep, proxies, training, renders" },
    { "demo",    cmd_demo,    "build the sample scene and run the pipeline on it" },
    { "info",    cmd_info,    "describe a video, frame folder, dataset, depth file or PLY" },
    { "synth",   cmd_synth,   "render the built-in sample scene (DyNeRF layout)" },
    { "depth",   cmd_depth,   "per-frame depth from a depth network (TFLite/ONNX)" },
    { "prepare", cmd_prepare, "refine and temporally align per-frame depth" },
    { "proxies", cmd_proxies, "render proxy views from virtual cameras" },
    { "train",   cmd_train,   "train canonical Gaussians + deformation network" },
    { "render",  cmd_render,  "render a trained model along a camera path" },
    { "export",  cmd_export,  "export deformed Gaussians as 3DGS PLY" },
    { "view",    cmd_view,    "interactive 4D viewer in the browser (localhost)" },
    { "eval",    cmd_eval,    "DyNeRF protocol evaluation (PSNR/SSIM, masked)" },
    { "bench",   cmd_bench,   "speed benchmarks printing one JSON line" },
};

static void usage(FILE *out)
{
    fprintf(out, "usage: prodygs COMMAND [options]   (prodygs COMMAND --help for details; prodygs --version)\n\ncommands:\n");
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(out, "  %-8s %s\n", commands[i].name, commands[i].summary);
}

#if defined(__SANITIZE_ADDRESS__)
/* Sanitizer builds: an absurd allocation returns NULL (a clean "out of memory" error, as in
 * release builds) instead of aborting, so bad-input tests see the same behaviour. */
const char *__asan_default_options(void);
const char *__asan_default_options(void) { return "allocator_may_return_null=1"; }
#endif

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "prodygs: missing command; usage: prodygs COMMAND [options] (prodygs --help lists the commands)\n");
        return 2;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "help") == 0) {
        usage(stdout);
        return 0;
    }
    cli_set_load_env(argv);
    if (strcmp(argv[1], "--version") == 0 || strcmp(argv[1], "version") == 0) {
        printf("prodygs %s (kernels: deformation network %s, rasterizer %s, depth network convolutions %s, OpenBLAS %s; "
               "force with PG_KERNELS=amx|avx512bf16|f32, PG_RASTER=avx512|avx2|scalar, PG_NN_GEMM=f32|openblas, "
               "OPENBLAS_CORETYPE)\n", PRODYGS_VERSION, gemm_bf16_name(gemm_bf16_backend()),
               splat_kernel_name(splat_kernel_default()), nn_conv_kernel(), cli_blas_core());
        return 0;
    }
    cli_install_progress();
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (strcmp(argv[1], commands[i].name) == 0) return commands[i].run(argc - 1, argv + 1);
    fprintf(stderr, "prodygs: unknown command '%s' (try prodygs --help)\n", argv[1]);
    return 2;
}
