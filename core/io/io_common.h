/* core/io/io_common.h - helpers of the VTK, MetaImage and TIFF loaders (io_vti.c, io_vtk.c,
 * io_mha.c, io_tiff.c). Internal to libcdvr; not a public header.
 *
 *  - a read-only mapping of a regular file (special files refused), so a probe touches only the
 *    header's pages and a load copies the voxels once;
 *  - file element types (the ten C scalar types) and their conversion into a cdvr_volume: u8,
 *    u16, i16 and f32 are kept; i8, i32, u32, i64, u64 and f64 become f32 and the volume's value
 *    window is the range of the file's values computed in double (so the classification window
 *    is not narrowed; the voxels themselves are float);
 *  - zlib inflate into an exact-size buffer (a stream that inflates to more or less is refused);
 *  - base64 decoding (whitespace skipped) and ASCII numbers.
 * Every size a header claims is checked by the caller against the mapping before allocating. */
#ifndef CDVR_IO_COMMON_H
#define CDVR_IO_COMMON_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/volume.h"
#include "volume_io.h"

typedef struct cdvr_io_map {
    const uint8_t *p; /* NULL for an empty file */
    size_t n;
} cdvr_io_map;

/* Maps path read-only (a regular file; else CDVR_ERR_IO naming path and what it is). */
cdvr_status cdvr_io_map_open(const char *path, cdvr_io_map *map, cdvr_error *err);
void cdvr_io_map_close(cdvr_io_map *map);

typedef enum cdvr_io_etype {
    CDVR_IO_I8, CDVR_IO_U8, CDVR_IO_I16, CDVR_IO_U16, CDVR_IO_I32, CDVR_IO_U32,
    CDVR_IO_I64, CDVR_IO_U64, CDVR_IO_F32, CDVR_IO_F64, CDVR_IO_ETYPES
} cdvr_io_etype;

/* Bytes per element (1..8). */
size_t cdvr_io_etype_size(cdvr_io_etype t);
/* "int8", "uint8", ..., "float64". */
const char *cdvr_io_etype_name(cdvr_io_etype t);
/* The volume type an element type loads as (u8, u16, i16, f32 kept; the others f32). */
cdvr_type cdvr_io_etype_volume_type(cdvr_io_etype t);
/* 1 when the element type is converted to f32 on load (its window then computed in double). */
int cdvr_io_etype_converted(cdvr_io_etype t);

/* Sets head->type to the type t loads as and head->source_type to t's name (probes and loads
 * alike, so a lazy series reports a conversion before reading a voxel). */
void cdvr_io_set_type(cdvr_volume *head, cdvr_io_etype t);

/* Running range of converted values (finite ones; lo > hi while empty) and the values beyond
 * f32 (cdvr_f32_guard: refused or accepted as +-Inf by opts, the rule of volume_io.h). */
typedef struct cdvr_io_range {
    double lo, hi;
    cdvr_f32_guard guard;
} cdvr_io_range;
void cdvr_io_range_init(cdvr_io_range *r, const cdvr_raw_opts *opts);

/* Stores count elements of type t from src (file byte order big_endian) into vol's data from
 * element `at` on (vol->type must be cdvr_io_etype_volume_type(t)); converted values extend r. */
void cdvr_io_store(cdvr_volume *vol, size_t at, const void *src, cdvr_io_etype t, int big_endian,
                   size_t count, cdvr_io_range *r);
/* Stores one value given as double (ASCII data): rounded and clamped for integer volume types. */
void cdvr_io_store_double(cdvr_volume *vol, size_t at, double v, cdvr_io_range *r);
/* Sets vol->source_type to t's name and, for a converted type, vol->window to r (or [0, 0]
 * when no finite value); then the f32 rule (cdvr_f32_guard_finish: values beyond f32 refused
 * naming path, `what` (e.g. "VTK") and the first voxel, unless the options accept +-Inf). */
cdvr_status cdvr_io_finish(cdvr_volume *vol, cdvr_io_etype t, const cdvr_io_range *r,
                           const char *path, const char *what, cdvr_error *err);

/* Inflates a zlib (or gzip) stream src[0..n) into exactly dst_n bytes at dst; a stream that is corrupt,
 * ends early or holds more is CDVR_ERR_FORMAT naming path and what. */
cdvr_status cdvr_io_inflate(const char *path, const char *what, const uint8_t *src, size_t n,
                            uint8_t *dst, size_t dst_n, cdvr_error *err);

/* Base64: decodes from text[*pos..n) until out_n bytes are written to out (whitespace skipped;
 * '=' padding ends a group, after which decoding continues with the next group, as VTK writes a
 * header and its data as two base64 streams). Returns 0 when the text ends early or holds a
 * character that is not base64. *pos is left after the last group used. */
int cdvr_io_base64(const uint8_t *text, size_t n, size_t *pos, uint8_t *out, size_t out_n);
/* Upper bound of the bytes that text[pos..n) decodes to. */
size_t cdvr_io_base64_bound(size_t pos, size_t n);

/* Next ASCII number from text[*pos..n) (whitespace separated); 0 at the end or on junk. */
int cdvr_io_ascii_number(const uint8_t *text, size_t n, size_t *pos, double *v);

/* Parses exactly count numbers from a whitespace-separated attribute value; 0 otherwise. */
int cdvr_io_parse_doubles(const char *s, double *v, int count);

/* Sets vol's direction from 3 column vectors given in a row-major 3x3 (as the file writes it):
 * each column normalised, its length multiplied into spacing; a singular matrix is
 * CDVR_ERR_FORMAT naming path and what. */
cdvr_status cdvr_io_set_direction(const char *path, const char *what, const double m[9],
                                  cdvr_volume *vol, cdvr_error *err);

#endif
