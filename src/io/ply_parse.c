/* ply_parse.c - PLY header parsing, raw vertex access and the allocation-free probe. */
#include "io/ply.h"
#include "core/fileutil.h"
#include "io/ply_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <errno.h>
#include <string.h>

#define PLY_MAX_HEADER (1 << 20)
#define PLY_MAX_VERTICES 200000000

void ply_free(ply_file *pf)
{
    if (!pf) return;
    free(pf->data);
    memset(pf, 0, sizeof *pf);
}

int ply_find(const ply_file *pf, const char *name)
{
    for (int i = 0; i < pf->nprops; i++)
        if (!strcmp(pf->props[i].name, name)) return i;
    return -1;
}

static int type_size(ply_type t)
{
    static const int sz[] = { 1, 1, 2, 2, 4, 4, 4, 8 };
    return sz[t];
}

static int parse_type(const char *s, ply_type *t)
{
    static const struct { const char *name; ply_type t; } map[] = {
        { "char", PLY_I8 },   { "int8", PLY_I8 },     { "uchar", PLY_U8 },   { "uint8", PLY_U8 },
        { "short", PLY_I16 }, { "int16", PLY_I16 },   { "ushort", PLY_U16 }, { "uint16", PLY_U16 },
        { "int", PLY_I32 },   { "int32", PLY_I32 },   { "uint", PLY_U32 },   { "uint32", PLY_U32 },
        { "float", PLY_F32 }, { "float32", PLY_F32 }, { "double", PLY_F64 }, { "float64", PLY_F64 },
    };
    for (size_t i = 0; i < sizeof map / sizeof map[0]; i++)
        if (!strcmp(s, map[i].name)) { *t = map[i].t; return 0; }
    return -1;
}

double ply_get(const ply_file *pf, int i, int p)
{
    const ply_prop *pr = &pf->props[p];
    const uint8_t *src = pf->data + (size_t)i * pf->stride + pr->offset;
    uint8_t b[8];
    int n = type_size(pr->type);
    for (int k = 0; k < n; k++) b[k] = pf->big_endian ? src[n - 1 - k] : src[k];
    switch (pr->type) {
    case PLY_I8: return (int8_t)b[0];
    case PLY_U8: return b[0];
    case PLY_I16: { int16_t v; memcpy(&v, b, 2); return v; }
    case PLY_U16: { uint16_t v; memcpy(&v, b, 2); return v; }
    case PLY_I32: { int32_t v; memcpy(&v, b, 4); return v; }
    case PLY_U32: { uint32_t v; memcpy(&v, b, 4); return v; }
    case PLY_F32: { float v; memcpy(&v, b, 4); return v; }
    default: { double v; memcpy(&v, b, 8); return v; }
    }
}

/* Reads one header line (without the newline) into buf; -1 at EOF or overlong line. */
static int read_line(FILE *fp, char *buf, size_t size, size_t *total)
{
    size_t n = 0;
    int c;
    while ((c = fgetc(fp)) != EOF) {
        (*total)++;
        if (c == '\n') break;
        if (n + 1 >= size) return -1;
        buf[n++] = (char)c;
    }
    if (c == EOF && n == 0) return -1;
    if (n && buf[n - 1] == '\r') n--;
    buf[n] = '\0';
    return 0;
}

pg_status ply_read(const char *path, ply_file *pf)
{
    memset(pf, 0, sizeof *pf);
    pf->sh_degree_comment = -1;
    FILE *fp;
    PG_TRY(pg_open_read(path, &fp));
    pg_status st = PG_OK;
    char line[1024];
    size_t total = 0;
    int format_seen = 0, in_vertex = 0, vertex_seen = 0, elem_list = 0, ended = 0;
    size_t skip_before = 0, elem_count = 0, elem_stride = 0;
#define PLY_FAIL(code, ...) do { st = pg_fail(code, __VA_ARGS__); goto done; } while (0)
    if (read_line(fp, line, sizeof line, &total) || strcmp(line, "ply")) PLY_FAIL(PG_ERR_FORMAT, "%s: not a PLY file (bad magic)", path);
    while (!ended) {
        if (total > PLY_MAX_HEADER) PLY_FAIL(PG_ERR_FORMAT, "%s: header longer than %d bytes", path, PLY_MAX_HEADER);
        if (read_line(fp, line, sizeof line, &total)) PLY_FAIL(PG_ERR_FORMAT, "%s: truncated header (no end_header)", path);
        char w1[64] = "", w2[64] = "", w3[64] = "", w4[64] = "";
        int nw = sscanf(line, "%63s %63s %63s %63s", w1, w2, w3, w4);
        if (nw <= 0) continue;
        if (!strcmp(w1, "format")) {
            if (!strcmp(w2, "binary_little_endian")) pf->big_endian = 0;
            else if (!strcmp(w2, "binary_big_endian")) pf->big_endian = 1;
            else PLY_FAIL(PG_ERR_FORMAT, "%s: PLY format '%s' not supported (binary only)", path, w2);
            format_seen = 1;
        } else if (!strcmp(w1, "comment") || !strcmp(w1, "obj_info")) {
            int d;
            if (sscanf(line, "comment sh_degree %d", &d) == 1 && d >= 0 && d <= 3) pf->sh_degree_comment = d;
        } else if (!strcmp(w1, "element")) {
            if (in_vertex) vertex_seen = 1;
            else if (!vertex_seen && elem_count) {
                /* Finish the size of an element before the vertices so it can be skipped. */
                size_t b;
                if (elem_list) PLY_FAIL(PG_ERR_FORMAT, "%s: cannot skip an element with list properties before 'vertex'", path);
                if (pg_size_mul(elem_count, elem_stride, &b) || skip_before + b < skip_before)
                    PLY_FAIL(PG_ERR_SIZE, "%s: element sizes overflow", path);
                skip_before += b;
            }
            in_vertex = 0;
            elem_count = 0;
            elem_stride = 0;
            elem_list = 0;
            char *end;
            unsigned long long n = strtoull(w3, &end, 10);
            if (nw < 3 || *end || w3[0] == '-') PLY_FAIL(PG_ERR_FORMAT, "%s: bad element line '%s'", path, line);
            if (!strcmp(w2, "vertex") && !vertex_seen) {
                if (n > PLY_MAX_VERTICES) PLY_FAIL(PG_ERR_SIZE, "%s: vertex count %llu is absurd (limit %d)", path, n, PLY_MAX_VERTICES);
                in_vertex = 1;
                pf->count = (int)n;
            } else {
                if (n > ((size_t)1 << 40)) PLY_FAIL(PG_ERR_SIZE, "%s: element '%s' count %llu is absurd", path, w2, n);
                elem_count = (size_t)n;
            }
        } else if (!strcmp(w1, "property")) {
            if (!strcmp(w2, "list")) {
                if (in_vertex) PLY_FAIL(PG_ERR_FORMAT, "%s: list property '%s' in the vertex element is not supported", path, w4);
                elem_list = 1;
                continue;
            }
            ply_type t;
            if (nw < 3 || parse_type(w2, &t)) PLY_FAIL(PG_ERR_FORMAT, "%s: bad property line '%s'", path, line);
            if (in_vertex) {
                if (pf->nprops >= PLY_MAX_PROPS) PLY_FAIL(PG_ERR_FORMAT, "%s: more than %d vertex properties", path, PLY_MAX_PROPS);
                if (ply_find(pf, w3) >= 0) PLY_FAIL(PG_ERR_FORMAT, "%s: vertex property '%s' appears twice", path, w3);
                ply_prop *p = &pf->props[pf->nprops++];
                snprintf(p->name, sizeof p->name, "%s", w3);
                p->type = t;
                p->offset = pf->stride;
                pf->stride += type_size(t);
            } else {
                elem_stride += (size_t)type_size(t);
            }
        } else if (!strcmp(w1, "end_header")) {
            ended = 1;
        } else {
            PLY_FAIL(PG_ERR_FORMAT, "%s: unexpected header line '%s'", path, line);
        }
    }
    if (!format_seen) PLY_FAIL(PG_ERR_FORMAT, "%s: header has no format line", path);
    if (!in_vertex && !vertex_seen) PLY_FAIL(PG_ERR_FORMAT, "%s: no 'vertex' element", path);
    if (pf->stride == 0) PLY_FAIL(PG_ERR_FORMAT, "%s: vertex element has no properties", path);
    {
        long header_end = ftell(fp);
        fseek(fp, 0, SEEK_END);
        long file_end = ftell(fp);
        size_t need;
        if (pg_size_mul((size_t)pf->count, (size_t)pf->stride, &need))
            PLY_FAIL(PG_ERR_SIZE, "%s: vertex block size overflows", path);
        size_t have = file_end > header_end ? (size_t)(file_end - header_end) : 0;
        if (skip_before > have || need > have - skip_before)
            PLY_FAIL(PG_ERR_FORMAT, "%s: truncated: header promises %d vertices x %d bytes (%zu bytes), file has %zu after the header",
                     path, pf->count, pf->stride, need, have - (skip_before < have ? skip_before : have));
        fseek(fp, header_end + (long)skip_before, SEEK_SET);
        pf->data = pg_malloc(need ? need : 1, path);
        if (!pf->data) { st = PG_ERR_NOMEM; goto done; }
        if (need && fread(pf->data, 1, need, fp) != need) PLY_FAIL(PG_ERR_FORMAT, "%s: truncated vertex data", path);
    }
#undef PLY_FAIL
done:
    fclose(fp);
    if (st) ply_free(pf);
    return st;
}

pg_status io_ply_probe(const char *path, io_ply_info *info)
{
    memset(info, 0, sizeof *info);
    ply_file pf;
    PG_TRY(ply_read(path, &pf));
    int px = ply_find(&pf, "x"), py = ply_find(&pf, "y"), pz = ply_find(&pf, "z"), po = ply_find(&pf, "opacity");
    if (px < 0 || py < 0 || pz < 0) {
        ply_free(&pf);
        return pg_fail(PG_ERR_FORMAT, "%s: vertex element lacks x, y or z", path);
    }
    int nrest = 0, highest = 0;
    char name[32];
    for (int k = 0; k < 45; k++) {
        snprintf(name, sizeof name, "f_rest_%d", k);
        if (ply_find(&pf, name) >= 0) nrest++, highest = k + 1;
    }
    if (nrest != highest || (nrest != 0 && nrest != 9 && nrest != 24 && nrest != 45)) {
        ply_free(&pf);
        return pg_fail(PG_ERR_FORMAT, "%s: %d f_rest properties (expected f_rest_0.. with 0, 9, 24 or 45)", path, nrest);
    }
    info->count = pf.count;
    info->num_rest = nrest;
    info->sh_degree = pf.sh_degree_comment >= 0 ? pf.sh_degree_comment : nrest >= 45 ? 3 : nrest >= 24 ? 2 : nrest >= 9 ? 1 : 0;
    info->has_opacity = po >= 0;
    info->has_scale = ply_find(&pf, "scale_0") >= 0;
    info->has_rot = ply_find(&pf, "rot_0") >= 0;
    double osum = 0;
    for (int k = 0; k < 3; k++) { info->bbox_min[k] = INFINITY; info->bbox_max[k] = -INFINITY; }
    for (int i = 0; i < pf.count; i++) {
        double v[3] = { ply_get(&pf, i, px), ply_get(&pf, i, py), ply_get(&pf, i, pz) };
        for (int k = 0; k < 3; k++) {
            if (!isfinite(v[k])) {
                ply_free(&pf);
                return pg_fail(PG_ERR_FORMAT, "%s: vertex %d has a non-finite position", path, i);
            }
            if (v[k] < info->bbox_min[k]) info->bbox_min[k] = (float)v[k];
            if (v[k] > info->bbox_max[k]) info->bbox_max[k] = (float)v[k];
        }
        double o = po >= 0 ? ply_get(&pf, i, po) : 2.0;
        osum += 1.0 / (1.0 + exp(-o));
    }
    if (pf.count == 0)
        for (int k = 0; k < 3; k++) info->bbox_min[k] = info->bbox_max[k] = 0;
    info->mean_opacity = pf.count ? (float)(osum / pf.count) : 0;
    ply_free(&pf);
    return PG_OK;
}
