/* marker.h - stage markers of the pipeline: OUT/<stage>.done says a stage finished with this
 * config on inputs with these content hashes; OUT/<stage>.started says what a stage that has
 * not finished was started with (so an interrupted training resumes only the same run).
 *
 *   cJSON *inputs = cJSON_CreateObject();
 *   PG_TRY(stage_hash_input(inputs, "depth", depth_path));
 *   char why[256];
 *   if (stage_marker_current(out, "prepare", config, inputs, why, sizeof why)) skip...
 *   else { fprintf(stderr, "prepare: %s\n", why); run...; stage_marker_write(out, "prepare", ...); }
 */
#ifndef PG_STAGE_MARKER_H
#define PG_STAGE_MARKER_H

#include <cjson/cJSON.h>
#include <stddef.h>

#include "core/status.h"

/* Adds inputs[name] = "<crc32>-<bytes>" of a file's content, or of every file under a directory
 * (names and contents, sorted, recursively). */
pg_status stage_hash_input(cJSON *inputs, const char *name, const char *path);

/* 1 if OUT/<stage>.<kind> ("done" or "started") holds the same config and inputs; else 0 and
 * why says what differs ("no marker", "setting iters changed (1500 -> 3000)", "input depth
 * changed"). */
int stage_marker_matches(const char *out, const char *stage, const char *kind, const cJSON *config,
                         const cJSON *inputs, char *why, size_t size);
/* Writes OUT/<stage>.<kind> atomically with config, inputs and the extra fields of `extra`
 * (seconds, threads; may be NULL). */
pg_status stage_marker_write(const char *out, const char *stage, const char *kind, const cJSON *config,
                             const cJSON *inputs, const cJSON *extra);
/* Reads OUT/<stage>.done's extra field (0 when absent). */
double stage_marker_number(const char *out, const char *stage, const char *field);
/* Removes OUT/<stage>.<kind> if present. */
void stage_marker_remove(const char *out, const char *stage, const char *kind);

#endif
