/* ply_internal.h - parsed PLY header and raw vertex access shared by ply_parse.c and ply.c. */
#ifndef PG_PLY_INTERNAL_H
#define PG_PLY_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include "core/status.h"

#define PLY_MAX_PROPS 256

typedef enum { PLY_I8, PLY_U8, PLY_I16, PLY_U16, PLY_I32, PLY_U32, PLY_F32, PLY_F64 } ply_type;

typedef struct {
    char name[64];
    ply_type type;
    int offset; /* bytes from the start of the vertex */
} ply_prop;

typedef struct {
    int count;
    int stride;            /* bytes per vertex */
    int big_endian;
    int nprops;
    ply_prop props[PLY_MAX_PROPS];
    int sh_degree_comment; /* -1 when absent */
    uint8_t *data;         /* (count, stride) raw vertex bytes */
} ply_file;

/* Reads the header and the vertex block into memory; checks counts against the file size. */
pg_status ply_read(const char *path, ply_file *pf);
void ply_free(ply_file *pf);
/* Index of a property by name, or -1. */
int ply_find(const ply_file *pf, const char *name);
/* Value of property p of vertex i as double. */
double ply_get(const ply_file *pf, int i, int p);

#endif
