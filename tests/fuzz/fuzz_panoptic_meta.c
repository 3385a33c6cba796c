/* fuzz_panoptic_meta.c - libFuzzer harness: a Panoptic dataset whose train_meta.json is the input. */
#include "fuzz_common.h"
#include "io/dataset.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_file("train_meta.json", data, size);
    pg_dataset *ds = NULL;
    io_dataset_options o = io_dataset_defaults();
    if (io_dataset_open(fuzz_dir(), &o, &ds) == PG_OK) io_dataset_close(ds);
    return 0;
}
