/* deform_amx.h - the bf16 path of the deformation network's MLP (internal to src/deform).
 *
 * deform.c does the HexPlane and the point ordering; this module runs the Linear layers and heads
 * of one chunk of points as bf16 GEMMs (gemm_amx.h: AMX or AVX512-BF16) with activations kept as
 * bf16 in exactly the layouts the later GEMMs read, so nothing is repacked. The exceptions are
 * the first layer (F -> W) and the heads' forward, which run in f32 (gemm_f32): their bf16
 * roundings cost most of the bf16-vs-f32 output agreement and they are small (docs/deform.md).
 * Only the f32 features (activation 0, 128 B per point with F = 32) are kept from forward to
 * backward: the backward reruns the GEMMs of the chunk's forward, which measured faster than
 * streaming the 1.9 KB per point of activations back from memory. Per chunk:
 *     act 0 = features, act l+1 = output of layer l (the last one = the heads' hidden layer a)
 *     act a row-major (mp, d_a)  - A operand of the next forward GEMM, and the backward ReLU mask
 *     act a transposed (d_a, mp) - A operand of the weight gradient d_W^T += x^T d_y (a < last)
 * (mp = chunk rounded up to 32, d_a = its width (W, or 5Wh for the last) rounded up to 32; act 0
 * is bf16 only in its transposed copy, packed by the backward); the forward writes the last one in
 * f32 instead, the input of the f32 heads. The backward writes each input gradient once as row-major (A of the next input
 * gradient) and as VNNI pairs of points (B of the weight gradient). Its five heads' last layers
 * run as one 5Wh -> 64 block-diagonal GEMM (Wh = head width) split into two calls that skip the
 * all-zero blocks (outputs 0-15 hold the 11 small-head outputs and read all 5Wh inputs; outputs
 * 16-63 are SH only and read head 4's Wh inputs, from the 32-aligned column k4 <= 4Wh on). Weight
 * gradients accumulate in f32 per thread and are added to the caller's gradient buffer by
 * deform_amx_backward_end.
 */
#ifndef PG_DEFORM_DEFORM_AMX_H
#define PG_DEFORM_DEFORM_AMX_H

#include "core/status.h"
#include "deform/deform.h"

typedef struct deform_amx deform_amx;

pg_status deform_amx_create(deform_amx **a, const deform_network *net, int chunk);
/* Grows the per-thread buffers to nthreads. */
pg_status deform_amx_ensure_threads(deform_amx *a, int nthreads);
void deform_amx_destroy(deform_amx *a);

/* Packs the current weights (once per forward / backward call: they change every optimiser step). */
void deform_amx_pack_forward(deform_amx *a, const deform_network *net);
void deform_amx_pack_backward(deform_amx *a, const deform_network *net);

/* Sizes the feature store for nchunks chunks (call before the chunks' forward). */
pg_status deform_amx_prepare(deform_amx *a, long nchunks);
/* Forward of chunk k (m points) on thread tid: features feat (m, F) f32 are copied into the store
 * (feat == NULL: the stored ones are reused, the backward's rerun), then all layers into the
 * thread's activations; with y != NULL (the forward) also the heads, y (m, DEFORM_OUT_DIM) f32. */
void deform_amx_chunk_forward(deform_amx *a, int tid, long k, const float *feat, int m, float *y);

/* Backward: begin zeroes thread tid's accumulators; chunk_backward (right after the chunk's forward
 * rerun, feat == NULL, on the same thread) takes d_out rows dy (m, 59) f32 and returns d features (f32, row stride *ld);
 * end adds the thread's accumulated parameter gradients into grads (the thread's gradient buffer,
 * network layout). */
void deform_amx_backward_begin(deform_amx *a, int tid);
const float *deform_amx_chunk_backward(deform_amx *a, int tid, long k, const float *dy, int m, int *ld);
void deform_amx_backward_end(deform_amx *a, const deform_network *net, int tid, float *grads);

#endif
