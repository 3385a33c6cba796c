/* json.h - small helpers on cJSON for configs, reports and cameras.
 *
 *   cJSON *root;
 *   PG_TRY(io_json_load("trainset.json", &root));
 *   double fps;
 *   PG_TRY(io_json_get_number(root, "fps", "trainset.json", &fps));
 *   ...
 *   cJSON_AddItemToObject(out, "camera", io_json_from_camera(&cam, "cam00"));
 *   PG_TRY(io_json_write_atomic("report.json", out));
 *
 * Every getter names the file/context (`what`) and the key in its error message.
 */
#ifndef PG_JSON_H
#define PG_JSON_H

#include <stddef.h>
#include <cjson/cJSON.h>
#include "core/camera.h"
#include "core/status.h"

/* Parses a whole file (limit 512 MB); fails naming the file and the byte offset of a syntax error. */
pg_status io_json_load(const char *path, cJSON **root);
/* Writes pretty-printed JSON atomically (temp file + rename). */
pg_status io_json_write_atomic(const char *path, const cJSON *root);

/* Required number at key (finite). */
pg_status io_json_get_number(const cJSON *obj, const char *key, const char *what, double *out);
/* Required integer at key within [lo, hi]. */
pg_status io_json_get_int(const cJSON *obj, const char *key, const char *what, int lo, int hi, int *out);
/* Required array of exactly n finite numbers at key (key NULL: obj itself is the array). */
pg_status io_json_get_floats(const cJSON *obj, const char *key, const char *what, float *out, int n);
/* Optional number/string with a default when the key is absent or has another type. */
double io_json_number_or(const cJSON *obj, const char *key, double def);
const char *io_json_string_or(const cJSON *obj, const char *key, const char *def);
/* Optional length factor at root.source.key (prepare.json's depth_unit, a training set's unit):
 * 1 when absent, else a number in [1e-30, 1e30]. */
pg_status io_json_get_source_unit(const cJSON *root, const char *key, const char *what, double *out);
/* Adds a float array (NULL on allocation failure). */
cJSON *io_json_float_array(const float *v, int n);

/* Camera object in the docs/FORMATS.md layout: name, width, height, fx, fy, cx, cy, R (9), t (3).
 * Returns NULL on allocation failure. name may be NULL (omitted). */
cJSON *io_json_from_camera(const pg_camera *cam, const char *name);
/* Reads a camera object; name (may be NULL) receives "name" if present. Validates sizes,
 * positive focal lengths and a rotation that is orthonormal within 1e-3. */
pg_status io_json_to_camera(const cJSON *obj, const char *what, pg_camera *cam, char *name, size_t name_size);

#endif
