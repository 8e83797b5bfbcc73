/* core/io/io_series.c - series of files loaded into memory (cdvr_volume_load_series); the load of
 * one file dispatches through the format registry (core/io/format.c). */
#include "cdvr/volume.h"
#include "volume_io.h"
#include "cdvr/format.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
    series->beyond_f32 += next->beyond_f32;
    return CDVR_OK;
}

static cdvr_status load_files(const char *const *paths, size_t count, const cdvr_raw_opts *raw,
                              cdvr_volume **out, cdvr_error *err);

cdvr_status cdvr_volume_load_series(const char *const *paths, size_t count,
                                    const cdvr_raw_opts *raw, cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    if (count == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series: no files given");
    char **files;
    size_t n;
    cdvr_status st = cdvr_format_expand(paths, count, raw, &files, &n, err);
    if (st == CDVR_OK)
        st = load_files((const char *const *)files, n, raw, out, err);
    cdvr_format_free_paths(files, n);
    return st;
}

/* cdvr_volume_load_series of files that need no expansion. */
static cdvr_status load_files(const char *const *paths, size_t count, const cdvr_raw_opts *raw,
                              cdvr_volume **out, cdvr_error *err)
{
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
