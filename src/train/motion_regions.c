/* motion_regions.c - boxes around the movers of each frame (see motion_regions.h). */
#include "train/motion_regions.h"

#include <stdlib.h>
#include <string.h>

/* A box in tiles, inclusive, with its moving pixels. */
typedef struct {
    int x0, y0, x1, y1, moving;
} tile_box;

static int boxes_overlap(const tile_box *a, const tile_box *b)
{
    return a->x0 <= b->x1 && b->x0 <= a->x1 && a->y0 <= b->y1 && b->y0 <= a->y1;
}

/* The 8-connected groups of active tiles, each as its box one tile wider on every side (the SSIM
 * window and the mover's edges need context), boxes that then overlap merged: separate movers
 * get separate crops, so a crop of one does not pay for the still floor between them. Returns
 * the number of boxes written to out (at most tw * th); label and stack are scratch (tw * th). */
static int frame_boxes(const int *count, int tw, int th, int *label, int *stack, tile_box *out)
{
    const int n = tw * th;
    for (int i = 0; i < n; i++) label[i] = count[i] >= TRAIN_REGION_TILE_MIN ? 0 : -1;
    int nb = 0;
    for (int seed = 0; seed < n; seed++) {
        if (label[seed] != 0) continue;
        tile_box b = { tw, th, -1, -1, 0 };
        int top = 0;
        stack[top++] = seed;
        label[seed] = 1;
        while (top > 0) {
            int i = stack[--top], tx = i % tw, ty = i / tw;
            b.x0 = tx < b.x0 ? tx : b.x0, b.x1 = tx > b.x1 ? tx : b.x1;
            b.y0 = ty < b.y0 ? ty : b.y0, b.y1 = ty > b.y1 ? ty : b.y1;
            b.moving += count[i];
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int x = tx + dx, y = ty + dy;
                    if (x < 0 || y < 0 || x >= tw || y >= th || label[y * tw + x] != 0) continue;
                    label[y * tw + x] = 1;
                    stack[top++] = y * tw + x;
                }
        }
        b.x0 = b.x0 > 0 ? b.x0 - 1 : 0, b.y0 = b.y0 > 0 ? b.y0 - 1 : 0;
        b.x1 = b.x1 < tw - 1 ? b.x1 + 1 : b.x1, b.y1 = b.y1 < th - 1 ? b.y1 + 1 : b.y1;
        out[nb++] = b;
    }
    for (int merged = 1; merged;) {
        merged = 0;
        for (int i = 0; i < nb && !merged; i++)
            for (int j = i + 1; j < nb && !merged; j++)
                if (boxes_overlap(&out[i], &out[j])) {
                    tile_box *a = &out[i], *b = &out[j];
                    a->x0 = b->x0 < a->x0 ? b->x0 : a->x0, a->y0 = b->y0 < a->y0 ? b->y0 : a->y0;
                    a->x1 = b->x1 > a->x1 ? b->x1 : a->x1, a->y1 = b->y1 > a->y1 ? b->y1 : a->y1;
                    a->moving += b->moving;
                    out[j] = out[--nb];
                    merged = 1;
                }
    }
    return nb;
}

pg_status train_motion_regions_find(const uint8_t *moving, int frames, int width, int height, train_motion_regions *r)
{
    memset(r, 0, sizeof *r);
    const int T = TRAIN_REGION_TILE, tw = (width + T - 1) / T, th = (height + T - 1) / T, n = tw * th;
    r->frames = frames, r->width = width, r->height = height;
    r->start = pg_calloc((size_t)frames + 1, sizeof *r->start, "moving regions");
    int *count = pg_malloc((size_t)n * 3 * sizeof *count, "moving regions");
    tile_box *fb = pg_malloc((size_t)n * sizeof *fb, "moving regions");
    int cap = 0;
    pg_status st = PG_OK;
    if (!r->start || !count || !fb) {
        st = PG_ERR_NOMEM;
        goto done;
    }
    for (int f = 0; f < frames; f++) {
        const uint8_t *mv = moving + (size_t)f * width * height;
        memset(count, 0, (size_t)n * sizeof *count);
        for (int y = 0; y < height; y++)
            for (int x = 0; x < width; x++) count[(y / T) * tw + x / T] += mv[(size_t)y * width + x] != 0;
        int nb = frame_boxes(count, tw, th, count + n, count + 2 * n, fb);
        int total = r->start[f];
        if (total + nb > cap) {
            int nc = 2 * cap > total + nb ? 2 * cap : total + nb + 64;
            train_region *grown = realloc(r->boxes, (size_t)nc * sizeof *grown);
            if (!grown) {
                st = pg_fail(PG_ERR_NOMEM, "out of memory for moving regions");
                goto done;
            }
            r->boxes = grown, cap = nc;
        }
        for (int k = 0; k < nb; k++) {
            train_region *o = &r->boxes[total + k];
            o->x = fb[k].x0 * T, o->y = fb[k].y0 * T;
            o->w = ((fb[k].x1 + 1) * T < width ? (fb[k].x1 + 1) * T : width) - o->x;
            o->h = ((fb[k].y1 + 1) * T < height ? (fb[k].y1 + 1) * T : height) - o->y;
            o->moving = fb[k].moving;
        }
        r->start[f + 1] = total + nb;
        r->frames_with_motion += nb > 0;
    }
done:
    free(count);
    free(fb);
    if (st) train_motion_regions_destroy(r);
    return st;
}

void train_motion_regions_destroy(train_motion_regions *r)
{
    free(r->start);
    free(r->boxes);
    memset(r, 0, sizeof *r);
}

const train_region *train_motion_regions_draw(const train_motion_regions *r, pg_rng *rng, int *frame)
{
    if (r->frames_with_motion == 0) return NULL;
    int k = (int)pg_rng_below(rng, (uint32_t)r->frames_with_motion), f = 0;
    for (; f < r->frames; f++)
        if (r->start[f + 1] > r->start[f] && k-- == 0) break;
    long total = 0;
    for (int i = r->start[f]; i < r->start[f + 1]; i++) total += r->boxes[i].moving;
    long pick = (long)(pg_rng_uniform(rng) * (double)total);
    int i = r->start[f];
    for (; i < r->start[f + 1] - 1; i++) {
        pick -= r->boxes[i].moving;
        if (pick < 0) break;
    }
    *frame = f;
    return &r->boxes[i];
}

double train_motion_regions_mean_area(const train_motion_regions *r)
{
    double area = 0;
    for (int i = 0; r->start && i < r->start[r->frames]; i++) area += (double)r->boxes[i].w * r->boxes[i].h;
    return r->frames_with_motion ? area / r->frames_with_motion / ((double)r->width * r->height) : 0;
}
