/* fuzz_exr.c - libFuzzer harness: io_exr_load (scanline OpenEXR depth) on any bytes. */
#include "fuzz_common.h"
#include "io/depth_io.h"
#include "io/npy.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pg_array a;
    if (io_exr_load(fuzz_file("x.exr", data, size), &a) == PG_OK) pg_array_destroy(&a);
    return 0;
}
