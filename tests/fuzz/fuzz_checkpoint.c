/* fuzz_checkpoint.c - libFuzzer harness: train_model_load; the CRC-32 is fixed up first so the fuzzer reaches the parser behind it. */
#include "fuzz_common.h"
#include <zlib.h>
#include "train/model.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy) return 0;
    memcpy(copy, data, size);
    if (size >= 16) { /* the trailing CRC of everything before it */
        uint32_t crc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), copy, (uInt)(size - 4));
        memcpy(copy + size - 4, &crc, 4);
    }
    train_model m;
    if (train_model_load(fuzz_file("model.ckpt", copy, size), &m) == PG_OK) train_model_destroy(&m);
    free(copy);
    return 0;
}
