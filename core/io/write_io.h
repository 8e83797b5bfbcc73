/* core/io/write_io.h - helpers shared by the volume writers (write.c, write_nrrd.c,
 * write_nifti.c). Internal to libcdvr; not a public header. See cdvr/write.h. */
#ifndef CDVR_WRITE_IO_H
#define CDVR_WRITE_IO_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "cdvr/error.h"
#include "cdvr/volume.h"

/* One writer: vol checked (geometry, data), compress 0 or 1 (already resolved). */
typedef cdvr_status (*cdvr_writer_fn)(const cdvr_volume *vol, const char *path, int compress,
                                      cdvr_error *err);

cdvr_status cdvr_write_nrrd(const cdvr_volume *vol, const char *path, int compress, cdvr_error *err);
cdvr_status cdvr_write_nifti(const cdvr_volume *vol, const char *path, int compress,
                             cdvr_error *err);

/* M = D * diag(spacing) (row-major), with D the volume's direction (identity for all zeros). */
void cdvr_write_matrix(const cdvr_volume *vol, double M[9]);

/* path without its last `suffix_len` characters + tail, malloc'd (NULL when out of memory). */
char *cdvr_write_sibling(const char *path, size_t suffix_len, const char *tail);
/* The last path component of p. */
const char *cdvr_write_basename(const char *p);

/* CDVR_OK when path does not exist or is a regular file (symbolic links followed); else
 * CDVR_ERR_IO "path: cannot save over a directory ..." (before anything is written). */
cdvr_status cdvr_write_check_target(const char *path, cdvr_error *err);

/* Writes n bytes (in pieces, so counts above INT_MAX work); 0 on a short write. */
int cdvr_write_all(FILE *f, const void *p, size_t n);

/* The bytes of a zlib (gzip != 0: gzip) stream of src[0..n) into a malloc'd *out. */
cdvr_status cdvr_write_deflate(const char *path, const void *src, size_t n, int gzip,
                               uint8_t **out, size_t *out_n, cdvr_error *err);

/* Writes n bytes to path through cdvr/atomicfile.h (a detached data file); compress: as a gzip
 * stream (1) or a zlib stream (2). */
cdvr_status cdvr_write_data_file(const char *path, const void *data, size_t n, int compress,
                                 cdvr_error *err);

#endif
