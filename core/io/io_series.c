/* core/io/io_series.c - cdvr_volume_load (dispatch on the file name) and series of files. */
#include "cdvr/volume.h"
#include "volume_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static int has_suffix(const char *path, const char *suffix)
{
    size_t n = strlen(path), k = strlen(suffix);
    return n >= k && strcasecmp(path + n - k, suffix) == 0;
}

typedef enum { FORMAT_UNKNOWN, FORMAT_RAW, FORMAT_NRRD, FORMAT_NIFTI } file_format;

static file_format format_of(const char *path)
{
    static const struct { const char *suffix; file_format format; } suffixes[] = {
        {".nrrd", FORMAT_NRRD}, {".nhdr", FORMAT_NRRD}, {".nii", FORMAT_NIFTI},
        {".nii.gz", FORMAT_NIFTI}, {".hdr", FORMAT_NIFTI}, {".raw", FORMAT_RAW},
        {".bin", FORMAT_RAW},   {".dat", FORMAT_RAW},
    };
    for (size_t i = 0; i < sizeof suffixes / sizeof suffixes[0]; i++)
        if (has_suffix(path, suffixes[i].suffix))
            return suffixes[i].format;
    return FORMAT_UNKNOWN;
}

static void override_spacing(cdvr_volume *vol, const cdvr_raw_opts *raw)
{
    for (int i = 0; raw && i < 3; i++)
        if (raw->spacing[i] > 0)
            vol->spacing[i] = raw->spacing[i];
}

/* raw describes a raw file (dims given), rather than only carrying a spacing override. */
static int describes_raw(const cdvr_raw_opts *raw)
{
    return raw && raw->dims[0] > 0;
}

cdvr_status cdvr_volume_load(const char *path, const cdvr_raw_opts *raw, cdvr_volume **out,
                             cdvr_error *err)
{
    *out = NULL;
    cdvr_status st;
    switch (format_of(path)) {
    case FORMAT_NRRD: st = cdvr_volume_load_nrrd(path, out, err); break;
    case FORMAT_NIFTI: st = cdvr_volume_load_nifti(path, out, err); break;
    case FORMAT_RAW:
        if (!describes_raw(raw))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "%s: a raw file needs its dims and type (and endian, header, timesteps)",
                                  path);
        return cdvr_volume_load_raw(path, raw, out, err);
    default:
        if (describes_raw(raw)) /* any other name with a raw description is read as raw */
            return cdvr_volume_load_raw(path, raw, out, err);
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: unknown file type (.nrrd .nhdr .nii .nii.gz, or raw .raw .bin .dat "
                              "with dims and type)",
                              path);
    }
    if (st == CDVR_OK)
        override_spacing(*out, raw);
    return st;
}

cdvr_status cdvr_volume_probe(const char *path, const cdvr_raw_opts *raw, cdvr_volume *head,
                              cdvr_error *err)
{
    cdvr_status st;
    switch (format_of(path)) {
    case FORMAT_NRRD: st = cdvr_volume_probe_nrrd(path, head, err); break;
    case FORMAT_NIFTI: st = cdvr_volume_probe_nifti(path, head, err); break;
    case FORMAT_RAW:
        if (!describes_raw(raw))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "%s: a raw file needs its dims and type (and endian, header, timesteps)",
                                  path);
        return cdvr_volume_probe_raw(path, raw, head, err);
    default:
        if (describes_raw(raw))
            return cdvr_volume_probe_raw(path, raw, head, err);
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: unknown file type (.nrrd .nhdr .nii .nii.gz, or raw .raw .bin .dat "
                              "with dims and type)",
                              path);
    }
    if (st == CDVR_OK)
        override_spacing(head, raw);
    return st;
}

cdvr_status cdvr_series_same_shape(const cdvr_volume *first, const cdvr_volume *next,
                                   const char *first_path, const char *path, cdvr_error *err)
{
    if (memcmp(first->dims, next->dims, sizeof first->dims) != 0 || first->type != next->type)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: series file is %zux%zux%zu %s, but %s is %zux%zux%zu %s", path,
                              next->dims[0], next->dims[1], next->dims[2], cdvr_type_name(next->type),
                              first_path, first->dims[0], first->dims[1], first->dims[2],
                              cdvr_type_name(first->type));
    return CDVR_OK;
}

/* Files of a series must agree on spacing (relative difference 1e-6) unless the caller
 * overrides it. */
cdvr_status cdvr_series_same_spacing(const cdvr_volume *first, const cdvr_volume *next,
                                     const char *first_path, const char *path, cdvr_error *err)
{
    for (int i = 0; i < 3; i++) {
        double a = first->spacing[i], b = next->spacing[i];
        if (!(fabs(a - b) <= 1e-6 * fmax(fabs(a), fabs(b))))
            return cdvr_error_set(err, CDVR_ERR_FORMAT,
                                  "%s: series file has spacing %g %g %g, but %s has %g %g %g (give spacing= to use one "
                                  "spacing for the whole series)",
                                  path, next->spacing[0], next->spacing[1], next->spacing[2], first_path,
                                  first->spacing[0], first->spacing[1], first->spacing[2]);
    }
    return CDVR_OK;
}

/* Appends the timesteps of `next` to `series` (grows its buffer). */
static cdvr_status append_frames(cdvr_volume *series, const cdvr_volume *next, const char *path,
                                 cdvr_error *err)
{
    size_t timesteps, bytes, old_bytes = series->timesteps * cdvr_volume_frame_bytes(series);
    if (!cdvr_size_add(series->timesteps, next->timesteps, &timesteps) ||
        !cdvr_volume_bytes_for(series->dims, timesteps, series->type, &bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: series size overflows", path);
    void *data = realloc(series->data, bytes);
    if (!data)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot allocate %zu bytes for the series",
                              path, bytes);
    memcpy((unsigned char *)data + old_bytes, next->data, bytes - old_bytes);
    series->data = data;
    series->timesteps = timesteps;
    return CDVR_OK;
}

cdvr_status cdvr_volume_load_series(const char *const *paths, size_t count,
                                    const cdvr_raw_opts *raw, cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    if (count == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series: no files given");
    int spacing_given = raw && raw->spacing[0] > 0 && raw->spacing[1] > 0 && raw->spacing[2] > 0;
    cdvr_volume *series;
    cdvr_status st = cdvr_volume_load(paths[0], raw, &series, err);
    for (size_t i = 1; st == CDVR_OK && i < count; i++) {
        cdvr_volume *next;
        st = cdvr_volume_load(paths[i], raw, &next, err);
        if (st != CDVR_OK)
            break;
        st = cdvr_series_same_shape(series, next, paths[0], paths[i], err);
        if (st == CDVR_OK && !spacing_given)
            st = cdvr_series_same_spacing(series, next, paths[0], paths[i], err);
        if (st == CDVR_OK)
            st = append_frames(series, next, paths[i], err);
        cdvr_volume_free(next);
    }
    if (st != CDVR_OK) {
        cdvr_volume_free(series);
        return st;
    }
    *out = series;
    return CDVR_OK;
}
