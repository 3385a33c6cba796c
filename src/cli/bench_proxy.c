/* bench_proxy.c - `prodygs bench proxy`: seconds per frame of the proxy stage (fit + render +
 * write) on the analytic RGB-D scene, printed as one JSON line. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "cli/cli.h"
#include "proxy/poses.h"
#include "proxy/procedural.h"
#include "proxy/proxy.h"

typedef struct {
    pg_camera cam;
} bench_source;

static pg_status bench_frame(void *ctx, int camera, int frame, pg_image *out)
{
    bench_source *s = ctx;
    (void)camera;
    PG_TRY(pg_image_create(out, s->cam.width, s->cam.height, 3));
    proxy_procedural_render(&s->cam, 0.2f * frame, 2, out->data, NULL);
    return PG_OK;
}

int bench_proxy(int argc, char **argv)
{
    int width = 320, height = 240, num = 18, threads = 2, frames = 0, steps = proxy_default_fit_options().steps, block = 1;
    float pad = proxy_default_fit_options().pad;
    const char *out = NULL, *render = "mesh";
    cli_option opts[] = {
        { "--render", CLI_STR, &render, "mesh (default) or splat (per-frame Gaussians, fitted)" },
        { "--width", CLI_INT, &width, "frame width (320)" },
        { "--height", CLI_INT, &height, "frame height (240)" },
        { "--num", CLI_INT, &num, "proxy cameras M (18)" },
        { "--threads", CLI_INT, &threads, "frame workers (2)" },
        { "--frames", CLI_INT, &frames, "frames to process (2 x threads)" },
        { "--steps", CLI_INT, &steps, "splat: Adam steps per frame (50)" },
        { "--block", CLI_INT, &block, "splat: one Gaussian per k x k block (1)" },
        { "--pad", CLI_FLOAT, &pad, "outpainted margin, fraction of the larger side (0.3)" },
        { "--out", CLI_STR, &out, "scratch directory (/tmp/prodygs-bench-proxy-PID)" },
    };
    cli_spec spec = { "prodygs bench proxy", "[options]", "time the proxy stage on a synthetic RGB-D video",
                      opts, (int)(sizeof opts / sizeof opts[0]), 0, 0 };
    int rc = cli_parse(&spec, argc, argv, NULL, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (width < 16 || height < 16 || width > 4096 || height > 4096)
        return cli_usage_error("bench proxy: size %dx%d not in 16..4096", width, height);
    if (num < 1 || num > 256) return cli_usage_error("bench proxy: --num %d not in 1..256", num);
    if (threads < 1 || threads > 64) return cli_usage_error("bench proxy: --threads %d not in 1..64", threads);
    if (frames < 0) return cli_usage_error("bench proxy: --frames %d must be >= 1 (0 = 2 x threads)", frames);
    if (!(pad >= 0 && pad <= 1)) return cli_usage_error("bench proxy: --pad %g not in [0, 1]", pad);
    if (strcmp(render, "mesh") != 0 && strcmp(render, "splat") != 0)
        return cli_usage_error("bench proxy: --render must be mesh or splat, not '%s'", render);
    if (frames == 0) frames = 2 * threads;
    if (frames > 1000) return cli_usage_error("bench proxy: --frames %d too many", frames);
    char dir[256];
    if (out) snprintf(dir, sizeof dir, "%s", out);
    else snprintf(dir, sizeof dir, "/tmp/prodygs-bench-proxy-%d", (int)getpid());

    bench_source src;
    pg_camera_from_fov(&src.cam, width, height, 60);
    size_t npix = (size_t)width * height;
    float *depth = malloc((size_t)frames * npix * sizeof(float));
    pg_camera *cams = malloc((size_t)num * sizeof(pg_camera));
    char(*names)[24] = malloc((size_t)num * sizeof *names);
    const char **pnames = malloc((size_t)num * sizeof(char *));
    if (!depth || !cams || !names || !pnames) {
        free(depth); free(cams); free(names); free(pnames);
        return cli_fail(pg_fail(PG_ERR_NOMEM, "bench proxy: out of memory"));
    }
    for (int f = 0; f < frames; f++) proxy_procedural_render(&src.cam, 0.2f * f, 1, NULL, depth + (size_t)f * npix);
    proxy_job job = { 0 };
    pg_status st = proxy_scene_center(&src.cam, depth, 1.0f, job.center, &job.radius);
    if (!st) st = proxy_poses_hemisphere(&src.cam, job.center, num, 20.0f, cams);
    for (int k = 0; k < num; k++) {
        snprintf(names[k], sizeof names[k], "proxy%02d", k);
        pnames[k] = names[k];
    }
    job.frames = frames; job.width = width; job.height = height; job.fps = 30;
    job.get_frame = bench_frame; job.frame_ctx = &src;
    job.depth = depth; job.pose_scale = 1;
    job.real_name = "cam00"; job.real = src.cam;
    job.num_proxies = num; job.proxy_names = pnames; job.proxies = cams;
    proxy_options o = proxy_default_options();
    o.threads = threads;
    o.force = 1;
    o.fit.render = strcmp(render, "splat") == 0 ? PROXY_RENDER_SPLAT : PROXY_RENDER_MESH;
    o.fit.steps = steps;
    o.fit.block = block;
    o.fit.pad = pad;
    proxy_result r;
    struct rusage ru0, ru1;
    getrusage(RUSAGE_SELF, &ru0);
    if (!st) st = proxy_generate(&o, &job, dir, &r);
    getrusage(RUSAGE_SELF, &ru1);
    /* CPU seconds of the run: on a machine shared with other jobs, cpu / threads estimates the
     * uncontended wall time. */
    double cpu = (ru1.ru_utime.tv_sec - ru0.ru_utime.tv_sec) + 1e-6 * (ru1.ru_utime.tv_usec - ru0.ru_utime.tv_usec) +
                 (ru1.ru_stime.tv_sec - ru0.ru_stime.tv_sec) + 1e-6 * (ru1.ru_stime.tv_usec - ru0.ru_stime.tv_usec);
    free(depth); free(cams); free(names); free(pnames);
    if (st) return cli_fail(st);
    double pf = 1.0 / frames;
    char psnr[32];
    printf("{\"bench\": \"proxy\", \"render\": \"%s\", \"width\": %d, \"height\": %d, \"num\": %d, \"threads\": %d, \"frames\": %d, "
           "\"steps\": %d, \"block\": %d, \"pad\": %g, \"seconds_per_frame\": %.3f, \"cpu_seconds_per_frame\": %.3f, \"worker_seconds_per_frame\": %.3f, "
           "\"init_s\": %.3f, \"fit_s\": %.3f, \"render_s\": %.3f, \"write_s\": %.3f, \"source_psnr\": %s, "
           "\"mean_valid_fraction\": %.3f, \"out\": \"%s\"}\n",
           render, width, height, num, threads, frames, steps, block, pad, r.wall_s * pf, cpu * pf,
           (r.init_s + r.fit_s + r.render_s + r.write_s) * pf, r.init_s * pf, r.fit_s * pf, r.render_s * pf,
           r.write_s * pf, cli_json_number(r.mean_source_psnr, 2, psnr, sizeof psnr), r.mean_valid_fraction, dir);
    return 0;
}
