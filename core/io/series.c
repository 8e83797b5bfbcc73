/* core/io/series.c - series of volume files read one file at a time (cdvr/series.h). */
#include "cdvr/series.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cdvr_series {
    char **paths;
    cdvr_raw_opts raw;
    int has_raw;
    cdvr_series_info info;
    cdvr_volume *held;           /* the file read last */
    size_t held_file;
    int range_known;
    double range_lo, range_hi;
};

static void free_paths(char **paths, size_t n)
{
    for (size_t i = 0; paths && i < n; i++)
        free(paths[i]);
    free(paths);
}

void cdvr_series_close(cdvr_series *s)
{
    if (!s)
        return;
    free_paths(s->paths, s->info.files);
    cdvr_volume_free(s->held);
    free(s);
}

/* Reads file i (as the first file did) and checks it against the series. */
static cdvr_status read_file(cdvr_series *s, size_t i, cdvr_error *err)
{
    if (s->held && s->held_file == i)
        return CDVR_OK;
    cdvr_volume_free(s->held);
    s->held = NULL;
    cdvr_volume *v = NULL;
    cdvr_status st = cdvr_volume_load(s->paths[i], s->has_raw ? &s->raw : NULL, &v, err);
    if (st != CDVR_OK)
        return st;
    const cdvr_series_info *in = &s->info;
    if (i > 0 && (memcmp(v->dims, in->dims, sizeof in->dims) != 0 || v->type != in->type ||
                  v->timesteps != in->per_file)) {
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: series file is %zux%zux%zu %s with %zu "
                            "timesteps, but %s is %zux%zux%zu %s with %zu", s->paths[i],
                            v->dims[0], v->dims[1], v->dims[2], cdvr_type_name(v->type),
                            v->timesteps, s->paths[0], in->dims[0], in->dims[1], in->dims[2],
                            cdvr_type_name(in->type), in->per_file);
        cdvr_volume_free(v);
        return st;
    }
    for (int a = 0; s->has_raw && a < 3; a++) /* spacing given for the series wins */
        if (s->raw.spacing[a] > 0)
            v->spacing[a] = s->raw.spacing[a];
    s->held = v;
    s->held_file = i;
    return CDVR_OK;
}

cdvr_status cdvr_series_open(const char *const *paths, size_t count, const cdvr_raw_opts *raw,
                             cdvr_series **out, cdvr_error *err)
{
    *out = NULL;
    if (count == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series: no files given");
    cdvr_series *s = calloc(1, sizeof *s);
    if (!s)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "series: out of memory");
    s->paths = calloc(count, sizeof *s->paths);
    s->info.files = count;
    for (size_t i = 0; s->paths && i < count; i++)
        if (!(s->paths[i] = strdup(paths[i]))) {
            cdvr_series_close(s);
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "series: out of memory");
        }
    if (!s->paths) {
        cdvr_series_close(s);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "series: out of memory");
    }
    if (raw) {
        s->raw = *raw;
        s->has_raw = 1;
    }
    cdvr_status st = read_file(s, 0, err);
    if (st != CDVR_OK) {
        cdvr_series_close(s);
        return st;
    }
    cdvr_series_info *in = &s->info;
    const cdvr_volume *v = s->held;
    memcpy(in->dims, v->dims, sizeof in->dims);
    memcpy(in->spacing, v->spacing, sizeof in->spacing);
    memcpy(in->origin, v->origin, sizeof in->origin);
    memcpy(in->direction, v->direction, sizeof in->direction);
    in->type = v->type;
    in->per_file = v->timesteps;
    if (!cdvr_size_mul(count, in->per_file, &in->timesteps)) {
        cdvr_series_close(s);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "series: %zu files of %zu timesteps overflow",
                              count, v->timesteps);
    }
    *out = s;
    return CDVR_OK;
}

const cdvr_series_info *cdvr_series_get_info(const cdvr_series *s)
{
    return &s->info;
}

const char *cdvr_series_path(const cdvr_series *s, size_t i)
{
    return i < s->info.files ? s->paths[i] : NULL;
}

cdvr_status cdvr_series_frame(cdvr_series *s, size_t t, const void **voxels, cdvr_error *err)
{
    *voxels = NULL;
    if (t >= s->info.timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series %s: timestep %zu out of range 1..%zu",
                              s->paths[0], t + 1, s->info.timesteps);
    cdvr_status st = read_file(s, t / s->info.per_file, err);
    if (st == CDVR_OK)
        *voxels = cdvr_volume_frame(s->held, t % s->info.per_file);
    return st;
}

cdvr_status cdvr_series_read(cdvr_series *s, size_t t0, size_t count, cdvr_volume **out,
                             cdvr_error *err)
{
    *out = NULL;
    const cdvr_series_info *in = &s->info;
    if (count == 0 || t0 >= in->timesteps || count > in->timesteps - t0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series %s: timesteps %zu..%zu out of range "
                              "1..%zu", s->paths[0], t0 + 1, t0 + count, in->timesteps);
    cdvr_volume *v = NULL;
    cdvr_status st = cdvr_volume_create(in->dims, count, in->type, &v, err);
    size_t bytes = st == CDVR_OK ? cdvr_volume_frame_bytes(v) : 0;
    for (size_t k = 0; st == CDVR_OK && k < count; k++) {
        const void *src;
        st = cdvr_series_frame(s, t0 + k, &src, err);
        if (st == CDVR_OK)
            memcpy(cdvr_volume_frame(v, k), src, bytes);
    }
    if (st != CDVR_OK) {
        cdvr_volume_free(v);
        return st;
    }
    memcpy(v->spacing, in->spacing, sizeof v->spacing);
    memcpy(v->origin, in->origin, sizeof v->origin);
    memcpy(v->direction, in->direction, sizeof v->direction);
    *out = v;
    return CDVR_OK;
}

cdvr_status cdvr_series_range(cdvr_series *s, double *lo, double *hi,
                              void (*progress)(void *ud, size_t done, size_t total), void *ud,
                              cdvr_error *err)
{
    if (!s->range_known) {
        /* the held file first: a series of one file is never read twice */
        size_t n = s->info.files, first = s->held ? s->held_file : 0;
        double mn = INFINITY, mx = -INFINITY;
        for (size_t k = 0; k < n; k++) {
            size_t i = (first + k) % n;
            cdvr_status st = read_file(s, i, err);
            if (st != CDVR_OK)
                return st;
            double flo, fhi;
            cdvr_volume_range(s->held, &flo, &fhi);
            int any = !(flo == 0 && fhi == 0) || s->held->type != CDVR_TYPE_F32;
            if (!any) { /* (0, 0) is also "no finite value": look once more */
                double probe_lo = INFINITY;
                const float *f = s->held->data;
                size_t count = cdvr_volume_voxels(s->held) * s->held->timesteps;
                for (size_t j = 0; j < count && probe_lo > 0; j++)
                    if (isfinite(f[j]))
                        probe_lo = 0;
                any = probe_lo == 0;
            }
            if (any) {
                mn = flo < mn ? flo : mn;
                mx = fhi > mx ? fhi : mx;
            }
            if (progress)
                progress(ud, k + 1, n);
        }
        s->range_lo = isfinite(mn) ? mn : 0;
        s->range_hi = isfinite(mx) ? mx : 0;
        s->range_known = 1;
    }
    *lo = s->range_lo;
    *hi = s->range_hi;
    return CDVR_OK;
}
