/* test_splat_adam.c - Adam optimiser: exact first step, convergence, learning-rate schedule,
 * strided Gaussian groups and moment remapping for clone / prune, column-limited steps,
 * column ranges of one row. */
#include "testlib.h"
#include "optim/adam.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static void test_first_step_and_convergence(void)
{
    optim_adam *opt;
    CHECK_OK(optim_adam_create_flat(&opt, 3, 1e-15f));
    float x[3] = { 1, -2, 0.5f }, g[3] = { 4, -0.001f, 0 };
    CHECK_OK(optim_adam_step_group(opt, 0, x, g, 0.1f));
    /* bias-corrected first step is lr * sign(g) (0 where g = 0) */
    CHECK(fabsf(x[0] - 0.9f) < 1e-6f && fabsf(x[1] + 1.9f) < 1e-6f && x[2] == 0.5f,
          "first step gave %g %g %g", x[0], x[1], x[2]);
    optim_adam_destroy(opt);

    CHECK_OK(optim_adam_create_flat(&opt, 2, 1e-8f));
    float p[2] = { 5, -3 }, t[2] = { 1, 2 };
    for (int it = 0; it < 2000; it++) {
        float gr[2] = { 2 * (p[0] - t[0]), 2 * (p[1] - t[1]) };
        CHECK_OK(optim_adam_step_group(opt, 0, p, gr, 0.05f));
    }
    CHECK(fabsf(p[0] - 1) < 1e-2f && fabsf(p[1] - 2) < 1e-2f, "quadratic not minimised: %g %g", p[0], p[1]);
    CHECK(optim_adam_step_group(opt, 3, p, t, 0.1f) == PG_ERR_ARG, "bad group index accepted");
    optim_adam_destroy(opt);
}

static void test_schedule(void)
{
    optim_lr_schedule s = { 1.6e-4f, 1.6e-6f, 0, 1.0f, 30000 };
    CHECK(fabsf(optim_lr_expon(&s, 0) - 1.6e-4f) < 1e-10f, "lr(0) = %g", optim_lr_expon(&s, 0));
    CHECK(fabsf(optim_lr_expon(&s, 30000) - 1.6e-6f) < 1e-11f, "lr(max) = %g", optim_lr_expon(&s, 30000));
    CHECK(fabsf(optim_lr_expon(&s, 15000) - 1.6e-5f) < 1e-9f, "lr(mid) = %g (geometric mean expected)", optim_lr_expon(&s, 15000));
    CHECK(fabsf(optim_lr_expon(&s, 90000) - 1.6e-6f) < 1e-11f, "lr past max = %g", optim_lr_expon(&s, 90000));
    CHECK(optim_lr_expon(&s, -1) == 0, "negative step");
    optim_lr_schedule d = { 1e-2f, 1e-2f, 100, 0.01f, 1000 };
    CHECK(fabsf(optim_lr_expon(&d, 0) - 1e-4f) < 1e-9f, "delayed lr(0) = %g", optim_lr_expon(&d, 0));
    CHECK(fabsf(optim_lr_expon(&d, 100) - 1e-2f) < 1e-7f, "delayed lr(100) = %g", optim_lr_expon(&d, 100));
    /* an end <= 0 has no logarithm: linear instead */
    optim_lr_schedule z = { 1e-2f, 0, 0, 1.0f, 100 };
    CHECK(optim_lr_expon(&z, 0) == 1e-2f && fabsf(optim_lr_expon(&z, 25) - 7.5e-3f) < 1e-9f &&
              optim_lr_expon(&z, 100) == 0,
          "decay to 0: %g %g %g", optim_lr_expon(&z, 0), optim_lr_expon(&z, 25), optim_lr_expon(&z, 100));
    optim_lr_schedule u = { 0, 1e-2f, 0, 1.0f, 100 };
    CHECK(optim_lr_expon(&u, 0) == 0 && fabsf(optim_lr_expon(&u, 50) - 5e-3f) < 1e-9f, "ramp from 0: %g",
          optim_lr_expon(&u, 50));
}

/* Stepping the first k columns equals a full step when the other columns have zero gradient,
 * leaves those columns alone and counts a step; two groups in one pass equal two separate
 * steps; one row split in column ranges (as a network's grids and MLP) steps like separate
 * flat arrays. */
static void test_column_steps(void)
{
    optim_group_desc d[2] = { { "dc", 6, 0, 1 }, { "rest", 6, 1, 5 } };
    optim_adam *a, *b;
    CHECK_OK(optim_adam_create(&a, d, 2, 2, 1e-15f));
    CHECK_OK(optim_adam_create(&b, d, 2, 2, 1e-15f));
    float pa[12], pb[12], g[12] = { 9, 1, -2, 0, 0, 0, -9, 3, 0.5f, 0, 0, 0 };
    for (int i = 0; i < 12; i++) pa[i] = pb[i] = (float)i;
    optim_group_step two[2] = { { 0, pa, g, 0.3f, 1, NULL, 1.0f }, { 1, pa, g, 0.1f, 2, NULL, 1.0f } };
    two[1].cols = 6;
    CHECK(optim_adam_step_groups(a, two, 2) == PG_ERR_ARG && optim_adam_group_step(a, 0) == 0,
          "too many columns accepted");
    two[1].cols = 2;
    two[1].group = 0;
    CHECK(optim_adam_step_groups(a, two, 2) == PG_ERR_ARG, "group listed twice accepted");
    two[1].group = 1;
    for (int it = 0; it < 3; it++) {
        CHECK_OK(optim_adam_step_groups(a, two, 2));
        CHECK_OK(optim_adam_step_group(b, 0, pb, g, 0.3f));
        CHECK_OK(optim_adam_step_group(b, 1, pb, g, 0.1f));
    }
    CHECK(memcmp(pa, pb, sizeof pa) == 0, "fused 2-column steps differ from separate full steps");
    CHECK(pa[0] != 0 && pa[6] != 6 && pa[1] != 1 && pa[3] == 3 && pa[9] == 9, "wrong columns moved");
    CHECK(optim_adam_group_step(a, 0) == 3 && optim_adam_group_step(a, 1) == 3, "steps counted %d %d",
          optim_adam_group_step(a, 0), optim_adam_group_step(a, 1));
    two[1].cols = 0;
    CHECK_OK(optim_adam_step_groups(a, two + 1, 1));
    CHECK(optim_adam_group_step(a, 1) == 4 && memcmp(pa, pb, sizeof pa) == 0, "0-column step");
    CHECK(optim_adam_num_groups(a) == 2 && optim_adam_moment_size(a, 1) == 10 && optim_adam_moment_size(a, 2) == 0,
          "group sizes");
    optim_adam_destroy(a);
    optim_adam_destroy(b);

    optim_group_desc ranges[2] = { { "grid", 7, 0, 3 }, { "mlp", 7, 3, 4 } };
    optim_adam *r, *f0, *f1;
    CHECK_OK(optim_adam_create(&r, ranges, 2, 1, 1e-15f));
    CHECK_OK(optim_adam_create_flat(&f0, 3, 1e-15f));
    CHECK_OK(optim_adam_create_flat(&f1, 4, 1e-15f));
    float p[7] = { 1, 2, 3, 4, 5, 6, 7 }, q[7], gr[7] = { 0.3f, -1, 2, 5, -0.25f, 1e-3f, 0 };
    memcpy(q, p, sizeof p);
    for (int it = 0; it < 4; it++) {
        CHECK_OK(optim_adam_step_group(r, 0, p, gr, 0.01f));
        CHECK_OK(optim_adam_step_group(r, 1, p, gr, 0.2f));
        CHECK_OK(optim_adam_step_group(f0, 0, q, gr, 0.01f));
        CHECK_OK(optim_adam_step_group(f1, 0, q + 3, gr + 3, 0.2f));
    }
    CHECK(memcmp(p, q, sizeof p) == 0, "column ranges of one row differ from flat arrays");
    CHECK(memcmp(optim_adam_moment(r, 1, 1), optim_adam_moment(f1, 0, 1), 4 * sizeof(float)) == 0, "range moments");
    optim_adam_destroy(r);
    optim_adam_destroy(f0);
    optim_adam_destroy(f1);

    /* boosted rows: row 0 at twice the rate, row 1 at the rate, as two separate optimisers */
    optim_group_desc rows2 = { "rows", 3, 0, 3 };
    optim_adam *w, *w0, *w1;
    CHECK_OK(optim_adam_create(&w, &rows2, 1, 2, 1e-15f));
    CHECK_OK(optim_adam_create(&w0, &rows2, 1, 1, 1e-15f));
    CHECK_OK(optim_adam_create(&w1, &rows2, 1, 1, 1e-15f));
    float pw[6] = { 1, 2, 3, 4, 5, 6 }, pv[6], gw[6] = { 0.5f, -2, 1e-3f, 3, -0.1f, 7 };
    const uint8_t boosted[2] = { 1, 0 };
    memcpy(pv, pw, sizeof pw);
    optim_group_step rs = { 0, pw, gw, 0.3f, 3, boosted, 2.0f };
    for (int it = 0; it < 3; it++) {
        CHECK_OK(optim_adam_step_groups(w, &rs, 1));
        CHECK_OK(optim_adam_step_group(w0, 0, pv, gw, 0.6f));
        CHECK_OK(optim_adam_step_group(w1, 0, pv + 3, gw + 3, 0.3f));
    }
    CHECK(memcmp(pw, pv, sizeof pw) == 0, "boosted rows differ from separate rates: %g vs %g, %g vs %g", pw[0],
          pv[0], pw[3], pv[3]);
    CHECK(pw[0] != 1 && pw[3] != 4, "rows did not move");
    optim_adam_destroy(w);
    optim_adam_destroy(w0);
    optim_adam_destroy(w1);
}

static void test_gaussian_groups_and_remap(void)
{
    pg_gaussians g, gr;
    CHECK_OK(splat_gaussians_create(&g, 3));
    CHECK_OK(splat_gaussians_resize(&g, 3));
    CHECK_OK(splat_gaussians_create(&gr, 3));
    CHECK_OK(splat_gaussians_resize(&gr, 3));
    for (int i = 0; i < 3; i++) {
        for (int k = 0; k < 3; k++) gr.means[3*i+k] = (float)(i + 1);
        for (int k = 0; k < 48; k++) gr.sh[48*i+k] = 1;
        gr.opacity[i] = -1;
    }
    optim_adam *opt;
    CHECK_OK(optim_adam_create_gaussians(&opt, 3, g.sh_stride, 1e-15f));
    float lr[OPTIM_GAUSS_GROUPS] = { 0.1f, 0, 0, 0.2f, 0.3f, 0.01f };
    CHECK_OK(optim_adam_step_gaussians(opt, &g, &gr, lr));
    CHECK(fabsf(g.means[0] + 0.1f) < 1e-6f && fabsf(g.opacity[2] - 0.2f) < 1e-6f, "means/opacity step wrong");
    CHECK(fabsf(g.sh[48 + 2] + 0.3f) < 1e-6f && fabsf(g.sh[48 + 3] + 0.01f) < 1e-6f && fabsf(g.sh[47] + 0.01f) < 1e-6f,
          "SH dc/rest groups got %g %g %g", g.sh[50], g.sh[51], g.sh[47]);
    CHECK(g.log_scales[0] == 0 && g.quats[0] == 0, "frozen groups changed");
    CHECK(optim_adam_group_step(opt, OPTIM_G_MEANS) == 1 && optim_adam_group_step(opt, OPTIM_G_QUATS) == 0,
          "frozen group advanced its step");
    /* moments of row i are (1 - beta1) * grad_i for the means group */
    int src[4] = { 2, 0, -1, 0 };
    CHECK_OK(optim_adam_remap_rows(opt, src, 4));
    float *m = optim_adam_moment(opt, OPTIM_G_MEANS, 0);
    CHECK(fabsf(m[0] - 0.3f) < 1e-6f && fabsf(m[3] - 0.1f) < 1e-6f && m[6] == 0 && fabsf(m[9] - 0.1f) < 1e-6f,
          "remapped moments %g %g %g %g", m[0], m[3], m[6], m[9]);
    CHECK(optim_adam_rows(opt) == 4, "rows after remap %d", optim_adam_rows(opt));
    int bad[1] = { 7 };
    CHECK(optim_adam_remap_rows(opt, bad, 1) == PG_ERR_ARG && optim_adam_rows(opt) == 4, "bad remap accepted");
    /* stepping with the old row count is refused */
    CHECK(optim_adam_step_gaussians(opt, &g, &gr, lr) == PG_ERR_ARG, "row-count mismatch accepted");
    CHECK_OK(splat_gaussians_resize(&g, 4));
    CHECK_OK(splat_gaussians_resize(&gr, 4));
    CHECK_OK(optim_adam_step_gaussians(opt, &g, &gr, lr));
    optim_adam_reset_group(opt, OPTIM_G_OPACITY);
    CHECK(optim_adam_moment(opt, OPTIM_G_OPACITY, 1)[1] == 0, "reset group kept moments");
    optim_adam_destroy(opt);
    splat_gaussians_destroy(&g);
    splat_gaussians_destroy(&gr);
}

int main(void)
{
    test_first_step_and_convergence();
    test_schedule();
    test_column_steps();
    test_gaussian_groups_and_remap();
    return test_summary("test_splat_adam");
}
