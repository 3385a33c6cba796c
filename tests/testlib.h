/* testlib.h - a tiny test harness: checks that count, a summary line, temp dirs, CLI runs.
 *
 *   int main(void) {
 *       CHECK(x == 3, "x was %d", x);
 *       CHECK_NEAR(psnr, 35.0, ...);
 *       return test_summary("test_core");
 *   }
 * test_summary prints "name: N passed, N failed" and returns the exit code for ctest.
 */
#ifndef PG_TESTLIB_H
#define PG_TESTLIB_H

#include <stdio.h>

extern int test_passed, test_failed;

#define CHECK(cond, ...)                                                                      \
    do {                                                                                      \
        if (cond) {                                                                           \
            test_passed++;                                                                    \
        } else {                                                                              \
            test_failed++;                                                                    \
            fprintf(stderr, "FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond);                   \
            fprintf(stderr, __VA_ARGS__);                                                     \
            fprintf(stderr, "\n");                                                            \
        }                                                                                     \
    } while (0)

/* Checks that a pg_status call succeeded and prints the library's message if not. */
#define CHECK_OK(expr)                                                                        \
    do {                                                                                      \
        pg_status st__ = (expr);                                                              \
        CHECK(st__ == PG_OK, "%s -> %s", #expr, st__ ? pg_last_error() : "");                 \
    } while (0)

int test_summary(const char *name);
/* Creates (and empties) PG_TEST_TMP/<name>/ and writes its path into out. */
void test_tmpdir(const char *name, char *out, size_t size);
/* Runs the prodygs CLI with a shell-quoted argument string; captures stderr into err
 * (size bytes) and returns the exit code (or -1 if it did not exit normally). */
int test_run_cli(const char *args, char *err, size_t size);
/* Relative error |a - b| / max(|a|, |b|, floor). */
double test_rel_err(double a, double b, double floor);
/* Worst test_rel_err over n analytic (float) vs finite-difference (double) gradient entries,
 * with the floor at 1% of the largest |fd| so near-zero entries do not dominate. */
double test_grad_err(const float *g, const double *fd, size_t n);
/* 1 if the shared sample data directory (../shared/data/NAME) exists. */
int test_shared_data(const char *name, char *out, size_t size);
/* 1 if both files can be read (up to 1 GB each) and hold the same bytes. */
int test_files_equal(const char *a, const char *b);

/* Median of a[i] / b[i] over the i where both are > 0 (0 if there is none), e.g. a depth
 * map's scale against the ground truth. */
float test_median_ratio(const float *a, const float *b, size_t n);
/* Spearman rank correlation of a and b (average ranks for ties), e.g. depth against ground truth. */
double test_spearman(const float *a, const float *b, int n);

#endif
