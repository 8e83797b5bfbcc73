/* core/io/series.c - series of volume files read one file at a time (cdvr/series.h). */
#include "cdvr/series.h"
#include "volume_io.h"
#include "cdvr/format.h"
#include "cdvr/pvd.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cdvr_series {
    char **paths;
    size_t *first_t;             /* per file: its first timestep in the series; [files] = total */
    cdvr_raw_opts raw;
    int has_raw;
    cdvr_series_info info;
    cdvr_volume first;           /* header of the first file (no voxels) */
    cdvr_volume *held;           /* the file read last */
    size_t held_file;
    int range_known;
    double range_lo, range_hi;
    double *times;               /* per timestep, or NULL (cdvr_series_times) */
    unsigned char *counted;      /* per file: its beyond_f32 is in info.beyond_f32 */
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
    free(s->first_t);
    free(s->counted);
    free(s->times);
    cdvr_volume_free(s->held);
    free(s);
}

/* Whether a file read now still looks as its header did at open. */
static cdvr_status check_unchanged(const cdvr_series *s, size_t i, const cdvr_volume *v,
                                   cdvr_error *err)
{
    size_t want = s->first_t[i + 1] - s->first_t[i];
    if (memcmp(v->dims, s->first.dims, sizeof v->dims) != 0 || v->type != s->first.type ||
        v->timesteps != want)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: series file is now %zux%zux%zu %s with "
                              "%zu timesteps; it was %zux%zux%zu %s with %zu when the series was "
                              "opened", s->paths[i], v->dims[0], v->dims[1], v->dims[2],
                              cdvr_type_name(v->type), v->timesteps, s->first.dims[0],
                              s->first.dims[1], s->first.dims[2], cdvr_type_name(s->first.type),
                              want);
    return CDVR_OK;
}

/* Reads file i, unless it is the one held. */
static cdvr_status read_file(cdvr_series *s, size_t i, cdvr_error *err)
{
    if (s->held && s->held_file == i)
        return CDVR_OK;
    cdvr_volume_free(s->held);
    s->held = NULL;
    cdvr_volume *v = NULL;
    cdvr_status st = cdvr_volume_load(s->paths[i], s->has_raw ? &s->raw : NULL, &v, err);
    if (st == CDVR_OK)
        st = check_unchanged(s, i, v, err);
    if (st != CDVR_OK) {
        cdvr_volume_free(v);
        return st;
    }
    if (!s->counted[i]) {
        s->info.beyond_f32 += v->beyond_f32;
        s->counted[i] = 1;
    }
    s->held = v;
    s->held_file = i;
    return CDVR_OK;
}

/* Probes every file's header: the same checks as cdvr_volume_load_series, nothing read. */
static cdvr_status probe_all(cdvr_series *s, const char *const *paths, size_t count,
                             cdvr_error *err)
{
    const cdvr_raw_opts *raw = s->has_raw ? &s->raw : NULL;
    int spacing_given = raw && raw->spacing[0] > 0 && raw->spacing[1] > 0 && raw->spacing[2] > 0;
    size_t total = 0;
    for (size_t i = 0; i < count; i++) {
        cdvr_volume head;
        cdvr_volume_header_preset(&head);
        cdvr_status st = cdvr_volume_probe(paths[i], raw, &head, err);
        if (st == CDVR_OK && i > 0)
            st = cdvr_series_same_shape(&s->first, &head, paths[0], paths[i], err);
        if (st == CDVR_OK && i > 0 && !spacing_given)
            st = cdvr_series_same_spacing(&s->first, &head, paths[0], paths[i], err);
        if (st == CDVR_OK && !cdvr_size_add(total, head.timesteps, &total))
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: series size overflows", paths[i]);
        if (st != CDVR_OK)
            return st;
        if (i == 0)
            s->first = head;
        s->first_t[i + 1] = total;
    }
    return CDVR_OK;
}

static cdvr_status open_files(const char *const *paths, size_t count, const cdvr_raw_opts *raw,
                              cdvr_series **out, cdvr_error *err);

/* The time values of files (one timestep each) when every path is a ParaView collection
 * (cdvr/pvd.h) and they give one value per file; else NULL. */
static double *series_times(const char *const *paths, size_t count, const cdvr_raw_opts *raw,
                            size_t files)
{
    const cdvr_format *pvd = cdvr_format_find("pvd");
    double *t = pvd ? malloc(files * sizeof *t) : NULL;
    size_t k = 0;
    for (size_t i = 0; t && i < count; i++) {
        const cdvr_format *f = NULL;
        cdvr_pvd_entry *e = NULL;
        size_t n = 0;
        cdvr_error ignored;
        if (cdvr_format_for(paths[i], raw, &f, &ignored) != CDVR_OK || f != pvd ||
            cdvr_pvd_read(paths[i], raw, &e, &n, &ignored) != CDVR_OK || n > files - k) {
            cdvr_pvd_free(e, n);
            free(t);
            return NULL;
        }
        for (size_t j = 0; j < n; j++)
            t[k++] = e[j].time;
        cdvr_pvd_free(e, n);
    }
    if (t && k != files) {
        free(t);
        return NULL;
    }
    return t;
}

const double *cdvr_series_times(const cdvr_series *s)
{
    return s->times;
}

cdvr_status cdvr_series_open(const char *const *paths, size_t count, const cdvr_raw_opts *raw,
                             cdvr_series **out, cdvr_error *err)
{
    *out = NULL;
    if (count == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series: no files given");
    char **files;
    size_t n;
    cdvr_status st = cdvr_format_expand(paths, count, raw, &files, &n, err);
    if (st == CDVR_OK)
        st = open_files((const char *const *)files, n, raw, out, err);
    cdvr_format_free_paths(files, n);
    if (st == CDVR_OK && (*out)->info.timesteps == n)
        (*out)->times = series_times(paths, count, raw, n);
    return st;
}

/* cdvr_series_open of files that need no expansion. */
static cdvr_status open_files(const char *const *paths, size_t count, const cdvr_raw_opts *raw,
                              cdvr_series **out, cdvr_error *err)
{
    cdvr_series *s = calloc(1, sizeof *s);
    if (!s)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "series: out of memory");
    s->paths = calloc(count, sizeof *s->paths);
    s->first_t = calloc(count + 1, sizeof *s->first_t);
    s->counted = calloc(count, 1);
    s->info.files = count;
    int ok = s->paths && s->first_t && s->counted;
    for (size_t i = 0; ok && i < count; i++)
        ok = (s->paths[i] = strdup(paths[i])) != NULL;
    if (!ok) {
        cdvr_series_close(s);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "series: out of memory");
    }
    if (raw) {
        s->raw = *raw;
        s->has_raw = 1;
    }
    cdvr_status st = probe_all(s, paths, count, err);
    if (st != CDVR_OK) {
        cdvr_series_close(s);
        return st;
    }
    cdvr_series_info *in = &s->info;
    memcpy(in->dims, s->first.dims, sizeof in->dims);
    memcpy(in->spacing, s->first.spacing, sizeof in->spacing);
    memcpy(in->origin, s->first.origin, sizeof in->origin);
    memcpy(in->direction, s->first.direction, sizeof in->direction);
    in->type = s->first.type;
    memcpy(in->source_type, s->first.source_type, sizeof in->source_type);
    memcpy(in->space, s->first.space, sizeof in->space);
    in->space[sizeof in->space - 1] = 0;
    int u8_saved = in->type == CDVR_TYPE_U8 && s->first.window[0] < s->first.window[1];
    in->window[0] = u8_saved ? s->first.window[0] : in->type == CDVR_TYPE_U8 ? 0 : NAN;
    in->window[1] = u8_saved ? s->first.window[1] : in->type == CDVR_TYPE_U8 ? 255 : NAN;
    in->timesteps = s->first_t[count];
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

/* File holding timestep t: the last i with first_t[i] <= t. */
static size_t file_of(const cdvr_series *s, size_t t)
{
    size_t lo = 0, hi = s->info.files;
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (s->first_t[mid] <= t)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

cdvr_status cdvr_series_frame(cdvr_series *s, size_t t, const void **voxels, cdvr_error *err)
{
    *voxels = NULL;
    if (t >= s->info.timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series %s: timestep %zu out of range 1..%zu",
                              s->paths[0], t + 1, s->info.timesteps);
    size_t i = file_of(s, t);
    cdvr_status st = read_file(s, i, err);
    if (st == CDVR_OK)
        *voxels = cdvr_volume_frame(s->held, t - s->first_t[i]);
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
    memcpy(v->source_type, in->source_type, sizeof v->source_type);
    *out = v;
    return CDVR_OK;
}

/* Whether a f32 volume holds any finite value (cdvr_volume_range gives 0, 0 for none). */
static int any_finite(const cdvr_volume *v)
{
    if (v->type != CDVR_TYPE_F32)
        return 1;
    const float *f = v->data;
    size_t count = cdvr_volume_voxels(v) * v->timesteps;
    for (size_t j = 0; j < count; j++)
        if (isfinite(f[j]))
            return 1;
    return 0;
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
            cdvr_status st = read_file(s, (first + k) % n, err);
            if (st != CDVR_OK)
                return st;
            double flo, fhi;
            cdvr_volume_range(s->held, &flo, &fhi);
            if ((flo != 0 || fhi != 0) || any_finite(s->held)) {
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
