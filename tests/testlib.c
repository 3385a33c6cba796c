/* testlib.c - implementation of the small test harness. */
#include "testlib.h"
#include "core/fileutil.h"
#include "core/mathx.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

int test_passed, test_failed;

int test_summary(const char *name)
{
    printf("%s: %d passed, %d failed\n", name, test_passed, test_failed);
    return test_failed ? 1 : 0;
}

void test_tmpdir(const char *name, char *out, size_t size)
{
    snprintf(out, size, "%s/%s", PG_TEST_TMP, name);
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", out, out);
    if (system(cmd) != 0) fprintf(stderr, "warning: could not prepare %s\n", out);
}

int test_run_cli(const char *args, char *err, size_t size)
{
    char tmp[4096], cmd[16384];
    snprintf(tmp, sizeof tmp, "%s/cli-stderr-%d.txt", PG_TEST_TMP, (int)getpid());
    snprintf(cmd, sizeof cmd, "mkdir -p '%s' && '%s' %s 2>'%s' >/dev/null </dev/null", PG_TEST_TMP, PG_CLI_PATH, args, tmp);
    int rc = system(cmd);
    if (err && size) {
        err[0] = '\0';
        FILE *fp = fopen(tmp, "rb");
        if (fp) {
            size_t n = fread(err, 1, size - 1, fp);
            err[n] = '\0';
            fclose(fp);
        }
    }
    remove(tmp);
    if (rc == -1 || !WIFEXITED(rc)) return -1;
    return WEXITSTATUS(rc);
}

double test_rel_err(double a, double b, double floor)
{
    double m = fabs(a) > fabs(b) ? fabs(a) : fabs(b);
    if (m < floor) m = floor;
    return fabs(a - b) / m;
}

double test_grad_err(const float *g, const double *fd, size_t n)
{
    double mx = 0;
    for (size_t i = 0; i < n; i++) mx = fmax(mx, fabs(fd[i]));
    double worst = 0;
    for (size_t i = 0; i < n; i++) worst = fmax(worst, test_rel_err(g[i], fd[i], 1e-2 * mx + 1e-30));
    return worst;
}

int test_shared_data(const char *name, char *out, size_t size)
{
    snprintf(out, size, "%s/data/%s", PG_SHARED_DIR, name);
    return pg_path_is_dir(out);
}

int test_files_equal(const char *a, const char *b)
{
    char *da = NULL, *db = NULL;
    size_t na = 0, nb = 0;
    int eq = !pg_read_file(a, (size_t)1 << 30, &da, &na) && !pg_read_file(b, (size_t)1 << 30, &db, &nb) && na == nb &&
             memcmp(da, db, na) == 0;
    free(da);
    free(db);
    return eq;
}

float test_median_ratio(const float *a, const float *b, size_t n)
{
    float *r = malloc((n ? n : 1) * sizeof(float));
    if (!r) return 0;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (a[i] > 0 && b[i] > 0) r[k++] = a[i] / b[i];
    qsort(r, k, sizeof(float), pg_cmp_float);
    float med = k ? r[k / 2] : 0;
    free(r);
    return med;
}

/* Spearman rank correlation (average ranks for ties). */
static const float *rank_key;
static int rank_cmp(const void *a, const void *b)
{
    float x = rank_key[*(const int *)a], y = rank_key[*(const int *)b];
    return (x > y) - (x < y);
}
static void ranks(const float *v, int n, double *r)
{
    int *idx = malloc((size_t)n * sizeof(int));
    for (int i = 0; i < n; i++) idx[i] = i;
    rank_key = v;
    qsort(idx, (size_t)n, sizeof(int), rank_cmp);
    for (int i = 0; i < n;) {
        int j = i;
        while (j + 1 < n && v[idx[j + 1]] == v[idx[i]]) j++;
        for (int k = i; k <= j; k++) r[idx[k]] = (i + j) / 2.0;
        i = j + 1;
    }
    free(idx);
}
double test_spearman(const float *a, const float *b, int n)
{
    double *ra = malloc((size_t)n * sizeof(double)), *rb = malloc((size_t)n * sizeof(double));
    ranks(a, n, ra);
    ranks(b, n, rb);
    double ma = 0, mb = 0, sab = 0, saa = 0, sbb = 0;
    for (int i = 0; i < n; i++) ma += ra[i], mb += rb[i];
    ma /= n, mb /= n;
    for (int i = 0; i < n; i++) {
        sab += (ra[i] - ma) * (rb[i] - mb);
        saa += (ra[i] - ma) * (ra[i] - ma);
        sbb += (rb[i] - mb) * (rb[i] - mb);
    }
    free(ra);
    free(rb);
    return sab / sqrt(saa * sbb);
}
