/* mathx.h - small fixed-size linear algebra on plain float arrays.
 *
 * Vectors are float[3], 3x3 matrices float[9] row-major, quaternions float[4]
 * ordered (w, x, y, z). Everything is static inline so hot loops can use it.
 */
#ifndef PG_MATHX_H
#define PG_MATHX_H

#include <math.h>
#include <stddef.h>

#define PG_PI 3.14159265358979323846

static inline float vec3_dot(const float a[3], const float b[3]) { return a[0]*b[0] + a[1]*b[1] + a[2]*b[2]; }
static inline float vec3_norm(const float a[3]) { return sqrtf(vec3_dot(a, a)); }
static inline void vec3_sub(float out[3], const float a[3], const float b[3]) { out[0]=a[0]-b[0]; out[1]=a[1]-b[1]; out[2]=a[2]-b[2]; }
static inline void vec3_add(float out[3], const float a[3], const float b[3]) { out[0]=a[0]+b[0]; out[1]=a[1]+b[1]; out[2]=a[2]+b[2]; }
static inline void vec3_scale(float out[3], const float a[3], float s) { out[0]=a[0]*s; out[1]=a[1]*s; out[2]=a[2]*s; }
static inline void vec3_cross(float out[3], const float a[3], const float b[3])
{
    float x = a[1]*b[2] - a[2]*b[1], y = a[2]*b[0] - a[0]*b[2], z = a[0]*b[1] - a[1]*b[0];
    out[0] = x; out[1] = y; out[2] = z;
}
static inline void vec3_normalize(float a[3])
{
    float n = vec3_norm(a);
    if (n > 0) { a[0] /= n; a[1] /= n; a[2] /= n; }
}

/* out = m * v */
static inline void mat3_mul_vec(float out[3], const float m[9], const float v[3])
{
    float x = m[0]*v[0] + m[1]*v[1] + m[2]*v[2];
    float y = m[3]*v[0] + m[4]*v[1] + m[5]*v[2];
    float z = m[6]*v[0] + m[7]*v[1] + m[8]*v[2];
    out[0] = x; out[1] = y; out[2] = z;
}
/* out = m^T * v */
static inline void mat3_tmul_vec(float out[3], const float m[9], const float v[3])
{
    float x = m[0]*v[0] + m[3]*v[1] + m[6]*v[2];
    float y = m[1]*v[0] + m[4]*v[1] + m[7]*v[2];
    float z = m[2]*v[0] + m[5]*v[1] + m[8]*v[2];
    out[0] = x; out[1] = y; out[2] = z;
}
/* out = a * b (out may not alias a or b) */
static inline void mat3_mul(float out[9], const float a[9], const float b[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            out[3*i+j] = a[3*i]*b[j] + a[3*i+1]*b[3+j] + a[3*i+2]*b[6+j];
}
static inline void mat3_transpose(float out[9], const float m[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            out[3*j+i] = m[3*i+j];
}
static inline void mat3_identity(float m[9])
{
    for (int i = 0; i < 9; i++) m[i] = (i % 4 == 0) ? 1.0f : 0.0f;
}

/* Rotation matrix of a unit quaternion (w, x, y, z). */
static inline void quat_to_mat3(float m[9], const float q[4])
{
    float w = q[0], x = q[1], y = q[2], z = q[3];
    m[0] = 1 - 2*(y*y + z*z); m[1] = 2*(x*y - w*z);     m[2] = 2*(x*z + w*y);
    m[3] = 2*(x*y + w*z);     m[4] = 1 - 2*(x*x + z*z); m[5] = 2*(y*z - w*x);
    m[6] = 2*(x*z - w*y);     m[7] = 2*(y*z + w*x);     m[8] = 1 - 2*(x*x + y*y);
}

/* Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method, w >= 0). */
static inline void mat3_to_quat(float q[4], const float m[9])
{
    float tr = m[0] + m[4] + m[8];
    if (tr > 0) {
        float s = sqrtf(tr + 1.0f) * 2;
        q[0] = 0.25f * s; q[1] = (m[7] - m[5]) / s; q[2] = (m[2] - m[6]) / s; q[3] = (m[3] - m[1]) / s;
    } else if (m[0] > m[4] && m[0] > m[8]) {
        float s = sqrtf(1.0f + m[0] - m[4] - m[8]) * 2;
        q[0] = (m[7] - m[5]) / s; q[1] = 0.25f * s; q[2] = (m[1] + m[3]) / s; q[3] = (m[2] + m[6]) / s;
    } else if (m[4] > m[8]) {
        float s = sqrtf(1.0f + m[4] - m[0] - m[8]) * 2;
        q[0] = (m[2] - m[6]) / s; q[1] = (m[1] + m[3]) / s; q[2] = 0.25f * s; q[3] = (m[5] + m[7]) / s;
    } else {
        float s = sqrtf(1.0f + m[8] - m[0] - m[4]) * 2;
        q[0] = (m[3] - m[1]) / s; q[1] = (m[2] + m[6]) / s; q[2] = (m[5] + m[7]) / s; q[3] = 0.25f * s;
    }
    if (q[0] < 0) { q[0] = -q[0]; q[1] = -q[1]; q[2] = -q[2]; q[3] = -q[3]; }
}

/* Rotation of angle (radians) about a unit axis. */
static inline void mat3_axis_angle(float m[9], const float axis[3], float angle)
{
    float h = 0.5f * angle, s = sinf(h);
    float q[4] = { cosf(h), axis[0]*s, axis[1]*s, axis[2]*s };
    quat_to_mat3(m, q);
}

/* 1 if the rows of m are orthonormal within tol (|m m^T - I| <= tol entrywise, summed in double). */
static inline int mat3_is_orthonormal(const float m[9], double tol)
{
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double d = 0;
            for (int k = 0; k < 3; k++) d += (double)m[a * 3 + k] * m[b * 3 + k];
            if (fabs(d - (a == b)) > tol) return 0;
        }
    return 1;
}

/* qsort comparator: ascending floats. */
static inline int pg_cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* qsort comparator for doubles, ascending. */
static inline int pg_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* k-th smallest of v[0..m) by quickselect (reorders v); O(m) on average. */
static inline double pg_select_kth(double *v, size_t m, size_t kk)
{
    long lo = 0, hi = (long)m - 1, k = (long)kk;
    while (lo < hi) {
        double pivot = v[lo + (hi - lo) / 2];
        long i = lo, j = hi;
        while (i <= j) {
            while (v[i] < pivot) i++;
            while (v[j] > pivot) j--;
            if (i <= j) {
                double t = v[i];
                v[i++] = v[j];
                v[j--] = t;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break;
    }
    return v[k];
}

static inline float clampf(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }
static inline int clampi(int x, int lo, int hi) { return x < lo ? lo : (x > hi ? hi : x); }

#endif
