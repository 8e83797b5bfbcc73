/* core/io/volume_io.h - helpers shared by the volume loaders (io_raw.c, io_nrrd.c, io_nifti.c,
 * io_series.c). Internal to libcdvr; not a public header. */
#ifndef CDVR_VOLUME_IO_H
#define CDVR_VOLUME_IO_H

#include <float.h>
#include <math.h>

#include "cdvr/volume.h"

/* Byte count of dims[0]*dims[1]*dims[2]*timesteps voxels of `type`; 0 on overflow. */
int cdvr_volume_bytes_for(const size_t dims[3], size_t timesteps, cdvr_type type, size_t *bytes);

/* A header before a probe: everything 0 but spacing 1 and direction identity. */
void cdvr_volume_header_preset(cdvr_volume *head);

/* CDVR_ERR_FORMAT when `bytes` of voxels (what the header of `file` claims for `what`, e.g.
 * "format 'tiff'" or "HDF5: dataset '/d'") exceed cdvr_load_max_bytes(opts), checked before
 * anything is allocated or read; the message names file, what, both sizes and the option. */
cdvr_status cdvr_load_check_claim(const char *file, const char *what, size_t bytes,
                                  const cdvr_raw_opts *opts, cdvr_error *err);

/* Reverses the byte order of `count` elements of `elem_size` bytes (2 or 4) in place. */
void cdvr_swap_bytes(void *data, size_t count, size_t elem_size);

/* 1 when the host stores multi-byte numbers little endian. */
int cdvr_host_is_little_endian(void);

/* v as f32: values beyond float's range become +-Inf, NaN stays NaN, the rest round to
 * nearest. Loaders do not call it alone: cdvr_f32_guard_put below refuses such values unless
 * the load options accept +-Inf. */
float cdvr_double_to_f32(double v);

/* The one rule for values beyond f32 (cdvr_raw_opts.f32_overflow_inf): a loader that converts
 * a file's values to f32 passes each through cdvr_f32_guard_put (which counts the finite ones
 * beyond FLT_MAX and gives cdvr_double_to_f32 of it) and ends with cdvr_f32_guard_finish. */
typedef struct cdvr_f32_guard {
    int accept_inf;    /* opts->f32_overflow_inf */
    uint64_t beyond;   /* finite values beyond f32 seen */
    uint64_t first_at; /* element index (from 0, over all timesteps) of the first one */
    double first;      /* its value */
} cdvr_f32_guard;
void cdvr_f32_guard_init(cdvr_f32_guard *g, const cdvr_raw_opts *opts);
static inline float cdvr_f32_guard_put(cdvr_f32_guard *g, double v, uint64_t at)
{
    if (fabs(v) > FLT_MAX && isfinite(v) && g->beyond++ == 0) {
        g->first_at = at;
        g->first = v;
    }
    return cdvr_double_to_f32(v);
}
/* After the last value: when values went beyond f32 and the options did not accept them,
 * CDVR_ERR_FORMAT: "FILE: WHAT value V (SOURCE_TYPE, voxel (x,y,z) of timestep t) is beyond the
 * range of f32, ... (N such values); load with f32_overflow = \"inf\" ..." (what e.g. "NRRD",
 * source_type the file's element type name); else sets vol->beyond_f32 to the count. */
cdvr_status cdvr_f32_guard_finish(const cdvr_f32_guard *g, const char *file, const char *what,
                                  const char *source_type, cdvr_volume *vol, cdvr_error *err);

/* The value window of a u8 volume kept in a file (NRRD "old min"/"old max", cdvr's keys in
 * MetaImage, VTI and NIfTI; cdvr/write.h): sets vol->window to [lo, hi] when vol is u8 and lo <
 * hi are finite; otherwise leaves it. */
void cdvr_u8_window_set(cdvr_volume *vol, double lo, double hi);
/* 1 and w = the window when vol is u8 with a window other than [0, 255] (codes that stand for
 * other values: worth saving); else 0. */
int cdvr_u8_window_get(const cdvr_volume *vol, double w[2]);

/* Converts `count` values from a source array (read through `read`) to f32 in dst. */
typedef double (*cdvr_value_reader)(const void *src, size_t i);
void cdvr_convert_to_f32(float *dst, const void *src, size_t count, cdvr_value_reader read);

/* CDVR_OK when path names a readable regular file (checked without blocking on a FIFO, see
 * cdvr/regular_file.h), else CDVR_ERR_IO naming path and reason. */
cdvr_status cdvr_check_readable(const char *path, cdvr_error *err);

/* Cuts teem's biff message (several "[nrrd] function: text" lines, innermost last) in place to
 * its innermost non-empty reason. */
void cdvr_teem_reason(char *msg);

/* Header probes: what cdvr_volume_load of the same file gives (dims, timesteps, type after
 * the loaders' conversions, spacing, origin, direction) without reading the voxels. head must
 * be preset (spacing 1, origin 0, direction identity); head->data is left alone. */
cdvr_status cdvr_volume_probe_nrrd(const char *path, cdvr_volume *head, cdvr_error *err);
cdvr_status cdvr_volume_probe_nifti(const char *path, cdvr_volume *head, cdvr_error *err);
cdvr_status cdvr_volume_probe_raw(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                                  cdvr_error *err);

/* The checks cdvr_volume_load_series makes of each file against the first: the same dims and
 * type; the same spacing (relative 1e-6) unless the caller gives one. Errors name both files. */
cdvr_status cdvr_series_same_shape(const cdvr_volume *first, const cdvr_volume *next,
                                   const char *first_path, const char *path, cdvr_error *err);
cdvr_status cdvr_series_same_spacing(const cdvr_volume *first, const cdvr_volume *next,
                                     const char *first_path, const char *path, cdvr_error *err);

#endif
