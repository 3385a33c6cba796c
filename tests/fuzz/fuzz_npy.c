/* fuzz_npy.c - libFuzzer harness: io_npy_load on any bytes. */
#include "fuzz_common.h"
#include "io/npy.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pg_array a;
    if (io_npy_load(fuzz_file("x.npy", data, size), &a) == PG_OK) pg_array_destroy(&a);
    return 0;
}
