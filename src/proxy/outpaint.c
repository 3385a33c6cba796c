/* outpaint.c - border extension of an RGB-D frame (see outpaint.h). */
#include "proxy/outpaint.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/mathx.h"

#define FIT_PX 16        /* cells from the border used for the inverse-depth line fit */
#define SAME_SURFACE 0.1f /* relative inverse-depth difference to the border value still fitted */
#define SLOPE_RADIUS 4    /* lines the slope is averaged over, each side */

/* A set of parallel lines in a padded image: line l, cell i sits at l * line_step + i * cell_step
 * (in pixels). Cells [pad, pad + len) are known, the pad cells on both ends get filled. */
typedef struct {
    float *rgb; /* (H2, W2, 3) */
    float *id;  /* (H2, W2) inverse depth, 0 = invalid */
    size_t line_step, cell_step;
    int first_line, lines, pad, len;
    float id_lo, id_hi; /* clamp range of the continued inverse depth */
} line_set;

typedef struct {
    float a, b;  /* inverse depth at the border cell and its change per cell outward */
    int ok;      /* a line fit exists */
    float rgb[3]; /* border colour */
} border_fit;

/* Least-squares line through the border cells of one line on the border's surface. `dir` = +1 for
 * the far end (cells counted outward to larger i), -1 for the near end. */
static border_fit fit_border(const line_set *s, int line, int dir)
{
    border_fit f = { 0, 0, 0, { 0, 0, 0 } };
    size_t base = (size_t)line * s->line_step;
    int border = dir > 0 ? s->pad + s->len - 1 : s->pad;
    int n_fit = s->len < FIT_PX ? s->len : FIT_PX;
    for (int j = 0; j < 2 && j < s->len; j++) {
        const float *c = s->rgb + (base + (size_t)(border - dir * j) * s->cell_step) * 3;
        for (int k = 0; k < 3; k++) f.rgb[k] += c[k] / (s->len < 2 ? 1 : 2);
    }
    float ref = 0;
    for (int j = 0; j < 3 && j < n_fit && !(ref > 0); j++) ref = s->id[base + (size_t)(border - dir * j) * s->cell_step];
    if (!(ref > 0)) return f;
    double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (int j = 0; j < n_fit; j++) {
        float v = s->id[base + (size_t)(border - dir * j) * s->cell_step];
        if (!(v > 0) || fabsf(v - ref) > SAME_SURFACE * ref) continue;
        double x = -j; /* outward coordinate: border cell 0, inward negative */
        sw += 1; sx += x; sy += v; sxx += x * x; sxy += x * v;
    }
    if (sw < 1) return f;
    double det = sw * sxx - sx * sx;
    if (sw >= 4 && det > 1e-9) {
        f.b = (float)((sw * sxy - sx * sy) / det);
        f.a = (float)((sy - f.b * sx) / sw);
    } else {
        f.a = (float)(sy / sw);
    }
    f.ok = f.a > 0;
    return f;
}

/* Fills both pad ends of every line of s. */
static pg_status extend_lines(const line_set *s)
{
    int L = s->lines;
    border_fit *bf = pg_malloc((size_t)L * sizeof *bf, "outpaint border fits"); /* one side at a time */
    double *prefix = pg_malloc((size_t)(L + 1) * 3 * sizeof(double), "outpaint colour sums");
    float *slope = pg_malloc((size_t)L * sizeof(float), "outpaint slopes");
    if (!bf || !prefix || !slope) {
        free(bf);
        free(prefix);
        free(slope);
        return PG_ERR_NOMEM;
    }
    for (int side = 0; side < 2; side++) {
        int dir = side ? 1 : -1;
        for (int l = 0; l < L; l++) bf[l] = fit_border(s, s->first_line + l, dir);
        /* slope averaged over neighbouring lines (read from the unsmoothed copy in `slope`): one noisy
         * line would otherwise fan out */
        for (int l = 0; l < L; l++) slope[l] = bf[l].b;
        for (int l = 0; l < L; l++) {
            double sb = 0;
            int cnt = 0;
            for (int m = l - SLOPE_RADIUS; m <= l + SLOPE_RADIUS; m++)
                if (m >= 0 && m < L && bf[m].ok) {
                    sb += slope[m];
                    cnt++;
                }
            if (bf[l].ok) bf[l].b = (float)(sb / cnt);
        }
        for (int k = 0; k < 3; k++) prefix[k] = 0;
        for (int l = 0; l < L; l++)
            for (int k = 0; k < 3; k++) prefix[(size_t)(l + 1) * 3 + k] = prefix[(size_t)l * 3 + k] + bf[l].rgb[k];
        int border = dir > 0 ? s->pad + s->len - 1 : s->pad;
        for (int l = 0; l < L; l++) {
            size_t base = (size_t)(s->first_line + l) * s->line_step;
            for (int d = 1; d <= s->pad; d++) {
                size_t cell = base + (size_t)(border + dir * d) * s->cell_step;
                int r = 1 + d / 2, lo = l - r < 0 ? 0 : l - r, hi = l + r >= L ? L - 1 : l + r;
                for (int k = 0; k < 3; k++)
                    s->rgb[cell * 3 + k] =
                        (float)((prefix[(size_t)(hi + 1) * 3 + k] - prefix[(size_t)lo * 3 + k]) / (hi - lo + 1));
                float v = 0;
                if (bf[l].ok) {
                    v = bf[l].a + bf[l].b * d;
                    v = clampf(v, fmaxf(0.5f * bf[l].a, s->id_lo), fminf(2.0f * bf[l].a, s->id_hi));
                }
                s->id[cell] = v;
            }
        }
    }
    free(bf);
    free(prefix);
    free(slope);
    return PG_OK;
}

pg_status proxy_outpaint(int W, int H, const float *rgb, const float *depth, int pad, float *rgb_out,
                         float *depth_out)
{
    if (W < 1 || H < 1 || pad < 0) return pg_fail(PG_ERR_ARG, "outpaint: bad size %dx%d pad %d", W, H, pad);
    int W2 = W + 2 * pad, H2 = H + 2 * pad;
    size_t n2 = (size_t)W2 * H2;
    memset(rgb_out, 0, n2 * 3 * sizeof(float));
    float id_min = INFINITY, id_max = 0;
    for (int y = 0; y < H; y++) {
        memcpy(rgb_out + ((size_t)(y + pad) * W2 + pad) * 3, rgb + (size_t)y * W * 3, (size_t)W * 3 * sizeof(float));
        for (int x = 0; x < W; x++) {
            float d = depth[(size_t)y * W + x];
            float v = isfinite(d) && d > 0 ? 1.0f / d : 0;
            depth_out[(size_t)(y + pad) * W2 + x + pad] = v; /* inverse depth while extending */
            if (v > 0) {
                id_min = fminf(id_min, v);
                id_max = fmaxf(id_max, v);
            }
        }
    }
    if (pad > 0) {
        line_set s = { rgb_out, depth_out, 0, 1, 0, 0, pad, 0, 0.5f * id_min, 2.0f * id_max };
        if (!(id_max > 0)) s.id_lo = s.id_hi = 0;
        /* rows of the frame first (left/right margins), then full columns (top/bottom and corners) */
        s.line_step = (size_t)W2;
        s.cell_step = 1;
        s.first_line = pad;
        s.lines = H;
        s.len = W;
        PG_TRY(extend_lines(&s));
        s.line_step = 1;
        s.cell_step = (size_t)W2;
        s.first_line = 0;
        s.lines = W2;
        s.len = H;
        PG_TRY(extend_lines(&s));
    }
    for (size_t i = 0; i < n2; i++) depth_out[i] = depth_out[i] > 0 ? 1.0f / depth_out[i] : 0;
    return PG_OK;
}
