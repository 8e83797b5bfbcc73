/* core/io/series_view.c - series file names from a pattern, views of a series as u8 codes, and
 * the frame source of an out-of-core encode (cdvr/series.h). What cdvr.load_series, v:quantize
 * and cdvr.encode of a lazy series do, reachable from C. */
#include "cdvr/format.h"
#include "cdvr/series.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- pattern -------------------------------------------------------------------------------- */

/* The one conversion: text[conv_start, conv_end). */
typedef struct series_pattern {
    const char *text;
    size_t conv_start, conv_end;
    int zero_pad, width;
} series_pattern;

static cdvr_status parse_pattern(const char *text, series_pattern *p, cdvr_error *err)
{
    int found = 0;
    memset(p, 0, sizeof *p);
    p->text = text;
    for (size_t i = 0; text[i]; i++) {
        if (text[i] != '%')
            continue;
        if (text[i + 1] == '%') {
            i++;
            continue;
        }
        size_t j = i + 1;
        p->zero_pad = text[j] == '0';
        j += (size_t)p->zero_pad;
        p->width = 0;
        while (text[j] >= '0' && text[j] <= '9' && p->width < 100)
            p->width = p->width * 10 + (text[j++] - '0');
        if (found || text[j] == '\0' || !strchr("diu", text[j]) || p->width >= 100)
            return cdvr_error_set(err, CDVR_ERR_ARG, "series pattern '%s': exactly one integer "
                                  "conversion (%%d, %%03d, ...) expected", text);
        found = 1;
        p->conv_start = i;
        p->conv_end = j + 1;
        i = j;
    }
    if (!found)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series pattern '%s': no integer conversion "
                              "(%%d, %%03d, ...)", text);
    return CDVR_OK;
}

/* Copies n bytes of s to out with "%%" as "%"; returns the bytes written. */
static size_t copy_literal(char *out, const char *s, size_t n)
{
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        out[k++] = s[i];
        if (s[i] == '%' && i + 1 < n && s[i + 1] == '%')
            i++;
    }
    return k;
}

/* The name for number v (malloc'd), or NULL when out of memory. */
static char *series_name(const series_pattern *p, long long v)
{
    char number[128];
    snprintf(number, sizeof number, p->zero_pad ? "%0*lld" : "%*lld", p->width, v);
    size_t len = strlen(p->text) + strlen(number) + 1;
    char *out = malloc(len);
    if (!out)
        return NULL;
    size_t k = copy_literal(out, p->text, p->conv_start);
    memcpy(out + k, number, strlen(number));
    k += strlen(number);
    k += copy_literal(out + k, p->text + p->conv_end, strlen(p->text + p->conv_end));
    out[k] = '\0';
    return out;
}

cdvr_status cdvr_series_pattern(const char *pattern, long long first, size_t count, char ***out,
                                size_t *n, cdvr_error *err)
{
    *out = NULL;
    *n = 0;
    series_pattern p;
    cdvr_status st = parse_pattern(pattern, &p, err);
    if (st != CDVR_OK)
        return st;
    if (count > 1000000)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series '%s': count must be 1..1000000 (got "
                              "%zu)", pattern, count);
    size_t cap = count ? count : 16, used = 0;
    char **names = malloc(cap * sizeof *names);
    for (size_t i = 0; st == CDVR_OK && names && (count == 0 || i < count); i++) {
        char *name = series_name(&p, first + (long long)i);
        if (!name) {
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "series '%s': out of memory", pattern);
            break;
        }
        if (count == 0 && access(name, F_OK) != 0) {
            if (i == 0)
                st = cdvr_error_set(err, CDVR_ERR_IO, "%s: no such file (series pattern %s, "
                                    "first=%lld)", name, pattern, first);
            free(name);
            break;
        }
        if (used == cap) {
            char **grown = cap < 1000000 ? realloc(names, 2 * cap * sizeof *names) : NULL;
            if (!grown) {
                free(name);
                st = cdvr_error_set(err, CDVR_ERR_NOMEM, "series '%s': out of memory or more "
                                    "than 1000000 files", pattern);
                break;
            }
            names = grown;
            cap *= 2;
        }
        names[used++] = name;
    }
    if (!names)
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "series '%s': out of memory", pattern);
    if (st != CDVR_OK) {
        cdvr_format_free_paths(names, used);
        return st;
    }
    *out = names;
    *n = used;
    return CDVR_OK;
}

/* ---- views ---------------------------------------------------------------------------------- */

cdvr_status cdvr_series_view_window(const cdvr_series_view *v, double w[2],
                                    cdvr_series_progress_fn progress, void *ud, cdvr_error *err)
{
    if (v->quantized) {
        w[0] = v->lo;
        w[1] = v->hi;
        return CDVR_OK;
    }
    const cdvr_series_info *in = cdvr_series_get_info(v->series);
    if (in->type == CDVR_TYPE_U8) { /* the codes' saved window, else [0, 255] */
        w[0] = in->window[0];
        w[1] = in->window[1];
        return CDVR_OK;
    }
    return cdvr_series_range(v->series, &w[0], &w[1], progress, ud, err);
}

cdvr_status cdvr_series_view_read(const cdvr_series_view *v, size_t t0, size_t count,
                                  cdvr_volume **out, cdvr_series_progress_fn progress, void *ud,
                                  cdvr_error *err)
{
    *out = NULL;
    double w[2];
    cdvr_volume *raw = NULL;
    cdvr_status st = cdvr_series_view_window(v, w, progress, ud, err);
    if (st == CDVR_OK)
        st = cdvr_series_read(v->series, t0, count, &raw, err);
    if (st == CDVR_OK && v->quantized) {
        st = cdvr_volume_quantize(raw, v->lo, v->hi, out, NULL, err);
        cdvr_volume_free(raw);
    } else if (st == CDVR_OK) {
        *out = raw;
    }
    if (*out) {
        (*out)->window[0] = w[0];
        (*out)->window[1] = w[1];
    }
    return st;
}

cdvr_status cdvr_series_view_scan(const cdvr_series_view *v, cdvr_quantize_report *report,
                                  double *lo, double *hi, cdvr_error *err)
{
    const cdvr_series_info *in = cdvr_series_get_info(v->series);
    if (!v->quantized)
        return cdvr_error_set(err, CDVR_ERR_ARG, "series %s: scan of a view that is not "
                              "quantized", cdvr_series_path(v->series, 0));
    size_t n = in->dims[0] * in->dims[1] * in->dims[2];
    uint8_t *codes = malloc(n), mn = 255, mx = 0;
    if (!codes)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "series %s: no memory for a frame",
                              cdvr_series_path(v->series, 0));
    cdvr_status st = CDVR_OK;
    for (size_t t = 0; st == CDVR_OK && t < in->timesteps; t++) {
        const void *voxels;
        st = cdvr_series_frame(v->series, t, &voxels, err);
        if (st == CDVR_OK)
            st = cdvr_quantize_values(voxels, in->type, n, v->lo, v->hi, codes, report, err);
        for (size_t i = 0; st == CDVR_OK && (lo || hi) && i < n; i++) {
            mn = codes[i] < mn ? codes[i] : mn;
            mx = codes[i] > mx ? codes[i] : mx;
        }
    }
    free(codes);
    if (st == CDVR_OK && lo)
        *lo = mn;
    if (st == CDVR_OK && hi)
        *hi = mx;
    return st;
}

/* ---- encode source -------------------------------------------------------------------------- */

/* Frame t of the source: the series' voxels of t as u8 (copied, or quantised). */
static cdvr_status source_frame(void *ud, size_t t, uint8_t *out, cdvr_error *err)
{
    const cdvr_series_source *s = ud;
    const cdvr_series_info *in = cdvr_series_get_info(s->series);
    const void *voxels;
    cdvr_status st = cdvr_series_frame(s->series, t, &voxels, err);
    size_t n = in->dims[0] * in->dims[1] * in->dims[2];
    if (st != CDVR_OK)
        return st;
    if (!s->quantize) {
        memcpy(out, voxels, n);
        return CDVR_OK;
    }
    return cdvr_quantize_values(voxels, in->type, n, s->lo, s->hi, out, NULL, err);
}

cdvr_status cdvr_series_encode_source(const cdvr_series_view *v, cdvr_series_source *state,
                                      cdvr_encode_source *src, cdvr_encode_opts *opts,
                                      cdvr_series_progress_fn progress, void *ud,
                                      cdvr_error *err)
{
    double w[2];
    cdvr_status st = cdvr_series_view_window(v, w, progress, ud, err);
    if (st != CDVR_OK)
        return st;
    const cdvr_series_info *in = cdvr_series_get_info(v->series);
    state->series = v->series;
    state->quantize = v->quantized || in->type != CDVR_TYPE_U8;
    state->lo = w[0];
    state->hi = w[1];
    opts->qlo = w[0];
    opts->qhi = w[1];
    opts->source_type = in->type;
    memset(src, 0, sizeof *src);
    memcpy(src->dims, in->dims, sizeof src->dims);
    memcpy(src->spacing, in->spacing, sizeof src->spacing);
    memcpy(src->origin, in->origin, sizeof src->origin);
    cdvr_volume geometry; /* for the all-zeros-is-identity rule of cdvr_volume_direction */
    memcpy(geometry.direction, in->direction, sizeof geometry.direction);
    cdvr_volume_direction(&geometry, src->direction);
    src->timesteps = in->timesteps;
    src->frame = source_frame;
    src->frame_ud = state;
    return CDVR_OK;
}
