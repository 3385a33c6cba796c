/* depth_default.c - the built-in depth network written out for use (see depth_default.h). */
#include "depth/depth_default.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/fileutil.h"

/* gen/depth_fastdepth.c, made by cmake/embed.cmake from models/fastdepth_224_int8.tflite */
extern const unsigned char depth_fastdepth_tflite[];
extern const size_t depth_fastdepth_tflite_size;

/* The model's MODEL.json (depth_net.h): the network reads BGR (its Spearman correlation with
 * tabletop_dev's ground truth is 0.6-0.75 that way, about 0 in RGB) and outputs metres. */
static const char sidecar[] = "{\"name\": \"FastDepth (MIT)\", \"license\": \"MIT\", \"input_size\": [224, 224], "
                              "\"channel_order\": \"bgr\", \"output\": \"depth\", \"scale\": 1}\n";

/* Writes data to path unless the file already holds exactly these bytes. */
static pg_status write_if_different(const char *path, const void *data, size_t size)
{
    char *have = NULL;
    size_t n = 0;
    if (pg_path_exists(path) && pg_read_file(path, size + 1, &have, &n) == PG_OK && n == size && memcmp(have, data, size) == 0) {
        free(have);
        return PG_OK;
    }
    free(have);
    return pg_write_file_atomic(path, data, size);
}

pg_status depth_default_model(char *path, size_t size)
{
    char dir[4096], side[4200];
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    if (xdg && *xdg) snprintf(dir, sizeof dir, "%s/prodygs", xdg);
    else if (home && *home) snprintf(dir, sizeof dir, "%s/.cache/prodygs", home);
    else snprintf(dir, sizeof dir, "/tmp/prodygs-%u", (unsigned)getuid());
    PG_TRY(pg_private_dir(dir));
    PG_TRY(pg_path_join(path, size, dir, "fastdepth_224_int8.tflite"));
    snprintf(side, sizeof side, "%s.json", path);
    PG_TRY(write_if_different(path, depth_fastdepth_tflite, depth_fastdepth_tflite_size));
    return write_if_different(side, sidecar, sizeof sidecar - 1);
}
