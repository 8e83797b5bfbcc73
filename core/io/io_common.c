/* core/io/io_common.c - helpers of the VTK, MetaImage and TIFF loaders (io_common.h). */
#include "io_common.h"
#include "volume_io.h"
#include "cdvr/regular_file.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>
#include <zlib.h>

/* ---- file mapping ------------------------------------------------------------------------ */

cdvr_status cdvr_io_map_open(const char *path, cdvr_io_map *map, cdvr_error *err)
{
    map->p = NULL;
    map->n = 0;
    int fd;
    struct stat sb;
    cdvr_status st = cdvr_open_regular_file(path, &fd, &sb, err);
    if (st != CDVR_OK)
        return st;
    if ((unsigned long long)sb.st_size > (unsigned long long)SIZE_MAX) {
        close(fd);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: file too large for the address space", path);
    }
    map->n = (size_t)sb.st_size;
    if (map->n) {
        void *p = mmap(NULL, map->n, PROT_READ, MAP_PRIVATE, fd, 0);
        if (p == MAP_FAILED) {
            int e = errno;
            close(fd);
            map->n = 0;
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot map: %s", path, strerror(e));
        }
        map->p = p;
    }
    close(fd);
    return CDVR_OK;
}

void cdvr_io_map_close(cdvr_io_map *map)
{
    if (map->p)
        munmap((void *)map->p, map->n);
    map->p = NULL;
    map->n = 0;
}

/* ---- element types ------------------------------------------------------------------------ */

static const struct {
    const char *name;
    size_t size;
    cdvr_type vtype;
    int converted;
} ETYPES[CDVR_IO_ETYPES] = {
    {"int8", 1, CDVR_TYPE_F32, 1},     {"uint8", 1, CDVR_TYPE_U8, 0},
    {"int16", 2, CDVR_TYPE_I16, 0},    {"uint16", 2, CDVR_TYPE_U16, 0},
    {"int32", 4, CDVR_TYPE_F32, 1},    {"uint32", 4, CDVR_TYPE_F32, 1},
    {"int64", 8, CDVR_TYPE_F32, 1},    {"uint64", 8, CDVR_TYPE_F32, 1},
    {"float32", 4, CDVR_TYPE_F32, 0},  {"float64", 8, CDVR_TYPE_F32, 1},
};

size_t cdvr_io_etype_size(cdvr_io_etype t) { return ETYPES[t].size; }
const char *cdvr_io_etype_name(cdvr_io_etype t) { return ETYPES[t].name; }
cdvr_type cdvr_io_etype_volume_type(cdvr_io_etype t) { return ETYPES[t].vtype; }
int cdvr_io_etype_converted(cdvr_io_etype t) { return ETYPES[t].converted; }

void cdvr_io_set_type(cdvr_volume *head, cdvr_io_etype t)
{
    head->type = ETYPES[t].vtype;
    cdvr_volume_set_source_type(head, ETYPES[t].name);
}

void cdvr_io_range_init(cdvr_io_range *r, const cdvr_raw_opts *opts)
{
    r->lo = INFINITY;
    r->hi = -INFINITY;
    cdvr_f32_guard_init(&r->guard, opts);
}

static void range_add(cdvr_io_range *r, double v)
{
    if (isfinite(v)) {
        if (v < r->lo)
            r->lo = v;
        if (v > r->hi)
            r->hi = v;
    }
}

/* Element i of src (type t, swapped when swap) as double. */
static double element(const uint8_t *src, cdvr_io_etype t, int swap, size_t i)
{
    size_t k = ETYPES[t].size;
    uint8_t b[8];
    memcpy(b, src + i * k, k);
    if (swap)
        for (size_t j = 0; j < k / 2; j++) {
            uint8_t c = b[j];
            b[j] = b[k - 1 - j];
            b[k - 1 - j] = c;
        }
    switch (t) {
    case CDVR_IO_I8: return (int8_t)b[0];
    case CDVR_IO_U8: return b[0];
    case CDVR_IO_I16: { int16_t v; memcpy(&v, b, 2); return v; }
    case CDVR_IO_U16: { uint16_t v; memcpy(&v, b, 2); return v; }
    case CDVR_IO_I32: { int32_t v; memcpy(&v, b, 4); return v; }
    case CDVR_IO_U32: { uint32_t v; memcpy(&v, b, 4); return v; }
    case CDVR_IO_I64: { int64_t v; memcpy(&v, b, 8); return (double)v; }
    case CDVR_IO_U64: { uint64_t v; memcpy(&v, b, 8); return (double)v; }
    case CDVR_IO_F32: { float v; memcpy(&v, b, 4); return v; }
    case CDVR_IO_F64: { double v; memcpy(&v, b, 8); return v; }
    default: return 0;
    }
}

void cdvr_io_store(cdvr_volume *vol, size_t at, const void *src, cdvr_io_etype t, int big_endian,
                   size_t count, cdvr_io_range *r)
{
    size_t k = ETYPES[t].size;
    int swap = k > 1 && (big_endian ? 1 : 0) == cdvr_host_is_little_endian();
    if (!ETYPES[t].converted) {
        uint8_t *dst = (uint8_t *)vol->data + at * k;
        memcpy(dst, src, count * k);
        if (swap)
            cdvr_swap_bytes(dst, count, k);
        return;
    }
    float *dst = (float *)vol->data + at;
    for (size_t i = 0; i < count; i++) {
        double v = element(src, t, swap, i);
        range_add(r, v);
        dst[i] = cdvr_f32_guard_put(&r->guard, v, (uint64_t)(at + i));
    }
}

void cdvr_io_store_double(cdvr_volume *vol, size_t at, double v, cdvr_io_range *r)
{
    double lo = 0, hi = 0;
    switch (vol->type) {
    case CDVR_TYPE_U8: lo = 0; hi = 255; break;
    case CDVR_TYPE_U16: lo = 0; hi = 65535; break;
    case CDVR_TYPE_I16: lo = -32768; hi = 32767; break;
    case CDVR_TYPE_F32:
        range_add(r, v);
        ((float *)vol->data)[at] = cdvr_f32_guard_put(&r->guard, v, (uint64_t)at);
        return;
    }
    v = isnan(v) ? 0 : v < lo ? lo : v > hi ? hi : floor(v + 0.5);
    if (vol->type == CDVR_TYPE_U8)
        ((uint8_t *)vol->data)[at] = (uint8_t)v;
    else if (vol->type == CDVR_TYPE_U16)
        ((uint16_t *)vol->data)[at] = (uint16_t)v;
    else
        ((int16_t *)vol->data)[at] = (int16_t)v;
}

cdvr_status cdvr_io_finish(cdvr_volume *vol, cdvr_io_etype t, const cdvr_io_range *r,
                           const char *path, const char *what, cdvr_error *err)
{
    cdvr_volume_set_source_type(vol, ETYPES[t].name);
    if (!ETYPES[t].converted)
        return CDVR_OK;
    vol->window[0] = r->lo <= r->hi ? r->lo : 0;
    vol->window[1] = r->lo <= r->hi ? r->hi : 0;
    return cdvr_f32_guard_finish(&r->guard, path, what, ETYPES[t].name, vol, err);
}

/* ---- zlib ------------------------------------------------------------------------------------ */

cdvr_status cdvr_io_inflate(const char *path, const char *what, const uint8_t *src, size_t n,
                            uint8_t *dst, size_t dst_n, cdvr_error *err)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    if (inflateInit2(&z, 15 + 32) != Z_OK) /* zlib or gzip, told by the header */
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: %s: cannot start zlib", path, what);
    size_t in_done = 0, out_done = 0;
    int rc = Z_OK;
    uint8_t extra;
    while (rc == Z_OK) {
        size_t in_left = n - in_done, out_left = dst_n - out_done;
        z.next_in = (Bytef *)(uintptr_t)(src + in_done);
        z.avail_in = in_left > UINT32_MAX ? UINT32_MAX : (uInt)in_left;
        /* one spare byte past the end so that a stream holding more than dst_n is seen */
        z.next_out = out_left ? dst + out_done : &extra;
        z.avail_out = out_left ? (out_left > UINT32_MAX ? UINT32_MAX : (uInt)out_left) : 1;
        uInt in0 = z.avail_in, out0 = z.avail_out;
        rc = inflate(&z, Z_NO_FLUSH);
        in_done += in0 - z.avail_in;
        size_t produced = out0 - z.avail_out;
        if (!out_left && produced) {
            inflateEnd(&z);
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s: zlib data inflate to more than "
                                  "the %zu bytes the header gives", path, what, dst_n);
        }
        out_done += out_left ? produced : 0;
        if (rc == Z_BUF_ERROR && in_done == n)
            break;
        if (rc == Z_BUF_ERROR)
            rc = Z_OK;
    }
    inflateEnd(&z);
    if (rc != Z_STREAM_END)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s: %s zlib data", path, what,
                              rc == Z_BUF_ERROR || rc == Z_OK ? "truncated" : "corrupt");
    if (out_done != dst_n)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s: zlib data inflate to %zu bytes, the "
                              "header gives %zu", path, what, out_done, dst_n);
    return CDVR_OK;
}

/* ---- base64 and ASCII -------------------------------------------------------------------- */

static int b64_value(uint8_t c)
{
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
}

int cdvr_io_base64(const uint8_t *text, size_t n, size_t *pos, uint8_t *out, size_t out_n)
{
    size_t i = *pos, done = 0;
    while (done < out_n) {
        int v[4], got = 0, pad = 0;
        while (got < 4) {
            if (i >= n)
                return 0;
            uint8_t c = text[i++];
            if (isspace(c))
                continue;
            if (c == '=') {
                if (got < 2)
                    return 0;
                v[got++] = 0;
                pad++;
                continue;
            }
            if (pad || (v[got] = b64_value(c)) < 0)
                return 0;
            got++;
        }
        uint8_t b[3] = {(uint8_t)(v[0] << 2 | v[1] >> 4), (uint8_t)(v[1] << 4 | v[2] >> 2),
                        (uint8_t)(v[2] << 6 | v[3])};
        for (int k = 0; k < 3 - pad && done < out_n; k++)
            out[done++] = b[k];
    }
    *pos = i;
    return 1;
}

size_t cdvr_io_base64_bound(size_t pos, size_t n)
{
    return pos < n ? (n - pos) / 4 * 3 + 3 : 0;
}

int cdvr_io_ascii_number(const uint8_t *text, size_t n, size_t *pos, double *v)
{
    size_t i = *pos;
    while (i < n && isspace(text[i]))
        i++;
    char buf[64];
    size_t k = 0;
    while (i < n && !isspace(text[i]) && k < sizeof buf - 1)
        buf[k++] = (char)text[i++];
    if (k == 0 || (i < n && !isspace(text[i])))
        return 0;
    buf[k] = 0;
    char *end;
    errno = 0;
    *v = strtod(buf, &end);
    if (*end)
        return 0;
    *pos = i;
    return 1;
}

int cdvr_io_parse_doubles(const char *s, double *v, int count)
{
    for (int i = 0; i < count; i++) {
        char *end;
        v[i] = strtod(s, &end);
        if (end == s || !isfinite(v[i]))
            return 0;
        s = end;
    }
    while (isspace((unsigned char)*s))
        s++;
    return *s == 0;
}

cdvr_status cdvr_io_set_direction(const char *path, const char *what, const double m[9],
                                  cdvr_volume *vol, cdvr_error *err)
{
    double d[9];
    for (int c = 0; c < 3; c++) {
        double len = sqrt(m[c] * m[c] + m[3 + c] * m[3 + c] + m[6 + c] * m[6 + c]);
        if (!(len > 0) || !isfinite(len))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s: column %d is zero", path, what,
                                  c);
        for (int r = 0; r < 3; r++)
            d[3 * r + c] = m[3 * r + c] / len;
        vol->spacing[c] *= len;
    }
    double inv[9];
    if (!cdvr_mat3_inverse(d, inv))
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s is singular (the axes do not span 3D "
                              "space)", path, what);
    memcpy(vol->direction, d, sizeof d);
    return CDVR_OK;
}
