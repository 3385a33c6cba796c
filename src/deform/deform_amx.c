/* deform_amx.c - the bf16 path's forward/backward of the network's Linear layers and heads, one
 * chunk of points at a time (see deform_amx.h). */
#include "deform/deform_amx.h"

#include "deform/gemm_amx.h"

#include <stdlib.h>
#include <string.h>

#define HEAD_N 64 /* padded width of the 59 head outputs */
#define SH_HEAD (DEFORM_HEADS - 1)
#define MAX_ACTS (DEFORM_MAX_FEATURE_LAYERS + 2)

typedef struct {
    float *dwt[DEFORM_MAX_FEATURE_LAYERS + 1]; /* (d_l, d_{l+1}) transposed weight gradients */
    float *db[DEFORM_MAX_FEATURE_LAYERS + 1];  /* (d_{l+1}) bias gradients */
    float *dwh;                                /* (64, d_L) heads' last-layer weight gradients */
    float *dbh;                                /* (64) heads' bias gradients */
    uint16_t *acts;                            /* the current chunk's activations 1..L */
    uint16_t *ftr;                             /* the chunk's features transposed (d_0, mp): A of layer 0's dW */
    uint16_t *dya, *dyt;                       /* d_out as A (mp, 64) and transposed (64, mp) */
    uint16_t *avn;                             /* last activation as VNNI pairs of points (mp/2, d_L, 2),
                                                * written by the backward's rerun of the forward */
    uint16_t *grm[2], *gvn[2];                 /* ping-pong input gradients: row-major and VNNI */
    float *dfeat;                              /* (mp, d_0) */
    float *hid;                                /* (mp, d_L) f32 last activation of the forward: the heads' input */
    size_t acc_floats;                         /* dwt..dbh, zeroed per backward */
} amx_thread;

struct deform_amx {
    int L, Wh, F, mp, k4;            /* layers, head width, features, padded chunk, 32-aligned start of head 4's inputs */
    int d[MAX_ACTS];                 /* padded widths of the activations: d[0] features, d[L] = 5Wh padded */
    size_t rm_off[MAX_ACTS], tr_off[MAX_ACTS], act_elems; /* activations 1..L in a thread's acts */
    float *feats;                    /* (feat_chunks, mp, F): the f32 features of every chunk (layer 0's A) */
    long feat_chunks;
    float *w0;                       /* layer 0's w^T (F, d_1), f32: B of the f32 first layer */
    uint16_t *wf[DEFORM_MAX_FEATURE_LAYERS + 1], *wb[DEFORM_MAX_FEATURE_LAYERS + 1]; /* w as B of x w^T (l >= 1), of d_y w */
    float *hsh;                      /* SH head's w^T (Wh, 48), f32 */
    float *hsm;                      /* the small heads' w rows (11, Wh), f32 */
    float *hbias;                    /* the heads' biases (59) in output order */
    int koff[DEFORM_OUT_SH];         /* the small heads' outputs: start of their head's inputs */
    uint16_t *hb;                    /* heads' last layers, block-diagonal (64, d_L), as B of d a = d_out W_heads */
    float *bias[DEFORM_MAX_FEATURE_LAYERS + 1]; /* zero-padded biases */
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
    t->ftr = carve(base, &p, (size_t)a->d[0] * mp * 2);
    t->dya = carve(base, &p, mp * HEAD_N * 2);
    t->dyt = carve(base, &p, mp * HEAD_N * 2);
    t->avn = carve(base, &p, mp * dL * 2);
    for (int i = 0; i < 2; i++) {
        t->grm[i] = carve(base, &p, mp * mx * 2);
        t->gvn[i] = carve(base, &p, mp * mx * 2);
    }
    t->dfeat = carve(base, &p, mp * a->d[0] * sizeof(float));
    t->hid = carve(base, &p, mp * dL * sizeof(float));
    return p;
}

/* Lays out the packed weights and biases starting at base (base == NULL: only measures); returns
 * the bytes. */
static size_t shared_layout(deform_amx *a, char *base)
{
    size_t p = 0;
    deform_amx dummy;
    deform_amx *s = base ? a : &dummy;
    const size_t Wh = (size_t)a->Wh;
    s->w0 = carve(base, &p, (size_t)a->F * a->d[1] * sizeof(float));
    for (int l = 0; l < a->L; l++) {
        if (l > 0) s->wf[l] = carve(base, &p, (size_t)a->d[l] * a->d[l + 1] * 2);
        s->wb[l] = carve(base, &p, (size_t)a->d[l] * a->d[l + 1] * 2);
        s->bias[l] = carve(base, &p, (size_t)a->d[l + 1] * sizeof(float));
    }
    s->hsh = carve(base, &p, Wh * deform_head_dim[SH_HEAD] * sizeof(float));
    s->hsm = carve(base, &p, Wh * DEFORM_OUT_SH * sizeof(float));
    s->hbias = carve(base, &p, DEFORM_OUT_DIM * sizeof(float));
    s->hb = carve(base, &p, (size_t)a->d[a->L] * HEAD_N * 2);
    return p;
}

pg_status deform_amx_create(deform_amx **out, const deform_network *net, int chunk)
{
    *out = NULL;
    deform_amx *a = pg_calloc(1, sizeof(*a), "deform AMX path");
    if (!a) return PG_ERR_NOMEM;
    a->L = net->num_layers;
    a->Wh = deform_head_width(&net->cfg);
    a->F = net->layers[0].in;
    a->mp = gemm_amx_round(chunk);
    a->k4 = (4 * a->Wh) & ~31;
    for (int l = 0; l < a->L; l++) {
        a->d[l] = gemm_amx_round(net->layers[l].in);
        a->d[l + 1] = gemm_amx_round(net->layers[l].out);
    }
    for (int h = 0; h < SH_HEAD; h++)
        for (int r = 0; r < deform_head_dim[h]; r++) a->koff[deform_head_offset[h] + r] = h * a->Wh;
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
    a->shared = aligned_alloc(64, shared_layout(a, NULL));
    if (!a->shared) {
        free(a);
        return pg_fail(PG_ERR_NOMEM, "out of memory for the deform AMX weights");
    }
    shared_layout(a, a->shared);
    for (int l = 0; l < a->L; l++) memset(a->bias[l], 0, (size_t)a->d[l + 1] * sizeof(float));
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

/* Weight of the heads' last layers as one block-diagonal (5Wh, 59) matrix: input k, output o (the
 * backward's bf16 operand). */
static float head_weight(const deform_network *net, int k, int o)
{
    int Wh = deform_head_width(&net->cfg), h = DEFORM_HEADS - 1;
    while (deform_head_offset[h] > o) h--;
    if (o >= DEFORM_OUT_DIM || k / Wh != h) return 0.0f;
    return net->params[net->heads[h].w_off + (size_t)(o - deform_head_offset[h]) * Wh + (k - h * Wh)];
}

void deform_amx_pack_forward(deform_amx *a, const deform_network *net)
{
    const int Wh = a->Wh, d1 = a->d[1];
    const float *w0 = net->params + net->layers[0].w_off;
    for (int k = 0; k < a->F; k++)
        for (int n = 0; n < d1; n++) a->w0[(size_t)k * d1 + n] = n < net->layers[0].out ? w0[(size_t)n * a->F + k] : 0.0f;
    for (int l = 0; l < a->L; l++) {
        const deform_layer *Ly = &net->layers[l];
        if (l > 0) gemm_amx_pack_b(a->wf[l], net->params + Ly->w_off, 1, Ly->in, Ly->in, Ly->out);
        memcpy(a->bias[l], net->params + Ly->b_off, (size_t)Ly->out * sizeof(float));
    }
    const int nsh = deform_head_dim[SH_HEAD];
    const float *wsh = net->params + net->heads[SH_HEAD].w_off;
    for (int k = 0; k < Wh; k++)
        for (int o = 0; o < nsh; o++) a->hsh[(size_t)k * nsh + o] = wsh[(size_t)o * Wh + k];
    for (int h = 0; h < DEFORM_HEADS; h++) {
        const deform_layer *Ly = &net->heads[h];
        if (h < SH_HEAD)
            memcpy(a->hsm + (size_t)deform_head_offset[h] * Wh, net->params + Ly->w_off, (size_t)Ly->out * Wh * sizeof(float));
        memcpy(a->hbias + deform_head_offset[h], net->params + Ly->b_off, (size_t)Ly->out * sizeof(float));
    }
}

void deform_amx_pack_backward(deform_amx *a, const deform_network *net)
{
    for (int l = 0; l < a->L; l++) {
        const deform_layer *Ly = &net->layers[l];
        gemm_amx_pack_b(a->wb[l], net->params + Ly->w_off, Ly->in, 1, Ly->out, Ly->in);
    }
    const int N = a->d[a->L], in = DEFORM_HEADS * a->Wh;
    for (int oo = 0; oo < HEAD_N / 2; oo++)
        for (int k = 0; k < N; k++)
            for (int e = 0; e < 2; e++)
                a->hb[(size_t)oo * 2 * N + 2 * k + e] = k < in ? gemm_amx_bf16(head_weight(net, k, 2 * oo + e)) : 0;
}

pg_status deform_amx_prepare(deform_amx *a, long nchunks)
{
    if (nchunks <= a->feat_chunks) return PG_OK;
    size_t n;
    if (pg_size_mul((size_t)nchunks, (size_t)a->mp * a->F * sizeof(float), &n))
        return pg_fail(PG_ERR_SIZE, "deform: %ld chunks overflow", nchunks);
    float *f = aligned_alloc(64, align64(n));
    if (!f) return pg_fail(PG_ERR_NOMEM, "out of memory for the deform features of %ld chunks", nchunks);
    free(a->feats);
    a->feats = f;
    a->feat_chunks = nchunks;
    return PG_OK;
}

void deform_amx_chunk_forward(deform_amx *a, int tid, long k, const float *feat, int m, float *y)
{
    amx_thread *t = &a->th[tid];
    const int mp = a->mp, F = a->F, L = a->L, Wh = a->Wh;
    float *fk = a->feats + (size_t)k * mp * F;
    if (feat) { /* padding rows are zero, so padded points stay finite and add nothing to gradients */
        memcpy(fk, feat, (size_t)m * F * sizeof(float));
        memset(fk + (size_t)m * F, 0, (size_t)(mp - m) * F * sizeof(float));
    }
    const uint16_t *xin = NULL; /* layer l's bf16 input (l >= 1) in t->acts */
    for (int l = 0; l < L; l++) {
        uint16_t *o = t->acts + a->rm_off[l + 1];
        gemm_amx_epilogue e = { .bias = a->bias[l], .relu = 1 };
        if (l + 1 < L) {
            e.rm = o;
            e.ldrm = a->d[l + 1];
            if (!feat) { /* the backward's rerun: also the transposed copy the weight gradients read */
                e.tr = t->acts + a->tr_off[l + 1];
                e.ldtr = mp;
            }
        } else if (y) { /* the forward: f32 for the heads */
            e.f = t->hid;
            e.ldf = a->d[L];
        } else { /* the backward's rerun: the ReLU mask and the VNNI copy the heads' weight gradient reads */
            e.rm = o;
            e.ldrm = a->d[L];
            e.vn = t->avn;
            e.ldvn = 2 * a->d[L];
        }
        if (l == 0) gemm_f32(fk, F, a->w0, a->d[1], mp, a->d[1], F, &e);
        else gemm_bf16(xin, a->d[l], a->wf[l], 2 * a->d[l + 1], mp, a->d[l + 1], a->d[l], &e);
        xin = o;
    }
    if (!y) return;
    /* the heads in f32: the 11 outputs of the small heads, then the 48 of SH */
    const float *hid = t->hid;
    const int dL = a->d[L], nsh = deform_head_dim[SH_HEAD];
    gemm_f32_dots(hid, dL, a->hsm, a->koff, a->hbias, m, DEFORM_OUT_SH, Wh, y, DEFORM_OUT_DIM);
    gemm_amx_epilogue eh = { .c = y + DEFORM_OUT_SH, .ldc = DEFORM_OUT_DIM, .bias = a->hbias + DEFORM_OUT_SH };
    gemm_f32(hid + (size_t)SH_HEAD * Wh, dL, a->hsh, nsh, m, nsh, Wh, &eh);
}

void deform_amx_backward_begin(deform_amx *a, int tid)
{
    memset(a->th[tid].dwt[0], 0, a->th[tid].acc_floats * sizeof(float));
}

const float *deform_amx_chunk_backward(deform_amx *a, int tid, long k, const float *dy, int m, int *ld)
{
    amx_thread *t = &a->th[tid];
    const int mp = a->mp, L = a->L, dL = a->d[L], k4 = a->k4;
    /* the features transposed for layer 0's weight gradient (packed here: storing them measured slower) */
    gemm_amx_pack_a(t->ftr, mp, a->d[0], mp, a->feats + (size_t)k * mp * a->F, 1, a->F, a->F, m);
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
        gemm_bf16(l ? t->acts + a->tr_off[l] : t->ftr, mp, t->gvn[cur], 2 * dout, din, dout, mp, &w);
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
    const int Wh = a->Wh, dL = a->d[a->L];
    for (int h = 0; h < DEFORM_HEADS; h++) {
        const deform_layer *Ly = &net->heads[h];
        for (int r = 0; r < Ly->out; r++) {
            const float *s = t->dwh + (size_t)(deform_head_offset[h] + r) * dL + (size_t)h * Wh;
            float *gw = grads + Ly->w_off + (size_t)r * Wh;
            for (int c = 0; c < Wh; c++) gw[c] += s[c];
            grads[Ly->b_off + r] += t->dbh[deform_head_offset[h] + r];
        }
    }
}
