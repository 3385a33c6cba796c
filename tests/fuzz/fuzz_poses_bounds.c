/* fuzz_poses_bounds.c - libFuzzer harness: a DyNeRF dataset whose poses_bounds.npy is the input (one camera folder beside it). */
#include "fuzz_common.h"
#include "core/fileutil.h"
#include "core/image.h"
#include "io/dataset.h"
#include "io/image_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_file("poses_bounds.npy", data, size);
    static int once;
    if (!once) { /* cam00/images/0000.png beside it: a 4x4 grey frame */
        char path[1100];
        snprintf(path, sizeof path, "%s/cam00/images", fuzz_dir());
        if (pg_mkdir_p(path) != PG_OK) abort();
        snprintf(path, sizeof path, "%s/cam00/images/0000.png", fuzz_dir());
        pg_image img;
        if (pg_image_create(&img, 4, 4, 3) != PG_OK) abort();
        for (int i = 0; i < 48; i++) img.data[i] = 0.5f;
        if (io_image_save_png(path, &img) != PG_OK) abort();
        pg_image_destroy(&img);
        once = 1;
    }
    pg_dataset *ds = NULL;
    io_dataset_options o = io_dataset_defaults();
    if (io_dataset_open(fuzz_dir(), &o, &ds) == PG_OK) io_dataset_close(ds);
    return 0;
}
