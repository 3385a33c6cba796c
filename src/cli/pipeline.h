/* pipeline.h - the stages behind `prodygs run`, `eval` and `demo`.
 *
 * Each stage is the corresponding subcommand run in-process with arguments built here, so a
 * pipeline run is exactly what a user could type stage by stage. A stage that finished
 * writes OUT/<stage>.done (its arguments and wall time); a rerun with the same arguments skips
 * it, so an interrupted run continues from the last finished stage (and training resumes from
 * its last checkpoint).
 */
#ifndef PG_PIPELINE_H
#define PG_PIPELINE_H

#include <cjson/cJSON.h>
#include "cli/cli.h"

typedef struct {
    const char *input;       /* video, frame folder or dataset */
    const char *depth;       /* per-frame depth of the training camera */
    const char *out;         /* output directory */
    const char *preset;      /* "fast" or "quality" */
    const char *depth_kind;  /* NULL = depth */
    float depth_scale;       /* 0 = 1 */
    const char *train_cam;   /* dataset camera (NULL = first) */
    const char *test_cams;   /* "5,6": held out (dataset mode) */
    const char *poses;       /* "hemisphere" or "dataset" (NULL: dataset when test_cams given) */
    int proxies;             /* number of proxy cameras; -1 = preset default / all */
    float max_angle;         /* hemisphere cap angle (0 = default) */
    float fov;               /* single video: horizontal field of view in degrees (0 = default) */
    float pad;               /* proxies' outpainted margin, fraction of the larger side (< 0 = default) */
    int no_refine, no_align;
    int frames;              /* 0 = all */
    const char *size;        /* "WxH" or NULL (preset default) */
    char size_buf[32];       /* storage for a size the preset picked */
    int iters;               /* 0 = preset default */
    int threads, seed;
    float pose_scale;        /* 0 = fit */
    /* filled by pipeline_apply_preset: the cameras resolved once (names win over indices), passed
     * to every stage by NAME so each resolves the same camera, and recorded as "name (index i)" */
    char train_cam_buf[128], test_cams_buf[1024];
    char train_label[160], test_labels[2048];
} pipeline_options;

/* Runs prepare -> proxies -> train. Adds {stage: seconds} to `seconds`. Returns an exit code. */
int pipeline_run_stages(const pipeline_options *o, cJSON *seconds);
/* Copies the preset's defaults into the unset fields; returns 2 on an unknown preset. */
int pipeline_apply_preset(pipeline_options *o);
/* Paths of the stage outputs inside o->out. */
void pipeline_paths(const pipeline_options *o, char *prepare_dir, char *proxies_dir, char *model_dir, size_t size);
/* Fills opts with the options `run` and `eval` share (bound to o's fields, which it
 * initialises to defaults, with *proxies_text for --proxies); returns how many it wrote. */
int pipeline_cli_options(pipeline_options *o, const char **proxies_text, cli_option *opts, int max);
/* Parses argv with spec (one positional: INPUT), checks --depth/--out, interprets --proxies,
 * applies the preset and the thread count. Returns 0, -1 after --help, or an exit code. */
int pipeline_cli_parse(const cli_spec *spec, int argc, char **argv, pipeline_options *o, const char **proxies_text);
/* After the stages: novel-view videos into OUT/renders (cmd_run.c). */
int pipeline_render_videos(const pipeline_options *o, cJSON *seconds);
/* After the stages: the DyNeRF protocol scores into OUT (cmd_eval.c). */
int pipeline_evaluate(const pipeline_options *o, cJSON *seconds);
/* Records the arguments and configuration as JSON (for metrics.json). */
cJSON *pipeline_config_json(const pipeline_options *o);

#endif
