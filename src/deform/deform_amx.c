/* deform_amx.c - bf16 AMX forward/backward of the network's Linear layers and heads, one chunk of
 * points at a time (see deform_amx.h). */
#include "deform/deform_amx.h"

#include "deform/gemm_amx.h"

#include <stdlib.h>
#include <string.h>

#define HEAD_N 64 /* padded width of the 59 head outputs */
#define MAX_ACTS (DEFORM_MAX_FEATURE_LAYERS + 2)

typedef struct {
    float *dwt[DEFORM_MAX_FEATURE_LAYERS + 1]; /* (d_l, d_{l+1}) transposed weight gradients */
    float *db[DEFORM_MAX_FEATURE_LAYERS + 1];  /* (d_{l+1}) bias gradients */
    float *dwh;                                /* (64, d_L) heads' last-layer weight gradients */
    float *dbh;                                /* (64) heads' bias gradients */
    uint16_t *acts;                            /* the current chunk's activations 1..L */
    uint16_t *dya, *dyt;                       /* d_out as A (mp, 64) and transposed (64, mp) */
    uint16_t *avn;                             /* last activation as VNNI pairs of points (mp/2, d_L, 2),
                                                * written by the backward's rerun of the forward */
    uint16_t *grm[2], *gvn[2];                 /* ping-pong input gradients: row-major and VNNI */
    float *dfeat;                              /* (mp, d_0) */
    size_t acc_floats;                         /* dwt..dbh, zeroed per backward */
} amx_thread;

struct deform_amx {
    int L, W, F, mp, k4;             /* layers, width, features, padded chunk, 32-aligned start of head 4's inputs */
    int d[MAX_ACTS];                 /* padded widths of the activations: d[0] features, d[L] = 5W padded */
    size_t rm_off[MAX_ACTS], tr_off[MAX_ACTS], act_elems; /* activations 1..L in a thread's acts */
    uint16_t *feats;                 /* (feat_chunks, feat_elems): activation 0 (rm, then tr) of every chunk */
    size_t feat_elems;
    long feat_chunks;
    uint16_t *wf[DEFORM_MAX_FEATURE_LAYERS + 1], *wb[DEFORM_MAX_FEATURE_LAYERS + 1]; /* w as B of x w^T, of d_y w */
    uint16_t *hf, *hb;               /* heads' last layers, block-diagonal: (d_L, 64) and (64, d_L) as B */
    float *bias[DEFORM_MAX_FEATURE_LAYERS + 1], *hbias; /* zero-padded biases */
    void *shared;                    /* storage of the packed weights and biases */
    int nthreads;
    size_t thread_bytes;
    void *threads_mem;
    amx_thread *th;
};

static size_t align64(size_t bytes) { return (bytes + 63) & ~(size_t)63; }

/* Takes a 64-byte aligned piece of `bytes` at offset *off of base (base == NULL: only counts). */
static void *carve(char *base, size_t *off, size_t bytes)
{
    size_t o = *off;
    *off += align64(bytes);
    return base ? base + o : NULL;
}

/* Lays out one thread's buffers starting at base (base == NULL: only measures); returns the bytes. */
static size_t thread_layout(const deform_amx *a, char *base, amx_thread *t)
{
    size_t p = 0;
    amx_thread dummy;
    if (!t) t = &dummy;
    const size_t mp = (size_t)a->mp, dL = (size_t)a->d[a->L];
    size_t mx = 0;
    for (int i = 0; i <= a->L; i++) mx = (size_t)a->d[i] > mx ? (size_t)a->d[i] : mx;
    for (int l = 0; l < a->L; l++) {
        t->dwt[l] = carve(base, &p, (size_t)a->d[l] * a->d[l + 1] * sizeof(float));
        t->db[l] = carve(base, &p, (size_t)a->d[l + 1] * sizeof(float));
    }
    t->dwh = carve(base, &p, HEAD_N * dL * sizeof(float));
    t->dbh = carve(base, &p, HEAD_N * sizeof(float));
    t->acc_floats = p / sizeof(float);
    t->acts = carve(base, &p, a->act_elems * 2);
    t->dya = carve(base, &p, mp * HEAD_N * 2);
    t->dyt = carve(base, &p, mp * HEAD_N * 2);
    t->avn = carve(base, &p, mp * dL * 2);
    for (int i = 0; i < 2; i++) {
        t->grm[i] = carve(base, &p, mp * mx * 2);
        t->gvn[i] = carve(base, &p, mp * mx * 2);
    }
    t->dfeat = carve(base, &p, mp * a->d[0] * sizeof(float));
    return p;
}

pg_status deform_amx_create(deform_amx **out, const deform_network *net, int chunk)
{
    *out = NULL;
    deform_amx *a = pg_calloc(1, sizeof(*a), "deform AMX path");
    if (!a) return PG_ERR_NOMEM;
    a->L = net->num_layers;
    a->W = net->cfg.width;
    a->F = net->layers[0].in;
    a->mp = gemm_amx_round(chunk);
    a->k4 = (4 * a->W) & ~31;
    for (int l = 0; l < a->L; l++) {
        a->d[l] = gemm_amx_round(net->layers[l].in);
        a->d[l + 1] = gemm_amx_round(net->layers[l].out);
    }
    a->feat_elems = 2 * (size_t)a->mp * a->d[0];
    a->rm_off[0] = 0;
    a->tr_off[0] = (size_t)a->mp * a->d[0];
    size_t off = 0;
    for (int i = 1; i <= a->L; i++) {
        a->rm_off[i] = off;
        off += (size_t)a->mp * a->d[i];
        if (i < a->L) {
            a->tr_off[i] = off;
            off += (size_t)a->d[i] * a->mp;
        }
    }
    a->act_elems = (off + 31) & ~(size_t)31; /* keeps every chunk's block 64-byte aligned */
    size_t bytes = 0;
    for (int l = 0; l < a->L; l++)
        bytes += 2 * align64((size_t)a->d[l] * a->d[l + 1] * 2) + align64((size_t)a->d[l + 1] * sizeof(float));
    bytes += 2 * align64((size_t)a->d[a->L] * HEAD_N * 2) + align64(HEAD_N * sizeof(float));
    a->shared = aligned_alloc(64, bytes);
    if (!a->shared) {
        free(a);
        return pg_fail(PG_ERR_NOMEM, "out of memory for the deform AMX weights");
    }
    char *sh = a->shared;
    size_t p = 0;
    for (int l = 0; l < a->L; l++) {
        a->wf[l] = carve(sh, &p, (size_t)a->d[l] * a->d[l + 1] * 2);
        a->wb[l] = carve(sh, &p, (size_t)a->d[l] * a->d[l + 1] * 2);
        a->bias[l] = carve(sh, &p, (size_t)a->d[l + 1] * sizeof(float));
        memset(a->bias[l], 0, (size_t)a->d[l + 1] * sizeof(float));
    }
    a->hf = carve(sh, &p, (size_t)a->d[a->L] * HEAD_N * 2);
    a->hb = carve(sh, &p, (size_t)a->d[a->L] * HEAD_N * 2);
    a->hbias = carve(sh, &p, HEAD_N * sizeof(float));
    memset(a->hbias, 0, HEAD_N * sizeof(float));
    a->thread_bytes = align64(thread_layout(a, NULL, NULL));
    *out = a;
    return PG_OK;
}

pg_status deform_amx_ensure_threads(deform_amx *a, int nt)
{
    if (nt <= a->nthreads) return PG_OK;
    void *mem = aligned_alloc(64, (size_t)nt * a->thread_bytes);
    amx_thread *th = calloc((size_t)nt, sizeof(*th));
    if (!mem || !th) {
        free(mem);
        free(th);
        return pg_fail(PG_ERR_NOMEM, "out of memory for %d deform AMX thread buffers", nt);
    }
    free(a->threads_mem);
    free(a->th);
    a->threads_mem = mem;
    a->th = th;
    a->nthreads = nt;
    for (int i = 0; i < nt; i++) thread_layout(a, (char *)mem + (size_t)i * a->thread_bytes, &th[i]);
    return PG_OK;
}

void deform_amx_destroy(deform_amx *a)
{
    if (!a) return;
    free(a->shared);
    free(a->feats);
    free(a->threads_mem);
    free(a->th);
    free(a);
}

/* Weight of the heads' last layers as one block-diagonal (5W, 59) matrix: input k, output o. */
static float head_weight(const deform_network *net, int k, int o)
{
    int W = net->cfg.width, h = DEFORM_HEADS - 1;
    while (deform_head_offset[h] > o) h--;
    if (o >= DEFORM_OUT_DIM || k / W != h) return 0.0f;
    return net->params[net->heads[h].w_off + (size_t)(o - deform_head_offset[h]) * W + (k - h * W)];
}

void deform_amx_pack_forward(deform_amx *a, const deform_network *net)
{
    for (int l = 0; l < a->L; l++) {
        const deform_layer *Ly = &net->layers[l];
        gemm_amx_pack_b(a->wf[l], net->params + Ly->w_off, 1, Ly->in, Ly->in, Ly->out);
        memcpy(a->bias[l], net->params + Ly->b_off, (size_t)Ly->out * sizeof(float));
    }
    const int K = a->d[a->L], in = DEFORM_HEADS * a->W;
    for (int kk = 0; kk < K / 2; kk++)
        for (int o = 0; o < HEAD_N; o++)
            for (int e = 0; e < 2; e++) {
                int k = 2 * kk + e;
                a->hf[(size_t)kk * 2 * HEAD_N + 2 * o + e] = k < in ? gemm_amx_bf16(head_weight(net, k, o)) : 0;
            }
    for (int h = 0; h < DEFORM_HEADS; h++)
        memcpy(a->hbias + deform_head_offset[h], net->params + net->heads[h].b_off, (size_t)deform_head_dim[h] * sizeof(float));
}

void deform_amx_pack_backward(deform_amx *a, const deform_network *net)
{
    for (int l = 0; l < a->L; l++) {
        const deform_layer *Ly = &net->layers[l];
        gemm_amx_pack_b(a->wb[l], net->params + Ly->w_off, Ly->in, 1, Ly->out, Ly->in);
    }
    const int N = a->d[a->L], in = DEFORM_HEADS * a->W;
    for (int oo = 0; oo < HEAD_N / 2; oo++)
        for (int k = 0; k < N; k++)
            for (int e = 0; e < 2; e++)
                a->hb[(size_t)oo * 2 * N + 2 * k + e] = k < in ? gemm_amx_bf16(head_weight(net, k, 2 * oo + e)) : 0;
}

pg_status deform_amx_prepare(deform_amx *a, long nchunks)
{
    if (nchunks <= a->feat_chunks) return PG_OK;
    size_t n;
    if (pg_size_mul((size_t)nchunks, a->feat_elems * 2, &n)) return pg_fail(PG_ERR_SIZE, "deform: %ld chunks overflow", nchunks);
    uint16_t *f = aligned_alloc(64, align64(n));
    if (!f) return pg_fail(PG_ERR_NOMEM, "out of memory for the deform features of %ld chunks", nchunks);
    free(a->feats);
    a->feats = f;
    a->feat_chunks = nchunks;
    return PG_OK;
}

void deform_amx_chunk_forward(deform_amx *a, int tid, long k, const float *feat, int m, float *y)
{
    amx_thread *t = &a->th[tid];
    const int mp = a->mp, F = a->F, L = a->L;
    uint16_t *fk = a->feats + (size_t)k * a->feat_elems;
    const uint16_t *xin = fk; /* this layer's input: features, then t->acts */
    if (feat) {
        /* padding rows/columns are zero, so padded points stay finite and add nothing to gradients */
        gemm_amx_pack_a(fk, a->d[0], mp, a->d[0], feat, F, 1, m, F);
        gemm_amx_pack_a(fk + a->tr_off[0], mp, a->d[0], mp, feat, 1, F, F, m);
    }
    for (int l = 0; l < L; l++) {
        uint16_t *o = t->acts + a->rm_off[l + 1];
        gemm_amx_epilogue e = { .bias = a->bias[l], .relu = 1, .rm = o, .ldrm = a->d[l + 1] };
        if (l + 1 < L) {
            if (!y) { /* the backward's rerun: also the transposed copy the weight gradients read */
                e.tr = t->acts + a->tr_off[l + 1];
                e.ldtr = mp;
            }
        } else if (!y) { /* the backward's rerun: also the VNNI copy its heads' weight gradient reads */
            e.vn = t->avn;
            e.ldvn = 2 * a->d[L];
        }
        gemm_bf16(xin, a->d[l], a->wf[l], 2 * a->d[l + 1], mp, a->d[l + 1], a->d[l], &e);
        xin = o;
    }
    if (!y) return;
    /* Heads: output columns [0, 16) (the 11 small-head outputs + 5 SH) read all of a; [16, 64) are SH
     * only and read head 4's inputs [k4, d_L). */
    const uint16_t *act = xin;
    const int dL = a->d[L], k4 = a->k4;
    gemm_amx_epilogue e0 = { .c = y, .ldc = DEFORM_AMX_OUT_LD, .bias = a->hbias };
    gemm_bf16(act, dL, a->hf, 2 * HEAD_N, mp, 16, dL, &e0);
    gemm_amx_epilogue e1 = { .c = y + 16, .ldc = DEFORM_AMX_OUT_LD, .bias = a->hbias + 16 };
    gemm_bf16(act + k4, dL, a->hf + (size_t)(k4 / 2) * 2 * HEAD_N + 32, 2 * HEAD_N, mp, 48, dL - k4, &e1);
}

void deform_amx_backward_begin(deform_amx *a, int tid)
{
    memset(a->th[tid].dwt[0], 0, a->th[tid].acc_floats * sizeof(float));
}

const float *deform_amx_chunk_backward(deform_amx *a, int tid, long k, const float *dy, int m, int *ld)
{
    amx_thread *t = &a->th[tid];
    const uint16_t *fk = a->feats + (size_t)k * a->feat_elems;
    const int mp = a->mp, L = a->L, dL = a->d[L], k4 = a->k4;
    for (int i = 0; i < m; i++) {
        const float *r = dy + (size_t)i * DEFORM_OUT_DIM;
        #pragma omp simd
        for (int o = 0; o < DEFORM_OUT_DIM; o++) t->dbh[o] += r[o];
    }
    gemm_amx_pack_a(t->dya, HEAD_N, mp, HEAD_N, dy, DEFORM_OUT_DIM, 1, m, DEFORM_OUT_DIM);
    gemm_amx_pack_a(t->dyt, mp, HEAD_N, mp, dy, 1, DEFORM_OUT_DIM, DEFORM_OUT_DIM, m);
    /* heads' weight gradients: rows [0, 16) over all inputs, rows [16, 64) (SH only) over [k4, dL) */
    const uint16_t *act = t->acts + a->rm_off[L];
    gemm_amx_epilogue w0 = { .c = t->dwh, .ldc = dL, .accumulate = 1 };
    gemm_bf16(t->dyt, mp, t->avn, 2 * dL, 16, dL, mp, &w0);
    gemm_amx_epilogue w1 = { .c = t->dwh + (size_t)16 * dL + k4, .ldc = dL, .accumulate = 1 };
    gemm_bf16(t->dyt + (size_t)16 * mp, mp, t->avn + 2 * k4, 2 * dL, 48, dL - k4, mp, &w1);
    /* d a = d_out W_heads, masked by a > 0: inputs [0, k4) belong to heads 0-3 whose outputs are the
     * first 32 columns of d_out; [k4, dL) need all 64 */
    int cur = 0;
    gemm_amx_epilogue g = { .mask = act, .ldmask = dL, .colsum = t->db[L - 1], .rows = m, .rm = t->grm[cur],
                            .ldrm = dL, .vn = t->gvn[cur], .ldvn = 2 * dL };
    gemm_bf16(t->dya, HEAD_N, a->hb, 2 * dL, mp, k4, 32, &g);
    g.mask += k4;
    g.colsum += k4;
    g.rm += k4;
    g.vn += 2 * k4;
    gemm_bf16(t->dya, HEAD_N, a->hb + 2 * k4, 2 * dL, mp, dL - k4, HEAD_N, &g);
    for (int l = L - 1; l >= 0; l--) {
        const int din = a->d[l], dout = a->d[l + 1];
        gemm_amx_epilogue w = { .c = t->dwt[l], .ldc = dout, .accumulate = 1 };
        gemm_bf16((l ? t->acts : fk) + a->tr_off[l], mp, t->gvn[cur], 2 * dout, din, dout, mp, &w);
        if (l == 0) {
            gemm_amx_epilogue f = { .c = t->dfeat, .ldc = din };
            gemm_bf16(t->grm[cur], dout, a->wb[0], 2 * din, mp, din, dout, &f);
            break;
        }
        gemm_amx_epilogue n = { .mask = t->acts + a->rm_off[l], .ldmask = din, .colsum = t->db[l - 1], .rows = m,
                                .rm = t->grm[!cur], .ldrm = din, .vn = t->gvn[!cur], .ldvn = 2 * din };
        gemm_bf16(t->grm[cur], dout, a->wb[l], 2 * din, mp, din, dout, &n);
        cur = !cur;
    }
    *ld = a->d[0];
    return t->dfeat;
}

void deform_amx_backward_end(deform_amx *a, const deform_network *net, int tid, float *grads)
{
    amx_thread *t = &a->th[tid];
    for (int l = 0; l < a->L; l++) {
        const deform_layer *Ly = &net->layers[l];
        float *gw = grads + Ly->w_off, *gb = grads + Ly->b_off;
        const int dout = a->d[l + 1];
        for (int i = 0; i < Ly->in; i++)
            for (int o = 0; o < Ly->out; o++) gw[(size_t)o * Ly->in + i] += t->dwt[l][(size_t)i * dout + o];
        for (int o = 0; o < Ly->out; o++) gb[o] += t->db[l][o];
    }
    const int W = a->W, dL = a->d[a->L];
    for (int h = 0; h < DEFORM_HEADS; h++) {
        const deform_layer *Ly = &net->heads[h];
        for (int r = 0; r < Ly->out; r++) {
            const float *s = t->dwh + (size_t)(deform_head_offset[h] + r) * dL + (size_t)h * W;
            float *gw = grads + Ly->w_off + (size_t)r * W;
            for (int c = 0; c < W; c++) gw[c] += s[c];
            grads[Ly->b_off + r] += t->dbh[deform_head_offset[h] + r];
        }
    }
}
