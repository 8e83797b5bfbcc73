/* cdvr/series.h - a series of volume files read one file at a time (out of core).
 *
 * cdvr_series_open reads the header of every file (not its voxels) and makes the checks
 * cdvr_volume_load_series makes, with the same messages: every file exists and is readable,
 * and has the dims and type of the first and, unless the caller gives a spacing, its spacing;
 * a file may hold several timesteps (a 4D file), and the series is their concatenation. Voxels
 * are read when a timestep is asked for: the series holds the one file it read last, and
 * asking for a timestep of another file reads that file instead, so a series of files of one
 * 3D volume each never holds more than one timestep, whatever its length. A file that changed
 * since it was opened is an error naming it. Calls on one series must come from one thread at
 * a time.
 */
#ifndef CDVR_SERIES_H
#define CDVR_SERIES_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/volume.h"

typedef struct cdvr_series cdvr_series;

typedef struct cdvr_series_info {
    size_t dims[3];
    size_t timesteps;          /* of all files */
    size_t files;
    cdvr_type type;
    double spacing[3], origin[3], direction[9]; /* of the first file */
} cdvr_series_info;

/* Opens count files (raw files need raw; its spacing, when set, overrides every file's),
 * reading their headers; a file whose format lists files (cdvr/format.h, expand) stands for
 * those files. */
cdvr_status cdvr_series_open(const char *const *paths, size_t count, const cdvr_raw_opts *raw,
                             cdvr_series **out, cdvr_error *err);
void cdvr_series_close(cdvr_series *s);
const cdvr_series_info *cdvr_series_get_info(const cdvr_series *s);
/* Path of file i (from 0). */
const char *cdvr_series_path(const cdvr_series *s, size_t i);

/* Voxels of timestep t (from 0) inside the held file, reading that file first when needed;
 * valid until the next call on s. */
cdvr_status cdvr_series_frame(cdvr_series *s, size_t t, const void **voxels, cdvr_error *err);
/* Timesteps [t0, t0 + count) copied into a new volume with the series' geometry. */
cdvr_status cdvr_series_read(cdvr_series *s, size_t t0, size_t count, cdvr_volume **out,
                             cdvr_error *err);
/* Minimum and maximum over the finite values of every timestep (cdvr_volume_range of each
 * file), reading every file once; cached, so only the first call reads. progress, when not
 * NULL, is called after each file with the files done and their total. */
cdvr_status cdvr_series_range(cdvr_series *s, double *lo, double *hi,
                              void (*progress)(void *ud, size_t done, size_t total), void *ud,
                              cdvr_error *err);

/* Quantises count values of `type` at in into out as cdvr_volume_quantize does (same
 * formula, same report counts, which are added to *report when it is not NULL). */
cdvr_status cdvr_quantize_values(const void *in, cdvr_type type, size_t count, double lo,
                                 double hi, uint8_t *out, cdvr_quantize_report *report,
                                 cdvr_error *err);

#endif
