/* test_deform.c - HexPlane sampling, Linear layers and the whole deformation network:
 * float analytic gradients vs central finite differences of double-precision references,
 * t-invariance at init, identity at init, chunking/storage/thread determinism, blob round trip,
 * zeroed packing padding and the same bytes whatever the heap held.
 *
 * Tolerance: |g - fd| / max(|g|, |fd|, 1e-2 * max|fd|) < 1e-3 (see test_loss.c). FD steps: 1e-6
 * in double, small enough that no ReLU kink or bilinear cell edge is crossed for the random inputs
 * (positions are kept >= 1e-3 cells away from grid lines).
 */
#include "testlib.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "core/status.h"
#include "deform/deform.h"
#include "deform/gemm_amx.h"
#include "deform/hexplane.h"
#include "deform/mlp.h"
#include "optim/loss_reg.h"

#if defined(__GLIBC__)
#include <malloc.h> /* mallopt(M_PERTURB) */
#endif
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------------------------------------- */
/* double reference of the network, reading parameters from a double copy laid out like net->params */

typedef struct {
    const deform_network *net; /* layout only */
    const double *p;           /* (num_params) */
} ref_net;

static double ref_bilinear(const double *pl, int Wp, int C, int c, double ga, double gb, int resa, int resb)
{
    int ia = (int)ga, ib = (int)gb;
    if (ia > resa - 2) ia = resa - 2;
    if (ib > resb - 2) ib = resb - 2;
    double wa = ga - ia, wb = gb - ib;
    const double *t = pl + ((size_t)ib * Wp + ia) * C + c;
    return (1 - wa) * (1 - wb) * t[0] + wa * (1 - wb) * t[C] + (1 - wa) * wb * t[(size_t)Wp * C] +
           wa * wb * t[(size_t)Wp * C + C];
}

static void ref_hex(double *feat, const ref_net *r, const double *pos, double t)
{
    const hex_grid *g = &r->net->grid;
    for (int s = 0; s < g->S; s++)
        for (int c = 0; c < g->C; c++) {
            double prod = 1;
            for (int p = 0; p < HEX_PLANES; p++) {
                int a = hex_plane_axes[p][0], b = hex_plane_axes[p][1];
                double coord[2];
                int res[2];
                for (int k = 0; k < 2; k++) {
                    int d = k ? b : a;
                    double u = d == 3 ? t : (pos[d] - g->aabb[d]) / ((double)g->aabb[3 + d] - g->aabb[d]);
                    u = fmin(1.0, fmax(0.0, u));
                    res[k] = hex_axis_res(g, s, d);
                    coord[k] = u * (res[k] - 1);
                }
                prod *= ref_bilinear(r->p + r->net->plane_off[s][p], res[0], g->C, c, coord[0], coord[1], res[0], res[1]);
            }
            feat[s * g->C + c] = prod;
        }
}

static void ref_linear(double *y, const double *x, const ref_net *r, const deform_layer *L, int relu)
{
    for (int o = 0; o < L->out; o++) {
        double s = r->p[L->b_off + o];
        for (int i = 0; i < L->in; i++) s += r->p[L->w_off + (size_t)o * L->in + i] * x[i];
        y[o] = relu && s < 0 ? 0 : s;
    }
}

/* out (59) for one point */
static void ref_network(double *out, const ref_net *r, const double *pos, double t)
{
    const deform_network *net = r->net;
    int Wh = deform_head_width(&net->cfg);
    double x[4096], y[4096];
    ref_hex(x, r, pos, t);
    for (int l = 0; l < net->num_layers; l++) {
        ref_linear(y, x, r, &net->layers[l], 1);
        memcpy(x, y, net->layers[l].out * sizeof(double));
    }
    for (int h = 0; h < DEFORM_HEADS; h++) ref_linear(out + deform_head_offset[h], x + h * Wh, r, &net->heads[h], 0);
}

/* ---------------------------------------------------------------------------------------------- */

static void small_config(deform_config *cfg)
{
    deform_config_default(cfg);
    cfg->channels = 3;
    cfg->res_space = 4;
    cfg->num_scales = 2;
    cfg->res_time = 5;
    cfg->time_coarsen = 1; /* the coarse scale has 3 time rows, the fine one 5: both paths FD-checked */
    cfg->width = 8;
    cfg->feature_layers = 2;
    cfg->head_init_scale = 1.0f;
    cfg->seed = 5;
    cfg->bf16 = 0; /* the FD checks are for the exact f32 path; bf16 is compared to it separately */
}

/* Random position inside the aabb, at least 1e-3 cells away from every grid line of every scale. */
static void random_pos(pg_rng *rng, const hex_grid *g, float *pos)
{
    for (int d = 0; d < 3; d++) {
        for (;;) {
            double u = pg_rng_range(rng, 0.02, 0.98);
            int ok = 1;
            for (int s = 0; s < g->S; s++) {
                double c = u * ((g->R << s) - 1);
                if (fabs(c - floor(c + 0.5)) < 1e-3) ok = 0;
            }
            if (ok) {
                pos[d] = (float)(g->aabb[d] + u * (g->aabb[3 + d] - g->aabb[d]));
                break;
            }
        }
    }
}

static void randomize_planes(deform_network *net, pg_rng *rng)
{
    for (size_t i = 0; i < net->num_plane_params; i++) net->params[i] = (float)pg_rng_range(rng, 0.5, 1.5);
}

/* A network of cfg over the cube [-1, 1]^3 with planes drawn from rng, seeded with seed first
 * (NULL, after a failed check, if it cannot be made). */
static deform_network *random_network(const deform_config *cfg, pg_rng *rng, uint64_t seed)
{
    const float aabb[6] = { -1, -1, -1, 1, 1, 1 };
    deform_network *net = NULL;
    CHECK_OK(deform_network_create(&net, cfg, aabb));
    if (!net) return NULL;
    pg_rng_seed(rng, seed);
    randomize_planes(net, rng);
    return net;
}

/* One point through the slice API: slice at t, sample (and, with d_planes, the backward with the
 * slice gradient spread onto the time rows). */
static void hex_point_forward(float *feat, const hex_grid *g, const float *pos, float t)
{
    float *buf = malloc(hex_slice_size(g) * sizeof(float));
    hex_slice sl;
    hex_point hp;
    hex_slice_layout(&sl, buf, g, t);
    hex_slice_forward(&sl, g);
    hex_point_setup(&hp, g, pos);
    hex_sample_forward_point(feat, g, &sl, &hp);
    free(buf);
}

static void hex_point_backward(float *const d_planes[HEX_MAX_SCALES][HEX_PLANES], float *d_pos, const float *d_feat,
                               const hex_grid *g, const float *pos, float t)
{
    float *buf = malloc(hex_slice_size(g) * sizeof(float)), *dbuf = calloc(hex_slice_size(g), sizeof(float));
    hex_slice sl, dsl;
    hex_point hp;
    hex_slice_layout(&sl, buf, g, t);
    hex_slice_forward(&sl, g);
    hex_slice_layout(&dsl, dbuf, g, t);
    hex_point_setup(&hp, g, pos);
    hex_sample_backward_point(d_planes, &dsl, d_pos, d_feat, g, &sl, &hp);
    hex_slice_backward(d_planes, &dsl, g);
    free(buf);
    free(dbuf);
}

static void test_hexplane(void)
{
    deform_config cfg;
    small_config(&cfg);
    const float aabb[6] = { -1, -2, 0.5f, 2, 1, 3 };
    deform_network *net = NULL;
    CHECK_OK(deform_network_create(&net, &cfg, aabb));
    if (!net) return;
    pg_rng rng;
    pg_rng_seed(&rng, 17);
    /* t-invariance at init: time planes are 1 */
    float pos[3], f0[64], f1[64];
    random_pos(&rng, &net->grid, pos);
    hex_point_forward(f0, &net->grid, pos, 0.1f);
    hex_point_forward(f1, &net->grid, pos, 0.83f);
    int F = cfg.channels * cfg.num_scales;
    CHECK(memcmp(f0, f1, F * sizeof(float)) == 0, "features depend on t with time planes = 1");
    int inrange = 1;
    for (int i = 0; i < F; i++) inrange &= f0[i] >= 0.1f * 0.1f * 0.1f - 1e-6f && f0[i] <= 0.125f + 1e-6f;
    CHECK(inrange, "init features outside [0.1^3, 0.5^3]");

    randomize_planes(net, &rng);
    const size_t P = net->num_plane_params;
    double *pd = malloc(P * sizeof(double)), *fd = malloc(P * sizeof(double));
    float *gp = calloc(P, sizeof(float));
    for (size_t i = 0; i < P; i++) pd[i] = net->params[i];
    ref_net r = { net, pd };
    double wsum[64];
    float dfeat[64];
    for (int i = 0; i < F; i++) { wsum[i] = pg_rng_range(&rng, -1, 1); dfeat[i] = (float)wsum[i]; }
    const float t = 0.37f;
    const int npts = 3;
    float pts[3][3];
    for (int k = 0; k < npts; k++) random_pos(&rng, &net->grid, pts[k]);
    /* float forward vs double reference */
    double worst_f = 0;
    for (int k = 0; k < npts; k++) {
        double pos_d[3] = { pts[k][0], pts[k][1], pts[k][2] }, fr[64];
        hex_point_forward(f0, &net->grid, pts[k], t);
        ref_hex(fr, &r, pos_d, t);
        for (int i = 0; i < F; i++) worst_f = fmax(worst_f, fabs(f0[i] - fr[i]) / fmax(1e-3, fabs(fr[i])));
    }
    CHECK(worst_f < 1e-5, "hexplane forward vs reference rel err %g", worst_f);
    /* gradient w.r.t. plane values: L = sum_k sum_i wsum_i feat_k,i */
    float *dpl[HEX_MAX_SCALES][HEX_PLANES];
    for (int s = 0; s < cfg.num_scales; s++)
        for (int p = 0; p < HEX_PLANES; p++) dpl[s][p] = gp + net->plane_off[s][p];
    float dpos[3][3] = { { 0 } };
    for (int k = 0; k < npts; k++) hex_point_backward(dpl, dpos[k], dfeat, &net->grid, pts[k], t);
    const double h = 1e-6;
    for (size_t i = 0; i < P; i++) {
        double v = pd[i], L[2];
        for (int sgn = 0; sgn < 2; sgn++) {
            pd[i] = v + (sgn ? -h : h);
            L[sgn] = 0;
            for (int k = 0; k < npts; k++) {
                double pos_d[3] = { pts[k][0], pts[k][1], pts[k][2] }, fr[64];
                ref_hex(fr, &r, pos_d, t);
                for (int j = 0; j < F; j++) L[sgn] += wsum[j] * fr[j];
            }
        }
        pd[i] = v;
        fd[i] = (L[0] - L[1]) / (2 * h);
    }
    double e_plane = test_grad_err(gp, fd, P);
    CHECK(e_plane < 1e-3, "hexplane d/dplanes rel err %g", e_plane);
    /* gradient w.r.t. positions */
    double e_pos = 0;
    for (int k = 0; k < npts; k++) {
        double fdp[3];
        for (int d = 0; d < 3; d++) {
            double L[2];
            for (int sgn = 0; sgn < 2; sgn++) {
                double pos_d[3] = { pts[k][0], pts[k][1], pts[k][2] }, fr[64];
                pos_d[d] += sgn ? -h : h;
                ref_hex(fr, &r, pos_d, t);
                L[sgn] = 0;
                for (int j = 0; j < F; j++) L[sgn] += wsum[j] * fr[j];
            }
            fdp[d] = (L[0] - L[1]) / (2 * h);
        }
        e_pos = fmax(e_pos, test_grad_err(dpos[k], fdp, 3));
    }
    CHECK(e_pos < 1e-3, "hexplane d/dpos rel err %g", e_pos);
    /* outside the AABB: border clamp, zero position gradient */
    float out_pos[3] = { 5, -7, 10 }, dp_out[3] = { 0, 0, 0 };
    hex_point_backward(dpl, dp_out, dfeat, &net->grid, out_pos, t);
    CHECK(dp_out[0] == 0 && dp_out[1] == 0 && dp_out[2] == 0, "clamped position has gradient %g %g %g", dp_out[0],
          dp_out[1], dp_out[2]);
    printf("hexplane: forward rel err %.2e, d/dplanes %.2e, d/dpos %.2e\n", worst_f, e_plane, e_pos);
    free(pd); free(fd); free(gp);
    deform_network_destroy(net);
}

static void test_linear(void)
{
    enum { M = 5, IN = 7, OUT = 6 };
    pg_rng rng;
    pg_rng_seed(&rng, 4);
    float x[M * IN], w[OUT * IN], b[OUT], y[M * OUT], yr[M * OUT], dy[M * OUT], dy2[M * OUT];
    for (int i = 0; i < M * IN; i++) x[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int i = 0; i < OUT * IN; i++) w[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int i = 0; i < OUT; i++) b[i] = (float)pg_rng_range(&rng, -0.3, 0.3);
    for (int i = 0; i < M * OUT; i++) dy[i] = dy2[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int relu = 0; relu < 2; relu++) {
        mlp_linear_forward(y, OUT, x, IN, w, b, M, IN, OUT, relu);
        mlp_linear_forward_ref(yr, OUT, x, IN, w, b, M, IN, OUT, relu);
        double ef = 0;
        for (int i = 0; i < M * OUT; i++) ef = fmax(ef, fabs(y[i] - yr[i]));
        CHECK(ef < 1e-5, "linear blas vs ref forward %g (relu %d)", ef, relu);
        /* double FD of L = sum dy * linear(x) w.r.t. x, w, b */
        float dx[M * IN], dw[OUT * IN] = { 0 }, db[OUT] = { 0 };
        float dxr[M * IN], dwr[OUT * IN] = { 0 }, dbr[OUT] = { 0 };
        memcpy(dy2, dy, sizeof(dy));
        float dyc[M * OUT];
        memcpy(dyc, dy, sizeof(dy));
        mlp_linear_backward(dx, IN, dw, db, dyc, OUT, y, OUT, x, IN, w, M, IN, OUT, relu);
        mlp_linear_backward_ref(dxr, IN, dwr, dbr, dy2, OUT, yr, OUT, x, IN, w, M, IN, OUT, relu);
        double eb = 0;
        for (int i = 0; i < M * IN; i++) eb = fmax(eb, fabs(dx[i] - dxr[i]));
        for (int i = 0; i < OUT * IN; i++) eb = fmax(eb, fabs(dw[i] - dwr[i]));
        for (int i = 0; i < OUT; i++) eb = fmax(eb, fabs(db[i] - dbr[i]));
        CHECK(eb < 1e-5, "linear blas vs ref backward %g", eb);
        double xd[M * IN], wd[OUT * IN], bd[OUT];
        for (int i = 0; i < M * IN; i++) xd[i] = x[i];
        for (int i = 0; i < OUT * IN; i++) wd[i] = w[i];
        for (int i = 0; i < OUT; i++) bd[i] = b[i];
        double *vars[3] = { xd, wd, bd };
        int nv[3] = { M * IN, OUT * IN, OUT };
        float *an[3] = { dx, dw, db };
        const char *nm[3] = { "x", "w", "b" };
        for (int v = 0; v < 3; v++) {
            double fd[M * IN > OUT * IN ? M * IN : OUT * IN];
            for (int i = 0; i < nv[v]; i++) {
                double s0 = vars[v][i], L[2];
                for (int sgn = 0; sgn < 2; sgn++) {
                    vars[v][i] = s0 + (sgn ? -1e-6 : 1e-6);
                    L[sgn] = 0;
                    for (int m = 0; m < M; m++)
                        for (int o = 0; o < OUT; o++) {
                            double s = bd[o];
                            for (int k = 0; k < IN; k++) s += wd[o * IN + k] * xd[m * IN + k];
                            if (relu && s < 0) s = 0;
                            L[sgn] += dy[m * OUT + o] * s;
                        }
                }
                vars[v][i] = s0;
                fd[i] = (L[0] - L[1]) / 2e-6;
            }
            double e = test_grad_err(an[v], fd, nv[v]);
            CHECK(e < 1e-3, "linear d/d%s rel err %g (relu %d)", nm[v], e, relu);
            printf("linear (relu %d): d/d%s rel err %.2e\n", relu, nm[v], e);
        }
    }
}

/* Whole network: L = sum_i sum_j r_ij out_ij over a subset of points given by idx. */
/* head_width: 0 (= the width, 8) or another hidden width of the heads. */
static void test_network_fd(int head_width)
{
    deform_config cfg;
    small_config(&cfg);
    cfg.head_width = head_width;
    pg_rng rng;
    deform_network *net = random_network(&cfg, &rng, 23);
    if (!net) return;
    enum { N = 9, M = 7 };
    float means[N * 3];
    for (int i = 0; i < N; i++) random_pos(&rng, &net->grid, means + 3 * i);
    const int idx[M] = { 8, 0, 3, 4, 1, 6, 7 }; /* points 2 and 5 are "static" */
    const float t = 0.61f;
    deform_ws *ws = NULL;
    CHECK_OK(deform_ws_create_chunked(&ws, net, 3, 3)); /* 1 chunk stored, 2 recomputed, last partial */
    if (!ws) return;
    float out[M * DEFORM_OUT_DIM], dout[M * DEFORM_OUT_DIM], dmeans[N * 3] = { 0 };
    double r[M * DEFORM_OUT_DIM];
    for (int i = 0; i < M * DEFORM_OUT_DIM; i++) { r[i] = pg_rng_range(&rng, -1, 1); dout[i] = (float)r[i]; }
    CHECK_OK(deform_network_forward(net, ws, means, idx, M, t, out));
    deform_network_zero_grad(net);
    CHECK_OK(deform_network_backward(net, ws, dout, dmeans));

    const size_t P = net->num_params;
    double *pd = malloc(P * sizeof(double));
    for (size_t i = 0; i < P; i++) pd[i] = net->params[i];
    ref_net rn = { net, pd };
    double worst_out = 0;
    for (int i = 0; i < M; i++) {
        double pos[3] = { means[3 * idx[i]], means[3 * idx[i] + 1], means[3 * idx[i] + 2] }, o[DEFORM_OUT_DIM];
        ref_network(o, &rn, pos, t);
        for (int j = 0; j < DEFORM_OUT_DIM; j++)
            worst_out = fmax(worst_out, fabs(o[j] - out[i * DEFORM_OUT_DIM + j]) / fmax(1e-2, fabs(o[j])));
    }
    CHECK(worst_out < 1e-4, "network forward vs double reference %g", worst_out);

    /* FD over every parameter (the small net has ~1.5k) */
    double *fd = malloc(P * sizeof(double));
    const double h = 1e-6;
    for (size_t k = 0; k < P; k++) {
        double v = pd[k], L[2];
        for (int sgn = 0; sgn < 2; sgn++) {
            pd[k] = v + (sgn ? -h : h);
            L[sgn] = 0;
            for (int i = 0; i < M; i++) {
                double pos[3] = { means[3 * idx[i]], means[3 * idx[i] + 1], means[3 * idx[i] + 2] }, o[DEFORM_OUT_DIM];
                ref_network(o, &rn, pos, t);
                for (int j = 0; j < DEFORM_OUT_DIM; j++) L[sgn] += r[i * DEFORM_OUT_DIM + j] * o[j];
            }
        }
        pd[k] = v;
        fd[k] = (L[0] - L[1]) / (2 * h);
    }
    double e_planes = test_grad_err(net->grads, fd, net->num_plane_params);
    double e_mlp = test_grad_err(net->grads + net->num_plane_params, fd + net->num_plane_params, P - net->num_plane_params);
    CHECK(e_planes < 1e-3, "network d/dplanes rel err %g", e_planes);
    CHECK(e_mlp < 1e-3, "network d/dmlp rel err %g", e_mlp);
    /* positions */
    double fdm[N * 3];
    for (int i = 0; i < N * 3; i++) {
        double L[2];
        for (int sgn = 0; sgn < 2; sgn++) {
            L[sgn] = 0;
            for (int q = 0; q < M; q++) {
                double pos[3] = { means[3 * idx[q]], means[3 * idx[q] + 1], means[3 * idx[q] + 2] }, o[DEFORM_OUT_DIM];
                if (3 * idx[q] == i - i % 3) pos[i % 3] += sgn ? -h : h;
                ref_network(o, &rn, pos, t);
                for (int j = 0; j < DEFORM_OUT_DIM; j++) L[sgn] += r[q * DEFORM_OUT_DIM + j] * o[j];
            }
        }
        fdm[i] = (L[0] - L[1]) / (2 * h);
    }
    double e_pos = test_grad_err(dmeans, fdm, N * 3);
    CHECK(e_pos < 1e-3, "network d/dmeans rel err %g", e_pos);
    CHECK(dmeans[6] == 0 && dmeans[15] == 0, "static points got position gradients");
    printf("network (head width %d): forward %.2e, d/dplanes %.2e, d/dmlp %.2e, d/dmeans %.2e (%zu params)\n",
           deform_head_width(&cfg), worst_out, e_planes, e_mlp, e_pos, P);

    /* stored vs recomputed activations and thread counts: same gradients */
    float *g1 = malloc(P * sizeof(float));
    memcpy(g1, net->grads, P * sizeof(float));
    deform_ws *ws_all = NULL;
    CHECK_OK(deform_ws_create_chunked(&ws_all, net, M, 3));
    float out2[M * DEFORM_OUT_DIM], dm2[N * 3] = { 0 };
    CHECK_OK(deform_network_forward(net, ws_all, means, idx, M, t, out2));
    deform_network_zero_grad(net);
    CHECK_OK(deform_network_backward(net, ws_all, dout, dm2));
    CHECK(memcmp(out, out2, sizeof(out)) == 0 && memcmp(g1, net->grads, P * sizeof(float)) == 0 &&
          memcmp(dmeans, dm2, sizeof(dm2)) == 0, "stored and recomputed activations disagree");
    deform_ws_destroy(ws_all);

    pg_set_threads(2);
    double maxdiff = 0;
    float *g2 = malloc(P * sizeof(float));
    for (int rep = 0; rep < 2; rep++) {
        deform_ws *w2 = NULL;
        CHECK_OK(deform_ws_create_chunked(&w2, net, 0, 2));
        CHECK_OK(deform_network_forward(net, w2, means, idx, M, t, out2));
        deform_network_zero_grad(net);
        CHECK_OK(deform_network_backward(net, w2, dout, NULL));
        if (rep == 0) memcpy(g2, net->grads, P * sizeof(float));
        else CHECK(memcmp(g2, net->grads, P * sizeof(float)) == 0, "two runs with 2 threads differ");
        deform_ws_destroy(w2);
    }
    double gmax = 0;
    for (size_t i = 0; i < P; i++) gmax = fmax(gmax, fabs(g1[i]));
    for (size_t i = 0; i < P; i++) maxdiff = fmax(maxdiff, test_rel_err(g1[i], g2[i], 1e-2 * gmax));
    CHECK(maxdiff < 1e-5, "1 vs 2 threads gradients differ by %g", maxdiff);
    pg_set_threads(1);
    free(g1); free(g2); free(pd); free(fd);
    deform_ws_destroy(ws);
    deform_network_destroy(net);
}

static void test_identity_blob_reg(void)
{
    deform_config cfg;
    deform_config_default(&cfg);
    cfg.res_space = 8;
    cfg.res_time = 6;
    cfg.width = 16;
    cfg.head_width = 32; /* stored in the blob */
    cfg.time_coarsen = 2; /* so is this */
    const float aabb[6] = { 0, 0, 0, 1, 1, 1 };
    deform_network *net = NULL;
    CHECK_OK(deform_network_create(&net, &cfg, aabb));
    if (!net) return;
    deform_ws *ws = NULL;
    CHECK_OK(deform_ws_create(&ws, net, 100));
    float means[30], out[10 * DEFORM_OUT_DIM];
    pg_rng rng;
    pg_rng_seed(&rng, 1);
    for (int i = 0; i < 30; i++) means[i] = (float)pg_rng_uniform(&rng);
    CHECK_OK(deform_network_forward(net, ws, means, NULL, 10, 0.5f, out));
    int zero = 1;
    for (int i = 0; i < 10 * DEFORM_OUT_DIM; i++) zero &= out[i] == 0.0f;
    CHECK(zero, "deformation at init is not the identity");
    CHECK(deform_network_forward(net, ws, means, NULL, 10, 1.5f, out) == PG_ERR_ARG, "t outside [0,1] accepted");

    /* regularisers at init: time planes are 1 => time terms 0; spatial TV > 0 */
    deform_network_zero_grad(net);
    float r0 = deform_network_regularize(net, 0, 1, 1);
    float r1 = deform_network_regularize(net, 1, 0, 0);
    CHECK(r0 == 0.0f && r1 > 0.0f, "regularisers at init: time %g, tv %g", r0, r1);
    /* random planes: the network-level sum equals the per-plane functions, for 1 and 2 threads */
    for (size_t i = 0; i < net->num_plane_params; i++) net->params[i] = (float)pg_rng_range(&rng, 0.5, 1.5);
    double expect = 0;
    for (int s = 0; s < cfg.num_scales; s++)
        for (int p = 0; p < HEX_PLANES; p++) {
            int Wp = hex_axis_res(&net->grid, s, hex_plane_axes[p][0]), Hp = hex_axis_res(&net->grid, s, hex_plane_axes[p][1]);
            const float *pl = net->grid.planes[s][p];
            if (hex_plane_axes[p][1] != 3) expect += 2e-4 * optim_plane_tv_forward(pl, Hp, Wp, cfg.channels);
            else expect += 1e-3 * optim_plane_time_smooth_forward(pl, Hp, Wp, cfg.channels) +
                           1e-4 * optim_plane_l1_one_forward(pl, Hp, Wp, cfg.channels);
        }
    float *gr1 = malloc(net->num_params * sizeof(float));
    float tot[2];
    for (int th = 1; th <= 2; th++) {
        pg_set_threads(th);
        deform_network_zero_grad(net);
        tot[th - 1] = deform_network_regularize(net, 2e-4f, 1e-3f, 1e-4f);
        if (th == 1) memcpy(gr1, net->grads, net->num_params * sizeof(float));
    }
    pg_set_threads(1);
    CHECK(fabs(tot[0] - expect) < 1e-6 * fabs(expect) && tot[0] == tot[1] &&
              memcmp(gr1, net->grads, net->num_params * sizeof(float)) == 0,
          "regularize total %.9g vs %.9g (2 threads %.9g)", tot[0], expect, tot[1]);
    free(gr1);

    /* blob round trip + corrupt blob */
    char dir[512], path[600];
    test_tmpdir("test_deform", dir, sizeof(dir));
    snprintf(path, sizeof(path), "%s/net.bin", dir);
    net->params[net->num_params - 1] = 0.25f;
    CHECK_OK(deform_network_save(net, path));
    deform_network *back = NULL;
    CHECK_OK(deform_network_load(&back, path));
    CHECK(back && back->num_params == net->num_params &&
              memcmp(back->params, net->params, net->num_params * sizeof(float)) == 0 &&
              back->cfg.res_time == 6 && back->cfg.head_width == 32 && back->cfg.time_coarsen == 2 &&
              back->grid.time_coarsen == 2 && back->grid.aabb[4] == 1.0f,
          "blob round trip differs");
    size_t n = deform_network_blob_size(net);
    unsigned char *buf = malloc(n);
    CHECK_OK(deform_network_write_blob(net, buf, n));
    deform_network *bad = NULL;
    CHECK(deform_network_read_blob(&bad, buf, n - 4, "trunc.bin") == PG_ERR_FORMAT && !bad, "truncated blob accepted");
    CHECK(strstr(pg_last_error(), "trunc.bin") != NULL, "error does not name the file: %s", pg_last_error());
    memcpy(buf, "PGDEFRM1", 8);
    CHECK(deform_network_read_blob(&bad, buf, n, "v1.bin") == PG_ERR_FORMAT && strstr(pg_last_error(), "PGDEFRM1"),
          "format 1 blob: %s", pg_last_error());
    memcpy(buf, "PGDEFRM2", 8);
    CHECK(deform_network_read_blob(&bad, buf, n, "v2.bin") == PG_ERR_FORMAT && strstr(pg_last_error(), "PGDEFRM2"),
          "format 2 blob: %s", pg_last_error());
    buf[0] = 'X';
    CHECK(deform_network_read_blob(&bad, buf, n, "magic.bin") == PG_ERR_FORMAT, "bad magic accepted");
    free(buf);
    deform_config c2 = cfg;
    c2.channels = 0;
    CHECK(deform_network_create(&bad, &c2, aabb) == PG_ERR_ARG, "channels 0 accepted");
    c2 = cfg;
    c2.head_width = -1;
    CHECK(deform_network_create(&bad, &c2, aabb) == PG_ERR_ARG && strstr(pg_last_error(), "head_width"),
          "head_width -1: %s", pg_last_error());
    const float flat[6] = { 0, 0, 0, 1, 0, 1 };
    CHECK(deform_network_create(&bad, &cfg, flat) == PG_ERR_ARG, "empty aabb accepted");
    deform_network_destroy(back);
    deform_ws_destroy(ws);
    deform_network_destroy(net);
}

static float bf16_round(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    u += 0x7FFFu + ((u >> 16) & 1u);
    u &= 0xFFFF0000u;
    memcpy(&f, &u, 4);
    return f;
}

/* The bf16 GEMM backend in use vs a double product of the bf16-rounded inputs: f32 accumulate into
 * a sub-block of a bigger C (operands packed from a transposed A and a ragged B), then the bf16
 * epilogue (bias, ReLU, mask, column sums, row-major / transposed / VNNI outputs). */
static void test_gemm_bf16(const char *name)
{
    enum { M = 37, N = 45, K = 50, MP = 64, NP = 64, KP = 64, LDC = 80 };
    pg_rng rng;
    pg_rng_seed(&rng, 8);
    static float A[K * M], B[K * N], Cm[MP * LDC], C0[MP * LDC], R[M * N], bias[NP];
    static uint16_t ap[MP * KP], bp[KP * NP], mask[MP * NP], rm[MP * NP], tr[NP * MP], vn[MP * NP];
    for (int i = 0; i < K * M; i++) A[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int i = 0; i < K * N; i++) B[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int i = 0; i < MP * LDC; i++) C0[i] = Cm[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int j = 0; j < NP; j++) bias[j] = j < N ? (float)pg_rng_range(&rng, -0.5, 0.5) : 0.0f;
    for (int i = 0; i < MP * NP; i++) mask[i] = pg_rng_uniform(&rng) < 0.8 ? 1 : 0;
    /* A stored transposed (K, M): a(i,k) = A[k*M + i]; B row-major (K, N) */
    for (int i = 0; i < M; i++)
        for (int j = 0; j < N; j++) {
            double s = 0;
            for (int k = 0; k < K; k++) s += (double)bf16_round(A[k * M + i]) * bf16_round(B[k * N + j]);
            R[i * N + j] = (float)s;
        }
    gemm_amx_pack_a(ap, KP, MP, KP, A, 1, M, M, K);
    gemm_amx_pack_b(bp, B, N, 1, K, N);
    /* f32, accumulate into C at column offset 16 */
    gemm_amx_epilogue ef = { .c = Cm + 16, .ldc = LDC, .accumulate = 1 };
    gemm_bf16(ap, KP, bp, 2 * NP, MP, NP, KP, &ef);
    double e = 0;
    int outside = 0;
    for (int i = 0; i < MP; i++)
        for (int j = 0; j < LDC; j++) {
            int in = j >= 16 && j < 16 + NP;
            double ref = C0[i * LDC + j] + (in && i < M && j - 16 < N ? R[i * N + j - 16] : 0.0);
            if (!in) outside |= Cm[i * LDC + j] != C0[i * LDC + j];
            else e = fmax(e, fabs(Cm[i * LDC + j] - ref));
        }
    CHECK(e < 1e-4 && !outside, "%s gemm f32 accumulate: err %g, wrote outside %d", name, e, outside);
    /* 16-wide edges (M = 48, N = 48: a 32-block plus a row strip and a column strip), with bias */
    static float Ce[48 * 48];
    gemm_amx_epilogue ee = { .c = Ce, .ldc = 48, .bias = bias };
    gemm_bf16(ap, KP, bp, 2 * NP, 48, 48, KP, &ee);
    double e_edge = 0;
    for (int i = 0; i < 48; i++)
        for (int j = 0; j < 48; j++)
            e_edge = fmax(e_edge, fabs(Ce[i * 48 + j] - ((i < M && j < N ? R[i * N + j] : 0.0) + bias[j])));
    CHECK(e_edge < 1e-4, "%s gemm 16-wide edges: err %g", name, e_edge);
    /* bf16 epilogue */
    float colsum[NP] = { 0 };
    gemm_amx_epilogue eb = { .bias = bias, .relu = 1, .mask = mask, .ldmask = NP, .colsum = colsum, .rows = M,
                             .rm = rm, .ldrm = NP, .tr = tr, .ldtr = MP, .vn = vn, .ldvn = 2 * NP };
    gemm_bf16(ap, KP, bp, 2 * NP, MP, NP, KP, &eb);
    double e2 = 0, es = 0;
    int layout = 0;
    for (int j = 0; j < NP; j++) {
        double cs = 0;
        for (int i = 0; i < MP; i++) {
            double v = (i < M && j < N ? R[i * N + j] : 0.0) + bias[j];
            v = v > 0 && mask[i * NP + j] ? v : 0.0;
            if (i < M) cs += v;
            uint16_t r = rm[i * NP + j];
            float got;
            uint32_t u = (uint32_t)r << 16;
            memcpy(&got, &u, 4);
            e2 = fmax(e2, fabs(got - v) / (fabs(v) + 1e-3));
            layout |= tr[j * MP + i] != r || vn[(i / 2) * 2 * NP + 2 * j + i % 2] != r;
        }
        es = fmax(es, fabs(colsum[j] - cs));
    }
    CHECK(e2 < 1e-2 && es < 1e-3 && !layout, "%s gemm epilogue: rel err %g, colsum err %g, layouts differ %d", name, e2,
          es, layout);
    printf("gemm %s (37x45x50 padded to 64): f32 accumulate max err %.2e, epilogue rel err %.2e colsum %.2e\n", name, e,
           e2, es);
}

/* The f32 kernels of the bf16 path (first layer, heads) vs double products: f32 output with bias
 * into a sub-block (ragged M, N, K), the epilogue's f32 and bf16 outputs, and the per-output dot
 * products with their own input offsets. */
static void test_gemm_f32(void)
{
    enum { M = 37, N = 45, K = 50, LDA = 53, LDB = 64, LDC = 70, MP = 64, NP = 64, ND = 11 };
    pg_rng rng;
    pg_rng_seed(&rng, 12);
    static float A[MP * LDA], B[K * LDB], C[MP * LDC], F[MP * NP], bias[NP];
    static uint16_t rm[MP * NP];
    for (int i = 0; i < MP * LDA; i++) A[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int k = 0; k < K; k++)
        for (int j = 0; j < LDB; j++) B[k * LDB + j] = j < N ? (float)pg_rng_range(&rng, -1, 1) : 0.0f;
    for (int j = 0; j < NP; j++) bias[j] = (float)pg_rng_range(&rng, -0.5, 0.5);
    for (int i = 0; i < MP * LDC; i++) C[i] = 7.0f;
    gemm_amx_epilogue ec = { .c = C + 5, .ldc = LDC, .bias = bias };
    gemm_f32(A, LDA, B, LDB, M, N, K, &ec);
    double e = 0, eb = 0, ed = 0;
    int outside = 0, layout = 0;
    for (int i = 0; i < MP; i++)
        for (int j = 0; j < LDC; j++) {
            if (i >= M || j < 5 || j >= 5 + N) {
                outside |= C[i * LDC + j] != 7.0f;
                continue;
            }
            double r = bias[j - 5];
            for (int k = 0; k < K; k++) r += (double)A[i * LDA + k] * B[k * LDB + j - 5];
            e = fmax(e, fabs(C[i * LDC + j] - r));
        }
    /* bf16 epilogue (bias, ReLU) with its f32 output: rm must be f rounded to nearest even */
    gemm_amx_epilogue ee = { .bias = bias, .relu = 1, .rm = rm, .ldrm = NP, .f = F, .ldf = NP };
    gemm_f32(A, LDA, B, LDB, MP, NP, K, &ee);
    for (int i = 0; i < MP; i++)
        for (int j = 0; j < NP; j++) {
            double r = bias[j];
            for (int k = 0; k < K; k++) r += (double)A[i * LDA + k] * B[k * LDB + j];
            eb = fmax(eb, fabs(F[i * NP + j] - fmax(r, 0.0)));
            layout |= rm[i * NP + j] != gemm_amx_bf16(F[i * NP + j]);
        }
    /* dots: output o reads K inputs from column koff[o] */
    static float D[K * ND], Y[M * 16];
    int koff[ND];
    for (int o = 0; o < ND; o++) koff[o] = o % 4;
    for (int i = 0; i < K * ND; i++) D[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int i = 0; i < M * 16; i++) Y[i] = 7.0f;
    gemm_f32_dots(A, LDA, D, koff, bias, M, ND, K, Y, 16);
    for (int i = 0; i < M; i++)
        for (int o = 0; o < 16; o++) {
            if (o >= ND) {
                outside |= Y[i * 16 + o] != 7.0f;
                continue;
            }
            double r = bias[o];
            for (int k = 0; k < K; k++) r += (double)A[i * LDA + koff[o] + k] * D[o * K + k];
            ed = fmax(ed, fabs(Y[i * 16 + o] - r));
        }
    CHECK(e < 1e-5 && eb < 1e-5 && ed < 1e-5 && !outside && !layout,
          "gemm f32: err %g, epilogue %g, dots %g, wrote outside %d, bf16 layout %d", e, eb, ed, outside, layout);
    printf("gemm f32 (37x45x50): max err %.2e, epilogue %.2e, dots %.2e\n", e, eb, ed);
}

/* The packers write zeros into every padding element whatever the destination held (uninitialised
 * bf16 padding could be NaN, and NaN * 0 is NaN in the tile products): destinations filled with
 * 0xFFFF (a NaN) first, ragged sizes, the plain, strided and (with a bf16 backend) transposing
 * paths of pack_a, and pack_b. */
static void test_pack_padding(const char *name)
{
    enum { M = 37, K = 50, MP = 64, KP = 64, LD = 72, BN = 45 };
    pg_rng rng;
    pg_rng_seed(&rng, 14);
    static float src[M * K], wide[M * 2 * K], tr[K * M]; /* a (M, K); every other column of (M, 2K); a^T */
    static uint16_t dst[MP * LD], bp[KP * MP];
    for (int i = 0; i < M; i++)
        for (int k = 0; k < K; k++) {
            src[i * K + k] = wide[i * 2 * K + 2 * k] = tr[k * M + i] = (float)pg_rng_range(&rng, -1, 1);
            wide[i * 2 * K + 2 * k + 1] = 0.0f;
        }
    const float *in[3] = { src, wide, tr };
    const long rs[3] = { K, 2 * K, 1 }, cs[3] = { 1, 2, M };
    int bad = 0;
    for (int v = 0; v < 3; v++) {
        memset(dst, 0xFF, sizeof dst);
        gemm_amx_pack_a(dst, LD, MP, KP, in[v], rs[v], cs[v], M, K);
        for (int i = 0; i < MP; i++)
            for (int k = 0; k < LD; k++) {
                /* columns from Kp to the row stride are not the packer's: left as they were */
                uint16_t want = k >= KP ? 0xFFFF : i < M && k < K ? gemm_amx_bf16(src[i * K + k]) : 0;
                bad += dst[i * LD + k] != want;
            }
    }
    /* B (37, 45) row-major -> VNNI pairs (round(37)/2, round(45), 2) */
    const int KB = gemm_amx_round(M), NB = gemm_amx_round(BN);
    memset(bp, 0xFF, sizeof bp);
    gemm_amx_pack_b(bp, src, BN, 1, M, BN);
    for (int k = 0; k < KB; k++)
        for (int n = 0; n < NB; n++)
            bad += bp[(k / 2) * 2 * NB + 2 * n + k % 2] != (k < M && n < BN ? gemm_amx_bf16(src[k * BN + n]) : 0);
    CHECK(bad == 0, "%s: %d packed elements wrong (padding must be 0 whatever the buffer held)", name, bad);
}

/* Issue 27 item 3: the network's outputs and gradients must not depend on what the heap held
 * (padding or scratch a kernel reads but nobody wrote). glibc's M_PERTURB fills every later
 * allocation with a chosen byte; the workspace is made under three fills (off, 0x7F: bf16 and f32
 * ~3.4e38, whose products overflow to Inf and NaN; 0xC0: -6.0) and a forward and backward with 2
 * threads must give the same bytes. A guard: the cause was the video encoder
 * (test_io_video); the network, AMX path included (run once on a scalar tile emulator), passed. */
static void test_heap_independent(const char *name, int bf16)
{
#if defined(__GLIBC__) && defined(M_PERTURB) && !defined(__SANITIZE_ADDRESS__)
    deform_config cfg;
    small_config(&cfg); /* ragged sizes: F = 6, W = 40, 5Wh = 60, all padded to 32 or 64 */
    cfg.channels = 3;
    cfg.width = 40;
    cfg.head_width = 12;
    cfg.bf16 = bf16;
    enum { N = 300 }; /* chunks of 64: the last one holds 44 points */
    pg_rng rng;
    deform_network *net = random_network(&cfg, &rng, 41);
    if (!net) return;
    const size_t P = net->num_params, NO = (size_t)N * DEFORM_OUT_DIM;
    float *means = malloc(N * 3 * sizeof(float)), *dout = malloc(NO * sizeof(float));
    float *ref = malloc((NO + P + N * 3) * sizeof(float)), *got = malloc((NO + P + N * 3) * sizeof(float));
    for (int i = 0; i < N * 3; i++) means[i] = (float)pg_rng_range(&rng, -1, 1);
    for (size_t i = 0; i < NO; i++) dout[i] = (float)pg_rng_range(&rng, -1, 1);
    static const int fills[3] = { 0, 0x80, 0x3F }; /* M_PERTURB b fills allocations with ~b */
    pg_set_threads(2);
    for (int k = 0; k < 3; k++) {
        float *o = k ? got : ref;
        memset(o + NO + P, 0, N * 3 * sizeof(float));
        deform_ws *ws = NULL;
        mallopt(M_PERTURB, fills[k]);
        pg_status st = deform_ws_create_chunked(&ws, net, N, 64);
        if (!st) {
            deform_network_zero_grad(net);
            st = deform_network_forward(net, ws, means, NULL, N, 0.4f, o);
            if (!st) st = deform_network_backward(net, ws, dout, o + NO + P);
            memcpy(o + NO, net->grads, P * sizeof(float));
        }
        deform_ws_destroy(ws);
        mallopt(M_PERTURB, 0);
        CHECK_OK(st);
        if (k) CHECK(memcmp(ref, got, (NO + P + N * 3) * sizeof(float)) == 0,
                     "%s: outputs or gradients depend on the heap's contents (fill 0x%02X)", name, ~fills[k] & 0xFF);
    }
    pg_set_threads(1);
    free(means); free(dout); free(ref); free(got);
    deform_network_destroy(net);
#else
    (void)bf16;
    printf("%s: heap-independence check skipped (needs glibc's M_PERTURB, not under the sanitizers)\n", name);
#endif
}

/* The bf16 network path (backend `name`) agrees with the f32 path to bf16 accuracy, with heads of
 * head_width hidden units (0: the width, 48). */
static void test_network_bf16(const char *name, int head_width)
{
    deform_config cfg;
    small_config(&cfg);
    cfg.channels = 8;
    cfg.res_space = 8;
    cfg.width = 48;
    cfg.head_width = head_width;
    pg_rng rng;
    deform_network *net = random_network(&cfg, &rng, 31);
    if (!net) return;
    enum { N = 300 };
    float *means = malloc(N * 3 * sizeof(float)), *dout = malloc(N * DEFORM_OUT_DIM * sizeof(float));
    float *o32 = malloc(N * DEFORM_OUT_DIM * sizeof(float)), *o16 = malloc(N * DEFORM_OUT_DIM * sizeof(float));
    float *dm32 = calloc(N * 3, sizeof(float)), *dm16 = calloc(N * 3, sizeof(float));
    for (int i = 0; i < N * 3; i++) means[i] = (float)pg_rng_range(&rng, -1, 1);
    for (int i = 0; i < N * DEFORM_OUT_DIM; i++) dout[i] = (float)pg_rng_range(&rng, -1, 1);
    const size_t P = net->num_params;
    float *g32 = malloc(P * sizeof(float));
    for (int pass = 0; pass < 2; pass++) {
        net->cfg.bf16 = pass;
        deform_ws *ws = NULL;
        CHECK_OK(deform_ws_create_chunked(&ws, net, N, 64));
        if (!ws) break;
        CHECK(deform_ws_uses_amx(ws) == pass, "workspace amx flag %d", deform_ws_uses_amx(ws));
        deform_network_zero_grad(net);
        CHECK_OK(deform_network_forward(net, ws, means, NULL, N, 0.3f, pass ? o16 : o32));
        CHECK_OK(deform_network_backward(net, ws, dout, pass ? dm16 : dm32));
        if (!pass) memcpy(g32, net->grads, P * sizeof(float));
        deform_ws_destroy(ws);
    }
    /* Relative L2 error per group. Max-norm is the wrong measure here: a hidden unit whose
     * pre-activation is within bf16 rounding of 0 switches its ReLU, which changes that point's
     * gradient by ~1/sqrt(width) of its norm. Measured: outputs 3.0e-3 (issue 14 asks <= 0.5%;
     * the first layer and the heads' forward run in f32, what is left are the roundings of the
     * bf16 layers' weights and activations); gradients of the heads' last layers ~0.5%, of the
     * layers behind ReLUs ~5%, which we attribute to such flips (dA = dY W2 is computed
     * identically in both paths; only the mask a > 0 differs). A wrong kernel (transposed or
     * misaligned operand) gives errors of order 1. */
    double e[4] = { 0 }, n[4] = { 0 };
    for (int i = 0; i < N * DEFORM_OUT_DIM; i++) { e[0] += pow(o32[i] - o16[i], 2); n[0] += pow(o32[i], 2); }
    for (size_t i = 0; i < P; i++) {
        int gi = i < net->num_plane_params ? 1 : 2;
        e[gi] += pow(g32[i] - net->grads[i], 2);
        n[gi] += pow(g32[i], 2);
    }
    for (int i = 0; i < N * 3; i++) { e[3] += pow(dm32[i] - dm16[i], 2); n[3] += pow(dm32[i], 2); }
    for (int k = 0; k < 4; k++) e[k] = sqrt(e[k] / n[k]);
    CHECK(e[0] < 5e-3 && e[1] < 0.15 && e[2] < 0.15 && e[3] < 0.15,
          "%s head width %d bf16 vs f32 rel L2: out %g planes %g mlp %g means %g", name, deform_head_width(&cfg), e[0],
          e[1], e[2], e[3]);
    printf("network %s, head width %d: bf16 vs f32 (relative L2): out %.1e, d/dplanes %.1e, d/dmlp %.1e, d/dmeans "
           "%.1e\n", name, deform_head_width(&cfg), e[0], e[1], e[2], e[3]);
    /* bf16 path determinism with 2 threads: two runs give the same bytes */
    {
        float *ga = malloc(P * sizeof(float)), *oa = malloc(N * DEFORM_OUT_DIM * sizeof(float));
        float *ob = malloc(N * DEFORM_OUT_DIM * sizeof(float));
        pg_set_threads(2);
        for (int rep = 0; rep < 2; rep++) {
            deform_ws *ws = NULL;
            CHECK_OK(deform_ws_create_chunked(&ws, net, N / 2, 32));
            if (!ws) break;
            float *g16 = calloc(N * 3, sizeof(float));
            deform_network_zero_grad(net);
            CHECK_OK(deform_network_forward(net, ws, means, NULL, N, 0.3f, rep ? ob : oa));
            CHECK_OK(deform_network_backward(net, ws, dout, g16));
            if (rep == 0) memcpy(ga, net->grads, P * sizeof(float));
            else CHECK(memcmp(ga, net->grads, P * sizeof(float)) == 0 && memcmp(oa, ob, N * DEFORM_OUT_DIM * sizeof(float)) == 0,
                       "bf16 path differs between two 2-thread runs");
            free(g16);
            deform_ws_destroy(ws);
        }
        pg_set_threads(1);
        free(ga);
        free(oa);
        free(ob);
    }
    free(means); free(dout); free(o32); free(o16); free(dm32); free(dm16); free(g32);
    deform_network_destroy(net);
}

/* Fits the network to a smooth time-varying displacement field with plain Adam; returns the final
 * mean squared error of dpos over the training points, and in *tail the mean of the last 40 steps'
 * (5 passes over the 8 times). */
static double fit_field(int bf16, int steps, double *tail)
{
    deform_config cfg;
    deform_config_default(&cfg);
    cfg.channels = 8;
    cfg.res_space = 8;
    cfg.res_time = 8;
    cfg.width = 64;
    cfg.bf16 = bf16;
    cfg.seed = 3;
    const float aabb[6] = { -1, -1, -1, 1, 1, 1 };
    deform_network *net = NULL;
    deform_ws *ws = NULL;
    *tail = 1e9;
    if (deform_network_create(&net, &cfg, aabb) || deform_ws_create(&ws, net, 512)) return 1e9;
    enum { N = 512 };
    static float means[N * 3], out[N * DEFORM_OUT_DIM], dout[N * DEFORM_OUT_DIM];
    pg_rng rng;
    pg_rng_seed(&rng, 9);
    for (int i = 0; i < N * 3; i++) means[i] = (float)pg_rng_range(&rng, -1, 1);
    const size_t P = net->num_params;
    float *m1 = calloc(P, sizeof(float)), *m2 = calloc(P, sizeof(float));
    double mse = 0;
    *tail = 0;
    for (int it = 1; it <= steps; it++) {
        float t = (float)((it * 7) % 8) / 7.0f;
        deform_network_forward(net, ws, means, NULL, N, t, out);
        memset(dout, 0, sizeof(dout));
        mse = 0;
        for (int i = 0; i < N; i++)
            for (int a = 0; a < 3; a++) {
                const float *p = means + 3 * i;
                double target = 0.1 * sin(3.0 * p[a] + 2.0 * p[(a + 1) % 3]) * cos(4.0 * t);
                double r = out[i * DEFORM_OUT_DIM + a] - target;
                mse += r * r / (3.0 * N);
                dout[i * DEFORM_OUT_DIM + a] = (float)(2 * r / (3.0 * N));
            }
        if (it > steps - 40) *tail += mse / 40;
        deform_network_zero_grad(net);
        deform_network_backward(net, ws, dout, NULL);
        const float lr = 3e-3f, b1 = 0.9f, b2 = 0.999f;
        float c1 = 1 - powf(b1, (float)it), c2 = 1 - powf(b2, (float)it);
        for (size_t k = 0; k < P; k++) {
            float g = net->grads[k];
            m1[k] = b1 * m1[k] + (1 - b1) * g;
            m2[k] = b2 * m2[k] + (1 - b2) * g * g;
            net->params[k] -= lr * (m1[k] / c1) / (sqrtf(m2[k] / c2) + 1e-15f);
        }
    }
    free(m1);
    free(m2);
    deform_ws_destroy(ws);
    deform_network_destroy(net);
    return mse;
}

/* Training quality: the bf16 backend `name` reaches the same fit as f32 on a small regression.
 * Compared on the mean of the last 40 steps: the last step alone depends chaotically on rounding
 * (its bf16/f32 ratio measured 0.2-2.1 over network seeds, against 0.86-1.34 for the mean). */
static void test_fit_bf16(const char *name)
{
    double t32, t16;
    double e32 = fit_field(0, 300, &t32);
    CHECK(e32 < 0.15 * 0.0025, "f32 fit did not learn the field: mse %g (field variance ~2.5e-3)", e32);
    double e16 = fit_field(1, 300, &t16);
    CHECK(t16 < 1.5 * t32 + 1e-6, "%s bf16 fit mse %g vs f32 %g (last 40 steps)", name, t16, t32);
    printf("fit (300 Adam steps): mse f32 %.3e, %s bf16 %.3e; last 40 steps: f32 %.3e, bf16 %.3e\n", e32, name, e16,
           t32, t16);
}

/* Time refinement (deform_params_resample_time): a network whose time rows are resampled from 5 to
 * 17 (every old row interval split in four; the coarse scale 3 -> 9) gives the same outputs at any
 * t, since the field is linear in t between rows. */
static void test_time_refinement(void)
{
    deform_config cfg;
    small_config(&cfg);
    const float aabb[6] = { -1, -1, -1, 1, 1, 1 };
    deform_network *a = NULL, *b = NULL;
    CHECK_OK(deform_network_create(&a, &cfg, aabb));
    cfg.res_time = 17;
    CHECK_OK(deform_network_create(&b, &cfg, aabb));
    if (!a || !b) return;
    pg_rng rng;
    pg_rng_seed(&rng, 11);
    for (size_t i = 0; i < a->num_params; i++) a->params[i] += 0.3f * (float)(pg_rng_uniform(&rng) - 0.5);
    deform_params_resample_time(a, a->params, b, b->params);
    CHECK(b->num_params > a->num_params && hex_time_res(&b->grid, 0) == 9, "refined network has %zu params, coarse rows %d",
          b->num_params, hex_time_res(&b->grid, 0));
    deform_ws *wa = NULL, *wb = NULL;
    CHECK_OK(deform_ws_create(&wa, a, 16));
    CHECK_OK(deform_ws_create(&wb, b, 16));
    float means[48], oa[16 * DEFORM_OUT_DIM], ob[16 * DEFORM_OUT_DIM];
    for (int i = 0; i < 48; i++) means[i] = (float)(1.8 * pg_rng_uniform(&rng) - 0.9);
    const float times[5] = { 0.0f, 0.13f, 0.5f, 0.77f, 1.0f };
    double worst = 0, scale = 0;
    for (int k = 0; k < 5; k++) {
        CHECK_OK(deform_network_forward(a, wa, means, NULL, 16, times[k], oa));
        CHECK_OK(deform_network_forward(b, wb, means, NULL, 16, times[k], ob));
        for (int i = 0; i < 16 * DEFORM_OUT_DIM; i++) {
            worst = fmax(worst, fabs((double)oa[i] - ob[i]));
            scale = fmax(scale, fabs((double)oa[i]));
        }
    }
    CHECK(scale > 1e-3 && worst <= 1e-5 * scale, "refined field differs by %.3g (outputs up to %.3g)", worst, scale);
    deform_ws_destroy(wa);
    deform_ws_destroy(wb);
    deform_network_destroy(a);
    deform_network_destroy(b);
}

int main(void)
{
    pg_set_threads(1);
    test_hexplane();
    test_linear();
    test_network_fd(0);
    test_network_fd(4);
    test_network_fd(12);
    test_identity_blob_reg();
    test_time_refinement();
    test_heap_independent("f32", 0);
    /* every bf16 backend this CPU can run, each forced in turn */
    /* the f32 kernels of the bf16 path need AVX-512F, which every bf16 backend implies */
    if (gemm_bf16_supported(GEMM_BF16_AVX512) || gemm_bf16_supported(GEMM_BF16_AMX)) test_gemm_f32();
    const gemm_bf16_kind kinds[2] = { GEMM_BF16_AMX, GEMM_BF16_AVX512 };
    for (int k = 0; k < 2; k++) {
        const char *name = gemm_bf16_name(kinds[k]);
        if (gemm_bf16_force(kinds[k]) != 0) {
            printf("bf16 backend %s: not supported by this CPU, skipped\n", name);
            continue;
        }
        test_gemm_bf16(name);
        test_pack_padding(name);
        test_heap_independent(name, 1);
        test_network_bf16(name, 0);
        test_network_bf16(name, 24);
#ifndef __SANITIZE_ADDRESS__ /* a training-quality check; the sanitizer pass covers the same code above */
        test_fit_bf16(name);
#else
        (void)test_fit_bf16;
#endif
    }
    return test_summary("test_deform");
}
