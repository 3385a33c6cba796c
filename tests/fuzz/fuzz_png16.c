/* fuzz_png16.c - libFuzzer harness: io_png16_load (8/16-bit grey PNG depth) on any bytes. */
#include "fuzz_common.h"
#include "io/depth_io.h"
#include "io/npy.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pg_array a;
    if (io_png16_load(fuzz_file("x.png", data, size), &a) == PG_OK) pg_array_destroy(&a);
    return 0;
}
