/* video_read.c - decode frames from a video (FFmpeg libav*) or an image folder into uint8 RGB. */
#include "io/video.h"
#include "io/image_io.h"
#include "core/fileutil.h"

#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/display.h>
#include <libavutil/imgutils.h>
#include <libswscale/swscale.h>

#include <ctype.h>
#include <dirent.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* Hard cap on frames held in memory (guards absurd counts before allocating). */
#define IO_MAX_FRAMES 100000

io_video_options io_video_defaults(void)
{
    io_video_options o;
    memset(&o, 0, sizeof o);
    o.stride = 1;
    o.folder_fps = 30.0;
    return o;
}

void io_frames_destroy(io_frames *fr)
{
    if (!fr) return;
    free(fr->rgb);
    memset(fr, 0, sizeof *fr);
}

pg_status io_frames_image(const io_frames *fr, int i, pg_image *img)
{
    if (i < 0 || i >= fr->count) return pg_fail(PG_ERR_ARG, "frame %d out of range (0..%d)", i, fr->count - 1);
    PG_TRY(pg_image_create(img, fr->width, fr->height, 3));
    size_t n = (size_t)fr->width * fr->height * 3;
    const uint8_t *src = fr->rgb + n * (size_t)i;
    for (size_t k = 0; k < n; k++) img->data[k] = src[k] * (1.0f / 255.0f);
    return PG_OK;
}

void io_video_target_size(const io_video_options *opt, int src_w, int src_h, int *w, int *h)
{
    int tw = src_w, th = src_h;
    if (opt && opt->width > 0 && opt->height > 0) {
        tw = opt->width;
        th = opt->height;
    } else if (opt && opt->width > 0) {
        tw = opt->width;
        th = (int)lround((double)src_h * tw / src_w);
    } else if (opt && opt->height > 0) {
        th = opt->height;
        tw = (int)lround((double)src_w * th / src_h);
    } else if (opt && opt->max_side > 0 && (src_w > opt->max_side || src_h > opt->max_side)) {
        double s = (double)opt->max_side / (src_w > src_h ? src_w : src_h);
        tw = (int)lround(src_w * s);
        th = (int)lround(src_h * s);
    }
    *w = tw < 1 ? 1 : tw;
    *h = th < 1 ? 1 : th;
}

/* ---------------- image folders ---------------- */

static int has_image_ext(const char *name)
{
    const char *dot = strrchr(name, '.');
    if (!dot) return 0;
    return !strcasecmp(dot, ".png") || !strcasecmp(dot, ".jpg") || !strcasecmp(dot, ".jpeg");
}

/* Natural order: digit runs compare by value so "frame2" sorts before "frame10". */
static int natural_cmp(const char *a, const char *b)
{
    while (*a && *b) {
        if (isdigit((unsigned char)*a) && isdigit((unsigned char)*b)) {
            while (*a == '0' && isdigit((unsigned char)a[1])) a++;
            while (*b == '0' && isdigit((unsigned char)b[1])) b++;
            size_t la = 0, lb = 0;
            while (isdigit((unsigned char)a[la])) la++;
            while (isdigit((unsigned char)b[lb])) lb++;
            if (la != lb) return la < lb ? -1 : 1;
            int c = strncmp(a, b, la);
            if (c) return c;
            a += la;
            b += lb;
        } else {
            if (*a != *b) return (unsigned char)*a < (unsigned char)*b ? -1 : 1;
            a++;
            b++;
        }
    }
    return (unsigned char)*a - (unsigned char)*b;
}

static int cmp_names(const void *x, const void *y)
{
    const char *a = *(const char *const *)x, *b = *(const char *const *)y;
    const char *sa = strrchr(a, '/'), *sb = strrchr(b, '/');
    return natural_cmp(sa ? sa + 1 : a, sb ? sb + 1 : b);
}

void io_sort_names(char **names, int count)
{
    if (count > 1) qsort(names, (size_t)count, sizeof *names, cmp_names);
}

void io_free_names(char **names, int count)
{
    if (!names) return;
    for (int i = 0; i < count; i++) free(names[i]);
    free(names);
}

pg_status io_list_images(const char *dir, char ***names, int *count)
{
    *names = NULL;
    *count = 0;
    DIR *d = opendir(dir);
    if (!d) return pg_fail(PG_ERR_IO, "%s: cannot open folder", dir);
    int n = 0, cap = 0;
    char **list = NULL;
    struct dirent *e;
    pg_status st = PG_OK;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.' || !has_image_ext(e->d_name)) continue;
        if (n >= IO_MAX_FRAMES) { st = pg_fail(PG_ERR_SIZE, "%s: more than %d images", dir, IO_MAX_FRAMES); break; }
        if (n == cap) {
            cap = cap ? cap * 2 : 64;
            char **nl = realloc(list, sizeof *list * (size_t)cap);
            if (!nl) { st = pg_fail(PG_ERR_NOMEM, "%s: out of memory listing images", dir); break; }
            list = nl;
        }
        size_t len = strlen(dir) + strlen(e->d_name) + 2;
        list[n] = pg_malloc(len, dir);
        if (!list[n]) { st = PG_ERR_NOMEM; break; }
        snprintf(list[n], len, "%s/%s", dir, e->d_name);
        n++;
    }
    closedir(d);
    if (st == PG_OK && n == 0) st = pg_fail(PG_ERR_FORMAT, "%s: folder holds no .png/.jpg frames", dir);
    if (st != PG_OK) { io_free_names(list, n); return st; }
    io_sort_names(list, n);
    *names = list;
    *count = n;
    return PG_OK;
}

static const char *file_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

/* The number at the end of a file's base name (before the extension); -1 if none. */
static long frame_number(const char *path)
{
    const char *base = file_name(path);
    const char *dot = strrchr(base, '.'), *end = dot ? dot : base + strlen(base), *d = end;
    while (d > base && isdigit((unsigned char)d[-1])) d--;
    if (d == end || end - d > 9) return -1;
    return strtol(d, NULL, 10);
}

/* Frames of a folder are used in name order as consecutive frames; a gap in their numbers (0001,
 * 0003: a frame lost in an export) shifts the timing of every later frame, so say so (once per
 * folder: every stage reopens the input). */
static void warn_number_gaps(const char *path, char **names, int n)
{
    static char warned[512];
    if (n < 2 || strncmp(warned, path, sizeof warned - 1) == 0) return;
    for (int i = 1; i < n; i++) {
        long a = frame_number(names[i - 1]), b = frame_number(names[i]);
        if (a < 0 || b < 0) return; /* not numbered frames */
        if (b != a + 1) {
            snprintf(warned, sizeof warned, "%s", path);
            pg_warn("%s: frame numbers jump from %ld to %ld (%s, %s): the frames are used in order as if consecutive",
                    path, a, b, file_name(names[i - 1]), file_name(names[i]));
            return;
        }
    }
}

/* Only the header of each image is needed for probing, but loading one full frame is cheap
 * enough and validates it; the rest are counted. */
static pg_status probe_folder(const char *path, io_video_info *info)
{
    char **names;
    int n;
    PG_TRY(io_list_images(path, &names, &n));
    warn_number_gaps(path, names, n);
    pg_image img;
    pg_status st = io_image_load(names[0], &img);
    if (st == PG_OK) {
        info->is_folder = 1;
        info->width = img.width;
        info->height = img.height;
        info->frames = n;
        info->frames_exact = 1;
        info->fps = 30.0;
        info->duration = n / 30.0;
        const char *dot = strrchr(names[0], '.');
        snprintf(info->codec, sizeof info->codec, "%s", !strcasecmp(dot, ".png") ? "png" : "jpeg");
        snprintf(info->container, sizeof info->container, "folder");
        pg_image_destroy(&img);
    }
    io_free_names(names, n);
    return st;
}

static pg_status select_range(const char *path, const io_video_options *opt, int available, int *first, int *count,
                              int *stride)
{
    *first = opt->first < 0 ? 0 : opt->first;
    *stride = opt->stride < 1 ? 1 : opt->stride;
    if (*first >= available)
        return pg_fail(PG_ERR_ARG, "%s: first frame %d is past the end (%d frames)", path, *first, available);
    int can = (available - *first + *stride - 1) / *stride;
    if (opt->count > 0) {
        if (opt->count > can)
            return pg_fail(PG_ERR_ARG, "%s: asked for %d frames from %d with stride %d, but only %d exist", path,
                           opt->count, *first, *stride, can);
        *count = opt->count;
    } else
        *count = can;
    return PG_OK;
}

static pg_status alloc_frames(const char *path, io_frames *out, int count, int w, int h)
{
    size_t bytes;
    if (pg_size_mul((size_t)w * h * 3, (size_t)count, &bytes))
        return pg_fail(PG_ERR_SIZE, "%s: %d frames of %d x %d is too large", path, count, w, h);
    out->rgb = pg_malloc(bytes ? bytes : 1, path);
    if (!out->rgb) return PG_ERR_NOMEM;
    out->width = w;
    out->height = h;
    return PG_OK;
}

static pg_status read_folder(const char *path, const io_video_options *opt, io_frames *out)
{
    char **names;
    int n, first = 0, count = 0, stride = 1;
    PG_TRY(io_list_images(path, &names, &n));
    pg_status st = select_range(path, opt, n, &first, &count, &stride);
    pg_image img = { 0 }, small = { 0 };
    for (int k = 0; st == PG_OK && k < count; k++) {
        const char *name = names[first + k * stride];
        st = io_image_load(name, &img);
        if (st) break;
        if (k == 0) {
            int tw, th;
            out->src_width = img.width;
            out->src_height = img.height;
            io_video_target_size(opt, img.width, img.height, &tw, &th);
            st = alloc_frames(path, out, count, tw, th);
        } else if (img.width != out->src_width || img.height != out->src_height) {
            st = pg_fail(PG_ERR_SIZE, "%s: is %d x %d but the first frame is %d x %d", name, img.width, img.height,
                         out->src_width, out->src_height);
        }
        const pg_image *use = &img;
        if (st == PG_OK && (img.width != out->width || img.height != out->height)) {
            st = pg_image_resize(&small, &img, out->width, out->height);
            use = &small;
        }
        if (st == PG_OK) {
            size_t m = (size_t)out->width * out->height * 3;
            uint8_t *dst = out->rgb + m * (size_t)k;
            for (size_t i = 0; i < m; i++) {
                float v = use->data[i] * 255.0f + 0.5f;
                dst[i] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
            }
            out->count = k + 1;
        }
        pg_image_destroy(&img);
        pg_image_destroy(&small);
    }
    out->fps = opt->folder_fps > 0 ? opt->folder_fps : 30.0;
    io_free_names(names, n);
    return st;
}

/* ---------------- video files ---------------- */

static void quiet_ffmpeg(void)
{
    /* The library must not print; FFmpeg's own log goes to stderr otherwise. */
    av_log_set_level(AV_LOG_QUIET);
}

static const char *av_err(int err, char *buf, size_t size)
{
    av_strerror(err, buf, size);
    return buf;
}

typedef struct {
    AVFormatContext *fmt;
    AVCodecContext *dec;
    int stream;
} av_input;

/* Clockwise rotation (0, 90, 180, 270) a player applies from the stream's display matrix
 * (phone videos are stored landscape with a "rotate" tag). */
static int stream_rotation(const AVStream *s)
{
    const uint8_t *m = av_stream_get_side_data(s, AV_PKT_DATA_DISPLAYMATRIX, NULL);
    if (!m) return 0;
    double a = -av_display_rotation_get((const int32_t *)m);
    if (isnan(a)) return 0;
    int r = (int)lround(a / 90.0) * 90 % 360;
    return r < 0 ? r + 360 : r;
}

static void av_input_close(av_input *in)
{
    avcodec_free_context(&in->dec);
    avformat_close_input(&in->fmt);
}

static pg_status av_input_open(const char *path, av_input *in, int open_decoder)
{
    char eb[128];
    memset(in, 0, sizeof *in);
    quiet_ffmpeg();
    PG_TRY(pg_check_input(path)); /* a FIFO would block ffmpeg's open until a writer came */
    int r = avformat_open_input(&in->fmt, path, NULL, NULL);
    if (r < 0) return pg_fail(PG_ERR_FORMAT, "%s: not a readable video: %s", path, av_err(r, eb, sizeof eb));
    r = avformat_find_stream_info(in->fmt, NULL);
    if (r < 0) {
        av_input_close(in);
        return pg_fail(PG_ERR_FORMAT, "%s: cannot read stream info: %s", path, av_err(r, eb, sizeof eb));
    }
    const AVCodec *codec = NULL;
    r = av_find_best_stream(in->fmt, AVMEDIA_TYPE_VIDEO, -1, -1, &codec, 0);
    if (r < 0 || !codec) {
        av_input_close(in);
        return pg_fail(PG_ERR_FORMAT, "%s: no decodable video stream", path);
    }
    in->stream = r;
    AVCodecParameters *par = in->fmt->streams[r]->codecpar;
    if (par->width <= 0 || par->height <= 0 || par->width > PG_MAX_IMAGE_SIDE || par->height > PG_MAX_IMAGE_SIDE) {
        int w = par->width, h = par->height; /* par belongs to the input closed below */
        av_input_close(in);
        return pg_fail(PG_ERR_SIZE, "%s: video size %d x %d is out of range (sides up to %d)", path, w, h,
                       PG_MAX_IMAGE_SIDE);
    }
    if (!open_decoder) return PG_OK;
    in->dec = avcodec_alloc_context3(codec);
    if (!in->dec) { av_input_close(in); return pg_fail(PG_ERR_NOMEM, "%s: cannot allocate decoder", path); }
    if (avcodec_parameters_to_context(in->dec, par) < 0 || (r = avcodec_open2(in->dec, codec, NULL)) < 0) {
        av_input_close(in);
        return pg_fail(PG_ERR_FORMAT, "%s: cannot open %s decoder", path, codec->name);
    }
    return PG_OK;
}

static double stream_fps(const AVStream *s)
{
    AVRational r = s->avg_frame_rate.num > 0 ? s->avg_frame_rate : s->r_frame_rate;
    return r.num > 0 && r.den > 0 ? av_q2d(r) : 30.0;
}

pg_status io_video_probe(const char *path, io_video_info *info)
{
    memset(info, 0, sizeof *info);
    if (pg_path_is_dir(path)) return probe_folder(path, info);
    av_input in;
    PG_TRY(av_input_open(path, &in, 0));
    AVStream *s = in.fmt->streams[in.stream];
    info->width = s->codecpar->width;
    info->height = s->codecpar->height;
    info->rotation = stream_rotation(s);
    if (info->rotation == 90 || info->rotation == 270) {
        info->width = s->codecpar->height;
        info->height = s->codecpar->width;
    }
    info->fps = stream_fps(s);
    if (in.fmt->duration > 0) info->duration = in.fmt->duration / (double)AV_TIME_BASE;
    if (s->nb_frames > 0 && s->nb_frames < IO_MAX_FRAMES) {
        info->frames = (int)s->nb_frames; /* from the container's index (mp4/mov): trusted */
        info->frames_exact = 1;
    } else if (info->duration > 0) {
        info->frames = (int)lround(info->duration * info->fps);
    }
    snprintf(info->codec, sizeof info->codec, "%s", avcodec_get_name(s->codecpar->codec_id));
    snprintf(info->container, sizeof info->container, "%s", in.fmt->iformat->name);
    av_input_close(&in);
    return PG_OK;
}

pg_status io_video_count_frames(const char *path, int *frames)
{
    *frames = 0;
    if (pg_path_is_dir(path)) {
        char **names;
        PG_TRY(io_list_images(path, &names, frames));
        io_free_names(names, *frames);
        return PG_OK;
    }
    av_input in;
    PG_TRY(av_input_open(path, &in, 0));
    AVPacket *pkt = av_packet_alloc();
    if (!pkt) { av_input_close(&in); return pg_fail(PG_ERR_NOMEM, "%s: cannot allocate packet", path); }
    int n = 0;
    while (av_read_frame(in.fmt, pkt) >= 0) {
        if (pkt->stream_index == in.stream) n++;
        av_packet_unref(pkt);
    }
    av_packet_free(&pkt);
    av_input_close(&in);
    *frames = n;
    return PG_OK;
}

typedef struct {
    const char *path;
    io_frames *out;
    struct SwsContext *sws;
    int first, count, stride; /* count < 0: all */
    int decoded;              /* frames decoded so far */
    int cap;                  /* allocated frames in out->rgb */
    int rotation;             /* clockwise degrees applied after scaling */
    int sw, sh;               /* scaled size before rotation */
    uint8_t *tmp;             /* (sh, sw, 3) scaled frame when rotating */
    int64_t last_pts;         /* timestamp of the previous decoded frame (AV_NOPTS_VALUE: none) */
    int64_t min_step, max_step; /* smallest and largest step between frames (stream time base) */
} decode_state;

/* Rotates an RGB24 image (w, h) clockwise by rot degrees into dst. */
static void rotate_rgb(uint8_t *dst, const uint8_t *src, int w, int h, int rot)
{
    int ow = rot == 180 ? w : h;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int ox, oy;
            if (rot == 90) { ox = h - 1 - y; oy = x; }
            else if (rot == 270) { ox = y; oy = w - 1 - x; }
            else { ox = w - 1 - x; oy = h - 1 - y; }
            memcpy(dst + ((size_t)oy * ow + ox) * 3, src + ((size_t)y * w + x) * 3, 3);
        }
}

/* Stores a decoded frame if the selection keeps it; grows the buffer when reading "all". */
static pg_status take_frame(decode_state *ds, const AVFrame *f)
{
    int idx = ds->decoded++;
    int64_t pts = f->best_effort_timestamp;
    if (pts != AV_NOPTS_VALUE && ds->last_pts != AV_NOPTS_VALUE && pts > ds->last_pts) {
        int64_t step = pts - ds->last_pts;
        if (!ds->min_step || step < ds->min_step) ds->min_step = step;
        if (step > ds->max_step) ds->max_step = step;
    }
    ds->last_pts = pts;
    if (idx < ds->first || (idx - ds->first) % ds->stride) return PG_OK;
    int k = (idx - ds->first) / ds->stride;
    if (ds->count >= 0 && k >= ds->count) return PG_OK;
    io_frames *out = ds->out;
    int fw = ds->rotation == 90 || ds->rotation == 270 ? f->height : f->width;
    int fh = ds->rotation == 90 || ds->rotation == 270 ? f->width : f->height;
    if (fw != out->src_width || fh != out->src_height)
        return pg_fail(PG_ERR_FORMAT, "%s: frame %d changes size to %d x %d", ds->path, idx, f->width, f->height);
    if (k >= ds->cap) {
        int ncap = ds->cap ? ds->cap * 2 : 16;
        if (ds->count >= 0) ncap = ds->count;
        if (ncap > IO_MAX_FRAMES) return pg_fail(PG_ERR_SIZE, "%s: more than %d frames", ds->path, IO_MAX_FRAMES);
        size_t fb = (size_t)out->width * out->height * 3;
        uint8_t *nb = realloc(out->rgb, fb * (size_t)ncap);
        if (!nb) return pg_fail(PG_ERR_NOMEM, "%s: out of memory holding %d frames", ds->path, ncap);
        out->rgb = nb;
        ds->cap = ncap;
    }
    if (!ds->sws) {
        int flags = (ds->sw < f->width || ds->sh < f->height) ? SWS_AREA : SWS_BICUBIC;
        ds->sws = sws_getContext(f->width, f->height, (enum AVPixelFormat)f->format, ds->sw, ds->sh,
                                 AV_PIX_FMT_RGB24, flags | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INT, NULL, NULL, NULL);
        if (!ds->sws) return pg_fail(PG_ERR_FORMAT, "%s: cannot convert pixel format %d to RGB", ds->path, f->format);
    }
    uint8_t *frame_dst = out->rgb + (size_t)k * out->width * out->height * 3;
    if (ds->rotation && !ds->tmp) {
        ds->tmp = pg_malloc((size_t)ds->sw * ds->sh * 3, ds->path);
        if (!ds->tmp) return PG_ERR_NOMEM;
    }
    uint8_t *dst[4] = { ds->rotation ? ds->tmp : frame_dst, NULL, NULL, NULL };
    int dst_stride[4] = { ds->sw * 3, 0, 0, 0 };
    sws_scale(ds->sws, (const uint8_t *const *)f->data, f->linesize, 0, f->height, dst, dst_stride);
    if (ds->rotation) rotate_rgb(frame_dst, ds->tmp, ds->sw, ds->sh, ds->rotation);
    out->count = k + 1;
    return PG_OK;
}

static int selection_done(const decode_state *ds)
{
    return ds->count >= 0 && ds->out->count >= ds->count;
}

static pg_status drain(decode_state *ds, AVCodecContext *dec, AVFrame *frame)
{
    char eb[128];
    for (;;) {
        int r = avcodec_receive_frame(dec, frame);
        if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return PG_OK;
        if (r < 0) return pg_fail(PG_ERR_FORMAT, "%s: decode error at frame %d: %s", ds->path, ds->decoded,
                                  av_err(r, eb, sizeof eb));
        pg_status st = take_frame(ds, frame);
        av_frame_unref(frame);
        if (st) return st;
    }
}

/* Frames are used in order and timed at the average rate: right for constant-rate video, a
 * distortion of the motion's timing for variable-rate phone footage, so say so (once per file;
 * every stage rereads the input). Steps off by more than 25 % are not rounding jitter. */
static void warn_variable_rate(const char *path, const decode_state *ds, const AVStream *s)
{
    static char warned[512];
    if (ds->min_step <= 0 || ds->max_step * 4 <= ds->min_step * 5 || strncmp(warned, path, sizeof warned - 1) == 0) return;
    snprintf(warned, sizeof warned, "%s", path);
    double tb = av_q2d(s->time_base);
    pg_warn("%s: variable frame rate (frames %.1f to %.1f ms apart); frames are used in order at the average %.2f fps, "
            "so motion timing is approximate", path, 1000.0 * tb * (double)ds->min_step, 1000.0 * tb * (double)ds->max_step,
            stream_fps(s));
}

static pg_status read_video(const char *path, const io_video_options *opt, io_frames *out)
{
    av_input in;
    PG_TRY(av_input_open(path, &in, 1));
    AVStream *s = in.fmt->streams[in.stream];
    decode_state ds;
    memset(&ds, 0, sizeof ds);
    ds.path = path;
    ds.out = out;
    ds.first = opt->first < 0 ? 0 : opt->first;
    ds.stride = opt->stride < 1 ? 1 : opt->stride;
    ds.count = opt->count > 0 ? opt->count : -1;
    ds.rotation = stream_rotation(s);
    ds.last_pts = AV_NOPTS_VALUE;
    int swap = ds.rotation == 90 || ds.rotation == 270;
    out->src_width = swap ? in.dec->height : in.dec->width;
    out->src_height = swap ? in.dec->width : in.dec->height;
    out->fps = stream_fps(s);
    io_video_target_size(opt, out->src_width, out->src_height, &out->width, &out->height);
    ds.sw = swap ? out->height : out->width;
    ds.sh = swap ? out->width : out->height;
    if (out->width > PG_MAX_IMAGE_SIDE || out->height > PG_MAX_IMAGE_SIDE) {
        av_input_close(&in);
        return pg_fail(PG_ERR_SIZE, "%s: resize target %d x %d is out of range", path, out->width, out->height);
    }
    AVPacket *pkt = av_packet_alloc();
    AVFrame *frame = av_frame_alloc();
    pg_status st = (!pkt || !frame) ? pg_fail(PG_ERR_NOMEM, "%s: cannot allocate decoder buffers", path) : PG_OK;
    int bad_packets = 0;
    char eb[128];
    while (st == PG_OK && !selection_done(&ds)) {
        int r = av_read_frame(in.fmt, pkt);
        if (r == AVERROR_EOF) break;
        if (r < 0) { st = pg_fail(PG_ERR_FORMAT, "%s: read error after frame %d: %s", path, ds.decoded, av_err(r, eb, sizeof eb)); break; }
        if (pkt->stream_index == in.stream) {
            r = avcodec_send_packet(in.dec, pkt);
            if (r < 0 && r != AVERROR(EAGAIN)) {
                /* One damaged packet is tolerated (decoders conceal); many mean a garbled file. */
                if (++bad_packets > 8)
                    st = pg_fail(PG_ERR_FORMAT, "%s: garbled video data near frame %d: %s", path, ds.decoded,
                                 av_err(r, eb, sizeof eb));
            }
            if (st == PG_OK) st = drain(&ds, in.dec, frame);
        }
        av_packet_unref(pkt);
    }
    if (st == PG_OK && !selection_done(&ds)) {
        avcodec_send_packet(in.dec, NULL); /* flush delayed frames */
        st = drain(&ds, in.dec, frame);
    }
    if (st == PG_OK) {
        int want = ds.count;
        if (out->count == 0)
            st = pg_fail(PG_ERR_FORMAT, "%s: no frames decoded (decoded %d, first %d): file empty, garbled or truncated",
                         path, ds.decoded, ds.first);
        else if (want > 0 && out->count < want && s->nb_frames > 0 && ds.decoded < s->nb_frames)
            st = pg_fail(PG_ERR_FORMAT, "%s: truncated: header says %lld frames, only %d decode", path,
                         (long long)s->nb_frames, ds.decoded); /* what was asked came from the header */
        else if (want > 0 && out->count < want)
            st = pg_fail(PG_ERR_ARG, "%s: asked for %d frames from %d with stride %d, but only %d exist", path, want,
                         ds.first, ds.stride, out->count);
        else if (want < 0 && s->nb_frames > 0 && ds.decoded < s->nb_frames)
            st = pg_fail(PG_ERR_FORMAT, "%s: truncated: header says %lld frames, only %d decode", path,
                         (long long)s->nb_frames, ds.decoded);
    }
    if (st == PG_OK) warn_variable_rate(path, &ds, s);
    if (st == PG_OK && ds.cap > out->count) {
        uint8_t *nb = realloc(out->rgb, (size_t)out->width * out->height * 3 * (size_t)out->count);
        if (nb) out->rgb = nb;
    }
    sws_freeContext(ds.sws);
    free(ds.tmp);
    av_frame_free(&frame);
    av_packet_free(&pkt);
    av_input_close(&in);
    return st;
}

pg_status io_frames_read(const char *path, const io_video_options *opt, io_frames *out)
{
    memset(out, 0, sizeof *out);
    io_video_options def = io_video_defaults();
    if (!opt) opt = &def;
    if (opt->width < 0 || opt->height < 0 || opt->max_side < 0 || opt->count < 0 ||
        opt->width > PG_MAX_IMAGE_SIDE || opt->height > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_ARG, "%s: bad frame selection or resize options", path);
    pg_status st = pg_path_is_dir(path) ? read_folder(path, opt, out) : read_video(path, opt, out);
    if (st != PG_OK) io_frames_destroy(out);
    return st;
}
