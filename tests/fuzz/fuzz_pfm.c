/* fuzz_pfm.c - libFuzzer harness: io_pfm_load on any bytes. */
#include "fuzz_common.h"
#include "io/depth_io.h"
#include "io/npy.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pg_array a;
    if (io_pfm_load(fuzz_file("x.pfm", data, size), &a) == PG_OK) pg_array_destroy(&a);
    return 0;
}
