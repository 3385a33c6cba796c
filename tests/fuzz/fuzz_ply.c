/* fuzz_ply.c - libFuzzer harness: io_ply_load (3DGS PLY) on any bytes. */
#include "fuzz_common.h"
#include "io/ply.h"
#include "splat/gaussians.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pg_gaussians g = { 0 };
    if (io_ply_load(fuzz_file("x.ply", data, size), &g) == PG_OK) splat_gaussians_destroy(&g);
    return 0;
}
