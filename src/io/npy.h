/* npy.h - NumPy .npy arrays (format 1.0/2.0/3.0, C order).
 *
 * Loading converts any of float32/float64/uint8/uint16/int16/int32/int64 (either byte
 * order) and float16 to float32; saving writes little-endian float32 ('<f4'), float16 ('<f2') or
 * uint8 ('|u1').
 */
#ifndef PG_NPY_H
#define PG_NPY_H

#include <stddef.h>
#include <stdint.h>
#include "core/status.h"

#define PG_NPY_MAX_DIMS 4

typedef struct {
    int ndim;
    size_t shape[PG_NPY_MAX_DIMS];
    size_t count;  /* product of shape */
    float *data;   /* (shape...) as float32 */
} pg_array;

/* Loads path; fails with a message naming the file on truncation, bad header, unsupported
 * dtype, Fortran order or absurd sizes (limit: 2^31 elements). */
pg_status io_npy_load(const char *path, pg_array *arr);
/* Reads path's values straight into dst when they are little-endian float16 and count of them
 * (*loaded = 1; a host of that byte order); else leaves dst and sets *loaded = 0 (io_npy_load then
 * converts whatever they are). Errors as io_npy_load's. */
pg_status io_npy_load_half(const char *path, uint16_t *dst, size_t count, int *loaded);
/* Saves float32 data of the given shape atomically. */
pg_status io_npy_save(const char *path, const float *data, int ndim, const size_t *shape);
/* Saves float data as float16 ('<f2') when every value is 0 or within float16's normal range
 * (relative error <= 2^-11), else as float32; atomically. For depth and probability maps. */
pg_status io_npy_save_compact(const char *path, const float *data, int ndim, const size_t *shape);
/* Saves float data as float16 whatever it holds (values in [0, 1] keep 3e-5 absolute). */
pg_status io_npy_save_f16(const char *path, const float *data, int ndim, const size_t *shape);
/* Saves uint8 data of the given shape atomically (masks). */
pg_status io_npy_save_u8(const char *path, const unsigned char *data, int ndim, const size_t *shape);
void pg_array_destroy(pg_array *arr);
/* IEEE half (binary16) to float, exactly (subnormals, inf and NaN included); also used by EXR. */
float io_half_to_float(uint16_t h);
/* out[i] = io_half_to_float(h[i]) * scale for n values; 8 at a time with the CPU's F16C conversion
 * when it has one (the same numbers; a signalling NaN comes out quiet). */
void io_halves_to_floats(const uint16_t *h, size_t n, float scale, float *out);
/* float to IEEE half, rounding to nearest even (overflow gives inf). */
uint16_t io_float_to_half(float f);

#endif
