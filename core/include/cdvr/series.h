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
#include "cdvr/store.h" /* cdvr_encode_source, cdvr_encode_opts */
#include "cdvr/volume.h"

typedef struct cdvr_series cdvr_series;

typedef struct cdvr_series_info {
    size_t dims[3];
    size_t timesteps;          /* of all files */
    size_t files;
    cdvr_type type;
    double spacing[3], origin[3], direction[9]; /* of the first file */
    char source_type[16];      /* the first file's element type (cdvr_volume.source_type) */
    /* Appended. The value window of a u8 series: the first file's saved window (NRRD old
     * min/max, ...: what cdvr.load and the eager cdvr_volume_load_series give), [0, 255] when
     * it saves none; NaN NaN for other types (their window is their range, cdvr_series_range). */
    double window[2];
    char space[8];             /* the first file's world ("RAS", "LPS", ...; cdvr_volume.space) */
    /* Values loaded as +-Inf (f32_overflow="inf", cdvr_volume.beyond_f32), summed over the
     * files read so far: a file counts once, when it is first read. */
    uint64_t beyond_f32;
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


/* Progress of a pass over the files: done of total files. */
typedef void (*cdvr_series_progress_fn)(void *ud, size_t done, size_t total);

/* ---- file names from a pattern -------------------------------------------------------------
 * A pattern is a printf-like name with exactly one integer conversion: %d, %i or %u with an
 * optional 0 flag and a width below 100 ("vf_t%03d.nrrd"); "%%" is a literal percent. */

/* The names for the numbers first .. first + count - 1; with count 0, the names from first on
 * while those files exist (at least the first must: CDVR_ERR_IO "NAME: no such file (series
 * pattern P, first=N)"). *out is a malloc'd array of *n malloc'd strings
 * (cdvr_format_free_paths). A bad pattern or a count above 1000000 is CDVR_ERR_ARG naming the
 * pattern. */
cdvr_status cdvr_series_pattern(const char *pattern, long long first, size_t count, char ***out,
                                size_t *n, cdvr_error *err);

/* ---- file names from a directory, a glob pattern or a single name ---------------------------
 * Natural order: runs of digits compare by their value, the rest byte by byte ("t2" before
 * "t10", "slice9" before "slice10"); names equal that way ("t02", "t2") by strcmp. */
int cdvr_series_natural_cmp(const char *a, const char *b);

/* 1 when s holds a printf integer conversion (%d, %03d, ...: the pattern rule above). */
int cdvr_series_is_pattern(const char *s);

/* The paths matching a glob(3) pattern (*, ?, [...]; a leading wildcard matches no hidden
 * name), in natural order. None matching: CDVR_ERR_IO "P: no file matches the pattern". Matches
 * may be directories (a series of TIFF stacks, one directory per timestep). */
cdvr_status cdvr_series_glob(const char *pattern, char ***out, size_t *n, cdvr_error *err);

/* The timesteps of a directory, in natural order, hidden names (".x") skipped: its files whose
 * suffix is that of one known format (cdvr_format_by_suffix: "t1.nrrd", "t2.nrrd", ...), or its
 * subdirectories that one format reads (cdvr/format.h rule 0: TIFF stacks, one per timestep).
 * Files of no known suffix and subdirectories no format reads are passed over. Refused,
 * CDVR_ERR_FORMAT, saying what the directory holds: one holding several formats ("holds 3 nrrd
 * files, 2 vti files: give a glob pattern of one suffix"), or none (empty, or only other
 * files). */
cdvr_status cdvr_series_dir(const char *dir, char ***out, size_t *n, cdvr_error *err);

/* The files of a series given as one string: an existing directory (cdvr_series_dir), an
 * existing file (itself: a 4D file, a .pvd collection), a printf pattern (cdvr_series_pattern
 * with first and count), else a glob pattern when it holds *, ? or [ (cdvr_series_glob), else
 * the name itself (its load reports it missing). *out as for cdvr_series_pattern. */
cdvr_status cdvr_series_names(const char *where, long long first, size_t count, char ***out,
                              size_t *n, cdvr_error *err);

/* cdvr_series_open and cdvr_volume_load_series of the files cdvr_series_names(where, 0, 0)
 * gives: cdvr_series_open_path("run/t_*.vti", NULL, &s, &err), a directory, a .pvd file. */
cdvr_status cdvr_series_open_path(const char *where, const cdvr_raw_opts *raw,
                                  cdvr_series **out, cdvr_error *err);
cdvr_status cdvr_volume_load_series_path(const char *where, const cdvr_raw_opts *raw,
                                         cdvr_volume **out, cdvr_error *err);

/* Time values of the series (a ParaView collection's timestep= of each DataSet, cdvr/pvd.h):
 * info->timesteps values, or NULL when the files give none (files that are
 * not all from .pvd collections, or a file of several timesteps). Valid while s is open. */
const double *cdvr_series_times(const cdvr_series *s);

/* ---- a series as u8 codes, and as the source of an out-of-core encode ----------------------
 * A view is a series seen either as its values or, quantized, as the u8 codes of its values
 * over [lo, hi] (the formula of cdvr_volume_quantize). What cdvr.load_series and v:quantize of
 * it give in Lua; a C caller encodes a series out of core with
 *     cdvr_series_view v = {series, 0, 0, 0};
 *     cdvr_series_source state;
 *     cdvr_encode_source src;
 *     cdvr_series_encode_source(&v, &state, &src, &opts, NULL, NULL, &err);
 *     cdvr_store_encode_source(&src, &opts, "out.cdv", &err);
 * which holds only the files of the timesteps in flight and writes the store that
 * cdvr_store_encode of the series loaded into memory and quantised over the same window
 * writes, byte for byte. */
typedef struct cdvr_series_view {
    cdvr_series *series;
    int quantized;               /* 1: u8 codes over [lo, hi] */
    double lo, hi;
} cdvr_series_view;

/* The view's value window (cdvr/volume.h): [lo, hi] when quantized, [0, 255] for a u8 series,
 * else the range of every timestep (cdvr_series_range: the first call reads every file). */
cdvr_status cdvr_series_view_window(const cdvr_series_view *v, double w[2],
                                    cdvr_series_progress_fn progress, void *ud, cdvr_error *err);
/* Timesteps [t0, t0 + count) as a new volume in memory (u8 codes when quantized), with the
 * series' geometry and the view's window. */
cdvr_status cdvr_series_view_read(const cdvr_series_view *v, size_t t0, size_t count,
                                  cdvr_volume **out, cdvr_series_progress_fn progress, void *ud,
                                  cdvr_error *err);

/* One pass over the timesteps of a quantized view (CDVR_ERR_ARG for one that is not): adds the
 * counts of cdvr_volume_quantize to *report and gives the range of the codes in *lo, *hi (each
 * may be NULL). */
cdvr_status cdvr_series_view_scan(const cdvr_series_view *v, cdvr_quantize_report *report,
                                  double *lo, double *hi, cdvr_error *err);

/* What the frames of an encode source read (the caller keeps it while the encode runs). */
typedef struct cdvr_series_source {
    cdvr_series *series;
    int quantize;                /* 0: the u8 voxels as they are */
    double lo, hi;               /* window of the codes */
} cdvr_series_source;

/* Fills src for cdvr_store_encode_source: the series' dims, timesteps and geometry (of its
 * first file), frames read one at a time through state: a u8 series that is not quantized as
 * it is, every other one quantised over the view's window (cdvr_series_view_window, which may
 * read every file once). Sets opts->qlo, qhi (that window) and source_type (the series' type);
 * leaves the rest of opts alone. */
cdvr_status cdvr_series_encode_source(const cdvr_series_view *v, cdvr_series_source *state,
                                      cdvr_encode_source *src, cdvr_encode_opts *opts,
                                      cdvr_series_progress_fn progress, void *ud,
                                      cdvr_error *err);

/* Quantises count values of `type` at in into out as cdvr_volume_quantize does (same
 * formula, same report counts, which are added to *report when it is not NULL). */
cdvr_status cdvr_quantize_values(const void *in, cdvr_type type, size_t count, double lo,
                                 double hi, uint8_t *out, cdvr_quantize_report *report,
                                 cdvr_error *err);

#endif
