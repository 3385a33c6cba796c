/* depth_default.h - the depth network built into prodygs: FastDepth (MIT, models/
 * fastdepth_224_int8.tflite, compiled into the library as a byte array at build time), used when
 * the user names no depth (run / eval / prepare without --depth or --depth-model, depth without
 * --model).
 *
 *   char model[4096];
 *   PG_TRY(depth_default_model(model, sizeof model));   then open `model` like any model file
 */
#ifndef PG_DEPTH_DEFAULT_H
#define PG_DEPTH_DEFAULT_H

#include <stddef.h>

#include "core/status.h"

/* What the CLI says when it falls back to the built-in model (one stderr line). */
#define DEPTH_DEFAULT_NOTICE "using the embedded FastDepth (MIT; 224x224 int8 TFLite, metric depth, trained indoors on NYU Depth v2)"

/* Writes the built-in model and its MODEL.json (name, licence, input size, BGR channel order,
 * output depth) into the user's cache folder ($XDG_CACHE_HOME/prodygs, else $HOME/.cache/prodygs,
 * else /tmp/prodygs-UID), unless identical files are there already, and gives the model's path:
 * every consumer (depth_net_open, the depth stage's content-hashed cache) then treats it like a
 * file the user passed. The folder must pass pg_private_dir (yours, 0700, not a symbolic link);
 * fails with PG_ERR_ENV naming the folder otherwise, or the path it could not write. */
pg_status depth_default_model(char *path, size_t size);

#endif
