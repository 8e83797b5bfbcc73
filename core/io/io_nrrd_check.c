/* core/io/io_nrrd_check.c - the NRRD header and its data files, checked before anything is read
 * (io_nrrd.h), and the reader of raw, gzip and bzip2 data straight into the volume.
 *
 * teem trusts the header: nrrdLoad allocates (and zeroes) what "sizes" claims before reading a
 * byte, so a 100-byte file can claim 8 GB; it opens detached data files with fopen, so a FIFO
 * blocks forever, "-" reads standard input and /dev/zero never ends, and any path (/etc/shadow,
 * ../../x) is read as voxels; a LIST of 200000 files takes it minutes; it leaks inside libbz2
 * and its gzip reader when a stream is corrupt; and nrrdLoad's buffer is a second copy of the
 * volume. So:
 *
 *  1. The header is read here, from a regular file (at most CDVR_NRRD_HEADER_MAX bytes), and
 *     parsed by teem from that text (nrrdStringRead, skipData) with the "data file" field taken
 *     out, so teem opens nothing. The data files are resolved here as teem does
 *     (nrrdIoStateDataFileIterNext): a single name, "LIST [subdim]" (the remaining lines), or
 *     "FORMAT min max step [subdim]" (FORMAT with exactly one %d-like conversion); names not
 *     starting with '/' are relative to the header's directory; at most CDVR_NRRD_FILES_MAX,
 *     as many as teem's subdimension rule asks for (check_file_count).
 *  2. Every data file must lie under the header's directory once both are resolved by realpath
 *     (symlinks, ".."), unless the load options say allow_outside; and be a regular file other
 *     than the header itself ("-", standard input, is refused).
 *  3. The claim (elements x element size, and the volume it makes) must be within max_bytes
 *     (cdvr_load_max_bytes), and each file's data must be able to hold its share (elements x
 *     element size / number of files), before anything is allocated:
 *       raw    bytes after the header (attached data) and byte skip >= claimed bytes
 *       ascii  at least one byte per value;  hex: two bytes per data byte
 *       zrl    at most 256 data bytes per stored byte
 *       gzip   at most 1032 bytes per stored byte (deflate's largest ratio)
 *       bzip2  (no useful ratio bound) a claim beyond 1032 per stored byte is decompressed
 *              once, nothing kept, before the volume is allocated
 *  4. Raw, gzip and bzip2 data are read here (cdvr_nrrd_stream) in pieces into the caller's
 *     sink (io_nrrd.c converts them into the volume's buffer): a stream stops at the claimed
 *     size, and one that ends earlier, goes on past it or is corrupt is refused naming the file.
 *     teem reads only ascii, hex and zrl data (after these checks).
 * The file can still change between these checks and the read; this guards against mistakes and
 * broken or hostile files, not against a concurrent attacker.
 */
#include "cdvr/regular_file.h"
#include "cdvr/volume.h"
#include "volume_io.h"
#include "io_nrrd.h"

#include <bzlib.h>
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <teem/nrrd.h>
#include <unistd.h>
#include <zlib.h>

#define STREAM_BUF (64u << 10)

/* ---- teem's error chain ------------------------------------------------------------------ */

void cdvr_teem_reason(char *msg)
{
    /* biff: "[nrrd] outer: trouble\n[nrrd] inner: reason\n", innermost last; keep the last
     * non-empty reason (the text after "[key] function: "). */
    const char *best = NULL;
    size_t best_len = 0;
    for (char *line = msg; line && *line;) {
        char *end = strchr(line, '\n');
        size_t len = end ? (size_t)(end - line) : strlen(line);
        const char *text = line;
        if (*text == '[' && memchr(text, ']', len))
            text = (const char *)memchr(text, ']', len) + 1;
        const char *colon = memchr(text, ':', len - (size_t)(text - line));
        if (colon)
            text = colon + 1;
        while (text < line + len && isspace((unsigned char)*text))
            text++;
        size_t tlen = len - (size_t)(text - line);
        while (tlen > 0 && isspace((unsigned char)text[tlen - 1]))
            tlen--;
        if (tlen > 0) {
            best = text;
            best_len = tlen;
        }
        line = end ? end + 1 : NULL;
    }
    if (best) {
        memmove(msg, best, best_len);
        msg[best_len] = '\0';
    }
}

static cdvr_status teem_error(const char *path, const char *what, cdvr_error *err)
{
    char *msg = biffGetDone(NRRD);
    if (msg)
        cdvr_teem_reason(msg);
    cdvr_status st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s: %s", path, what,
                                    msg && *msg ? msg : "unknown teem error");
    free(msg);
    return st;
}

/* ---- the header ------------------------------------------------------------------------- */

typedef struct nrrd_header {
    char *text;              /* the file's first bytes, NUL-terminated */
    size_t len;
    uint64_t data_offset;    /* attached data starts here (after the empty line) */
    char *data_file;         /* the "data file" field's value (a copy), or NULL */
    const char *list;        /* with "data file: LIST": the first name line, or NULL */
    struct stat sb;          /* of the header file */
} nrrd_header;

/* 1 when line (len bytes) is the field "data file" / "datafile" (not a key/value ":="); then
 * *value points after ": ". */
static int is_data_file_field(const char *line, size_t len, const char **value)
{
    static const char *const names[] = {"data file:", "datafile:"};
    for (int i = 0; i < 2; i++) {
        size_t n = strlen(names[i]);
        if (len >= n && strncasecmp(line, names[i], n) == 0 && (len == n || line[n] != '=')) {
            *value = line + n;
            while (*value < line + len && (**value == ' ' || **value == '\t'))
                (*value)++;
            return 1;
        }
    }
    return 0;
}

/* Reads the header (and a LIST's names) of the open file; splits it into lines in place. */
static cdvr_status read_header(const char *path, FILE *f, nrrd_header *h, cdvr_error *err)
{
    h->text = malloc(CDVR_NRRD_HEADER_MAX + 1);
    if (!h->text)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    h->len = fread(h->text, 1, CDVR_NRRD_HEADER_MAX, f);
    h->text[h->len] = '\0';
    size_t pos = 0;
    int ended = 0;
    const char *value;
    while (pos < h->len && !ended) {
        char *line = h->text + pos, *nl = memchr(line, '\n', h->len - pos);
        size_t len = nl ? (size_t)(nl - line) : h->len - pos;
        pos += len + (nl != NULL);
        if (nl)
            *nl = '\0';
        if (len > 0 && line[len - 1] == '\r')
            line[--len] = '\0';
        if (len == 0 && nl) { /* the empty line: attached data follow */
            ended = 1;
            h->data_offset = pos;
        } else if (line[0] != '#' && !h->data_file && is_data_file_field(line, len, &value)) {
            h->data_file = strdup(value);
            if (!h->data_file)
                return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
            memset(line, 0, len); /* taken out of what teem parses */
            if (strncmp(h->data_file, "LIST", 4) == 0) {
                h->list = h->text + pos; /* every further line names a data file */
                for (char *p = h->text + pos; p < h->text + h->len; p++)
                    if (*p == '\n' || *p == '\r')
                        *p = '\0';
                return CDVR_OK;
            }
        }
        if (len > 0 && memchr(line, '\0', len)) /* a NUL inside a line: binary, not a header */
            break;
    }
    if (!ended && h->len == CDVR_NRRD_HEADER_MAX && !h->data_file)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD header longer than %u bytes", path,
                              CDVR_NRRD_HEADER_MAX);
    if (!ended)
        h->data_offset = h->len;
    return CDVR_OK;
}

/* The header text teem parses: the lines before the empty line, without the data file field
 * (blanked by read_header), joined by '\n'. */
static char *header_for_teem(const nrrd_header *h)
{
    char *out = malloc(h->len + 2), *o = out;
    if (!out)
        return NULL;
    const char *end = h->list ? h->list : h->text + (h->data_offset ? h->data_offset : h->len);
    for (const char *p = h->text; p < end && p < h->text + h->len;) {
        size_t len = strlen(p);
        if (len > 0) {
            memcpy(o, p, len);
            o += len;
            *o++ = '\n';
        }
        p += len + 1;
    }
    *o = '\0';
    return out;
}

/* ---- data files ------------------------------------------------------------------------- */

typedef struct nrrd_shape {
    const NrrdEncoding *encoding;
    uint64_t elements, bytes;      /* whole array */
    long byte_skip;
    unsigned line_skip;
    char what[160];                /* "sizes 64 64 64 float" for messages */
} nrrd_shape;

/* Elements and bytes of the parsed header, overflow-checked. */
static cdvr_status shape_of(const char *path, const Nrrd *nrrd, const NrrdIoState *nio, nrrd_shape *s,
                            cdvr_error *err)
{
    size_t n = 1, off = (size_t)snprintf(s->what, sizeof s->what, "sizes");
    for (unsigned ax = 0; ax < nrrd->dim; ax++) {
        if (!cdvr_size_mul(n, nrrd->axis[ax].size, &n))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD sizes overflow the address space", path);
        if (off < sizeof s->what)
            off += (size_t)snprintf(s->what + off, sizeof s->what - off, " %zu", nrrd->axis[ax].size);
    }
    if (off < sizeof s->what)
        snprintf(s->what + off, sizeof s->what - off, " %s", airEnumStr(nrrdType, nrrd->type));
    size_t bytes;
    if (!cdvr_size_mul(n, nrrdElementSize(nrrd), &bytes))
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD %s overflows the address space", path, s->what);
    s->encoding = nio->encoding;
    s->elements = n;
    s->bytes = bytes;
    s->byte_skip = nio->byteSkip;
    s->line_skip = nio->lineSkip;
    return CDVR_OK;
}

/* Splits "FORMAT min max step [subdim]"; returns 1 when value has teem's %d-like conversion
 * (a '%', digits, 'd'), with the conversion checked to be the only one. */
static int is_name_format(const char *value)
{
    for (const char *p = strchr(value, '%'); p; p = strchr(p + 1, '%')) {
        const char *q = p + 1 + strspn(p + 1, "0123456789");
        if (*q == 'd')
            return 1;
    }
    return 0;
}

/* Writes file number num of a checked FORMAT (one %[0][width]d, no other '%') into out. */
static int format_name(const char *format, size_t flen, long num, char *out, size_t size)
{
    const char *pct = memchr(format, '%', flen);
    const char *conv = pct + 1;
    size_t digits = strspn(conv, "0123456789");
    int zero = conv[0] == '0', width = atoi(conv);
    size_t pre = (size_t)(pct - format), post_at = pre + 1 + digits + 1;
    int n = snprintf(out, size, "%.*s%0*ld%.*s", (int)pre, format, zero ? width : 0, num,
                     (int)(flen - post_at), format + post_at);
    if (!zero && width > 0)
        n = snprintf(out, size, "%.*s%*ld%.*s", (int)pre, format, width, num, (int)(flen - post_at),
                     format + post_at);
    return n > 0 && (size_t)n < size;
}

/* Path of data file `name` as teem opens it: relative names are relative to the header's
 * directory. */
static int data_path(const char *header, const char *name, size_t len, char *out, size_t size)
{
    const char *slash = strrchr(header, '/');
    int n;
    if (name[0] == '/' || !slash)
        n = snprintf(out, size, "%.*s", (int)len, name);
    else
        n = snprintf(out, size, "%.*s/%.*s", (int)(slash - header), header, (int)len, name);
    return n > 0 && (size_t)n < size;
}

/* Skips line_skip lines of f; 0 when the file ends first. */
static int skip_lines(FILE *f, unsigned lines)
{
    for (unsigned i = 0; i < lines;) {
        int c = getc(f);
        if (c == EOF)
            return 0;
        i += c == '\n';
    }
    return 1;
}

static cdvr_status count_bzip2(const char *path, const char *file, uint64_t offset,
                               const nrrd_shape *s, uint64_t need, cdvr_error *err);

/* Checks data file `file` (its share: `want` bytes) holding data from `offset` on: a regular
 * file, not the header itself, able to hold its share (compressed: within the ratio bound; the
 * stream itself is checked as it is read). */
static cdvr_status check_data_file(const char *path, const nrrd_header *h, const char *file, int attached,
                                   const nrrd_shape *s, uint64_t want, cdvr_error *err)
{
    struct stat sb;
    cdvr_error why;
    if (cdvr_check_regular_file(file, &sb, &why) != CDVR_OK)
        return cdvr_error_set(err, why.status, "%s: NRRD data file %s", path, why.msg);
    if (!attached && sb.st_dev == h->sb.st_dev && sb.st_ino == h->sb.st_ino)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: the NRRD data file is the header itself", path);
    uint64_t offset = attached ? h->data_offset : 0, size = (uint64_t)sb.st_size;
    uint64_t avail = size > offset ? size - offset : 0;
    int compressed = s->encoding == nrrdEncodingGzip || s->encoding == nrrdEncodingBzip2;
    uint64_t skip = s->byte_skip > 0 ? (uint64_t)s->byte_skip : 0;
    if (!compressed && s->byte_skip >= 0)
        avail = avail > skip ? avail - skip : 0;
    uint64_t have = avail; /* upper bound of the data bytes the file can yield */
    if (s->encoding == nrrdEncodingHex)
        have = avail / 2;
    else if (s->encoding == nrrdEncodingAscii)
        have = s->bytes / (s->elements ? s->elements : 1) * avail; /* a value takes a byte at least */
    else if (s->encoding == nrrdEncodingZRL)
        have = avail > UINT64_MAX / 256 ? UINT64_MAX : avail * 256;
    else if (s->encoding == nrrdEncodingGzip)
        have = avail > UINT64_MAX / 1032 ? UINT64_MAX : avail * 1032;
    uint64_t need = compressed ? want + skip : want;
    if (s->encoding == nrrdEncodingBzip2 && (avail > UINT64_MAX / 1032 || avail * 1032 < need))
        return count_bzip2(path, file, offset, s, need, err);
    if (s->encoding != nrrdEncodingBzip2 && have < need)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD header claims %llu bytes of data (%s, %s encoding), but %s holds only %llu "
                              "bytes after the header and skips%s",
                              path, (unsigned long long)need, s->what, s->encoding->name, file, (unsigned long long)avail,
                              s->encoding == nrrdEncodingGzip ? " (gzip expands at most 1032 times)" : "");
    return CDVR_OK;
}

/* ---- the source: header + data files ------------------------------------------------------ */

struct cdvr_nrrd_source {
    const char *path;              /* the header (the caller's string) */
    nrrd_header h;
    Nrrd *nrrd;
    NrrdIoState *nio;
    nrrd_shape shape;
    char **files;                  /* data files as teem would open them; attached: NULL */
    size_t nfiles;
    char *dir;                     /* realpath of the header's directory */
    int allow_outside;
};

const Nrrd *cdvr_nrrd_header(const cdvr_nrrd_source *s)
{
    return s->nrrd;
}

const NrrdIoState *cdvr_nrrd_io(const cdvr_nrrd_source *s)
{
    return s->nio;
}

int cdvr_nrrd_streamable(const cdvr_nrrd_source *s)
{
    const NrrdEncoding *e = s->shape.encoding;
    return e == nrrdEncodingRaw || e == nrrdEncodingGzip || e == nrrdEncodingBzip2;
}

int cdvr_nrrd_swap(const cdvr_nrrd_source *s)
{
    return nrrdElementSize(s->nrrd) > 1 && s->nio->endian != airEndianUnknown &&
           s->nio->endian != airMyEndian();
}

void cdvr_nrrd_close(cdvr_nrrd_source *s)
{
    if (!s)
        return;
    if (s->nio) /* teem's Nix functions dereference their argument */
        nrrdIoStateNix(s->nio);
    if (s->nrrd)
        nrrdNuke(s->nrrd);
    for (size_t i = 0; i < s->nfiles; i++)
        free(s->files[i]);
    free(s->files);
    free(s->dir);
    free(s->h.data_file);
    free(s->h.text);
    free(s);
}

/* Adds a data file, refusing one outside the header's directory (after realpath) unless
 * allowed; a confined file is kept by its resolved name, so what is read is what was checked. */
static cdvr_status add_file(cdvr_nrrd_source *s, const char *file, size_t cap, cdvr_error *err)
{
    char *keep = NULL;
    if (!s->allow_outside) {
        char *real = realpath(file, NULL);
        if (!real)
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: NRRD data file %s: %s", s->path, file,
                                  strerror(errno));
        size_t n = strlen(s->dir);
        int inside = strncmp(real, s->dir, n) == 0 && (real[n] == '/' || (n == 1 && s->dir[0] == '/'));
        if (!inside) {
            cdvr_status st = cdvr_error_set(err, CDVR_ERR_ARG, "%s: NRRD data file %s (%s) is "
                                            "outside the header's directory %s (load option "
                                            "allow_outside=true reads it)", s->path, file, real,
                                            s->dir);
            free(real);
            return st;
        }
        keep = real;
    }
    if (!keep && !(keep = strdup(file)))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", s->path);
    if (!s->files && !(s->files = calloc(cap, sizeof *s->files))) {
        free(keep);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", s->path);
    }
    s->files[s->nfiles++] = keep;
    return CDVR_OK;
}

/* teem's rule for the number of data files (subdim: the dimension of each file's piece; given
 * after LIST or as FORMAT's fourth number, else the array's dimension - 1): with subdim < dim
 * there is one file per piece (the product of the sizes of axes subdim .. dim-1); with subdim ==
 * dim the files are slabs along the slowest axis, at most one per slice (and here: the same
 * number of slices each, as the data are read). */
static cdvr_status check_file_count(const cdvr_nrrd_source *s, uint64_t count, const char *sub,
                                    cdvr_error *err)
{
    const Nrrd *n = s->nrrd;
    unsigned dim = n->dim, d = dim - 1;
    char *end;
    long given = sub ? strtol(sub, &end, 10) : 0;
    if (sub && end != sub) {
        if (given < 1 || given > (long)dim)
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file subdimension %ld is "
                                  "not 1..%u", s->path, given, dim);
        d = (unsigned)given;
    }
    if (d < dim) {
        uint64_t pieces = 1;
        for (unsigned ax = d; ax < dim; ax++)
            pieces *= n->axis[ax].size; /* <= elements: no overflow (shape_of checked) */
        if (pieces != count)
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data files: %llu named, the "
                                  "sizes need %llu (of %u-D pieces)", s->path,
                                  (unsigned long long)count, (unsigned long long)pieces, d);
        return CDVR_OK;
    }
    size_t slices = n->axis[dim - 1].size;
    if (count > slices || slices % count != 0)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data files: %llu slabs of the %zu "
                              "slices of axis %u (a slab count must divide them)", s->path,
                              (unsigned long long)count, slices, dim - 1);
    return CDVR_OK;
}

/* Resolves the data files the header names (none: attached data). */
static cdvr_status resolve_files(cdvr_nrrd_source *s, cdvr_error *err)
{
    const char *path = s->path, *v = s->h.data_file;
    char file[PATH_MAX];
    if (!v)
        return CDVR_OK;
    if (!s->allow_outside) {
        /* the directory relative names are taken from (the header as named: through a
         * symbolic link to a header, its names are relative to the link's directory) */
        const char *slash = strrchr(path, '/');
        char here[PATH_MAX];
        if (!slash)
            snprintf(here, sizeof here, ".");
        else if (slash == path)
            snprintf(here, sizeof here, "/");
        else if (snprintf(here, sizeof here, "%.*s", (int)(slash - path), path) >= (int)sizeof here)
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: path too long", path);
        if (!(s->dir = realpath(here, NULL)))
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: %s: %s", path, here, strerror(errno));
    }
    if (s->h.list) {
        size_t count = 0;
        for (const char *p = s->h.list; p < s->h.text + s->h.len; p += strlen(p) + 1)
            count += strlen(p) > 0;
        if (count == 0 || count > CDVR_NRRD_FILES_MAX)
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file LIST names %zu files "
                                  "(the limit is 1..%d)", path, count, CDVR_NRRD_FILES_MAX);
        cdvr_status cs = check_file_count(s, count, v + 4, err);
        if (cs != CDVR_OK)
            return cs;
        for (const char *p = s->h.list; p < s->h.text + s->h.len; p += strlen(p) + 1) {
            size_t len = strlen(p);
            if (len == 0)
                continue;
            if (!data_path(path, p, len, file, sizeof file))
                return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file name too long", path);
            cdvr_status st = add_file(s, file, count, err);
            if (st != CDVR_OK)
                return st;
        }
        return CDVR_OK;
    }
    if (strcmp(v, "-") == 0)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file '-' (standard input) is not supported", path);
    if (!is_name_format(v)) {
        if (!data_path(path, v, strlen(v), file, sizeof file))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file name too long", path);
        return add_file(s, file, 1, err);
    }
    size_t flen = strcspn(v, " \t");
    const char *pct = memchr(v, '%', flen);
    const char *conv = pct ? pct + 1 + strspn(pct + 1, "0123456789") : NULL;
    long lo, hi, step;
    if (!pct || *conv != 'd' || memchr(conv, '%', flen - (size_t)(conv - v)) || conv - pct - 1 > 3 ||
        sscanf(v + flen, "%ld %ld %ld", &lo, &hi, &step) != 3 || step == 0 || (hi - lo) / step < 0 ||
        lo < -1000000000L || lo > 1000000000L || hi < -1000000000L || hi > 1000000000L)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD data file '%s': expected FORMAT min max step with one %%d-like conversion",
                              path, v);
    uint64_t count = (uint64_t)((hi - lo) / step) + 1;
    if (count > CDVR_NRRD_FILES_MAX)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file pattern names %llu files "
                              "(the limit is %d)", path, (unsigned long long)count, CDVR_NRRD_FILES_MAX);
    long sub_n;
    int fields = sscanf(v + flen, "%ld %ld %ld %ld", &lo, &hi, &step, &sub_n);
    cdvr_status cs = check_file_count(s, count, NULL, err);
    if (fields == 4) {
        char sub[32];
        snprintf(sub, sizeof sub, "%ld", sub_n);
        cs = check_file_count(s, count, sub, err);
    }
    if (cs != CDVR_OK)
        return cs;
    for (uint64_t i = 0; i < count; i++) {
        char name[PATH_MAX];
        if (!format_name(v, flen, lo + (long)i * step, name, sizeof name) ||
            !data_path(path, name, strlen(name), file, sizeof file))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file name too long", path);
        cdvr_status st = add_file(s, file, (size_t)count, err);
        if (st != CDVR_OK)
            return st;
    }
    return CDVR_OK;
}

/* Checks every data file (cheap checks: stat; compressed streams are checked as they are read). */
static cdvr_status check_data_files(const cdvr_nrrd_source *s, cdvr_error *err)
{
    if (!s->files)
        return check_data_file(s->path, &s->h, s->path, 1, &s->shape, s->shape.bytes, err);
    for (size_t i = 0; i < s->nfiles; i++) {
        cdvr_status st = check_data_file(s->path, &s->h, s->files[i], 0, &s->shape,
                                         s->shape.bytes / s->nfiles, err);
        if (st != CDVR_OK)
            return st;
    }
    return CDVR_OK;
}

/* The voxel bytes of the volume a load makes (types other than u8/u16/i16/f32 become f32). */
static uint64_t volume_bytes(const Nrrd *nrrd, uint64_t elements)
{
    switch (nrrd->type) {
    case nrrdTypeUChar: return elements;
    case nrrdTypeUShort:
    case nrrdTypeShort: return elements > UINT64_MAX / 2 ? UINT64_MAX : 2 * elements;
    default: return elements > UINT64_MAX / 4 ? UINT64_MAX : 4 * elements;
    }
}

cdvr_status cdvr_nrrd_open(const char *path, const cdvr_raw_opts *opts, int header_only,
                           cdvr_nrrd_source **out, cdvr_error *err)
{
    *out = NULL;
    cdvr_nrrd_source *s = calloc(1, sizeof *s);
    if (!s)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    s->path = path;
    s->allow_outside = opts && opts->allow_outside;
    FILE *f;
    cdvr_status st = cdvr_fopen_regular_file(path, &f, &s->h.sb, err);
    if (st != CDVR_OK) {
        free(s);
        return st;
    }
    st = read_header(path, f, &s->h, err);
    fclose(f);
    char *text = st == CDVR_OK ? header_for_teem(&s->h) : NULL;
    if (st == CDVR_OK && !text)
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (st == CDVR_OK) {
        s->nrrd = nrrdNew();
        s->nio = nrrdIoStateNew();
        if (!s->nrrd || !s->nio)
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    if (st == CDVR_OK) {
        s->nio->skipData = 1;
        if (nrrdStringRead(s->nrrd, text, s->nio))
            st = teem_error(path, "cannot read NRRD header", err);
    }
    free(text);
    if (st == CDVR_OK)
        st = shape_of(path, s->nrrd, s->nio, &s->shape, err);
    uint64_t max = cdvr_load_max_bytes(opts), vbytes = st == CDVR_OK ? volume_bytes(s->nrrd, s->shape.elements) : 0;
    if (st == CDVR_OK && (s->shape.bytes > max || vbytes > max))
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD header claims %llu bytes of data (%s), "
                            "more than max_bytes %llu (a load option; the default is half the "
                            "physical memory)", path,
                            (unsigned long long)(s->shape.bytes > vbytes ? s->shape.bytes : vbytes),
                            s->shape.what, (unsigned long long)max);
    if (st == CDVR_OK && s->shape.byte_skip < 0 && s->shape.encoding != nrrdEncodingRaw)
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD byte skip %ld (data at the end of the "
                            "file) needs raw encoding, not %s", path, s->shape.byte_skip,
                            s->shape.encoding->name);
    if (st == CDVR_OK)
        st = resolve_files(s, err);
    if (st == CDVR_OK && !header_only) {
        st = check_data_files(s, err);
    }
    if (st != CDVR_OK) {
        cdvr_nrrd_close(s);
        return st;
    }
    *out = s;
    return CDVR_OK;
}

/* ---- reading the data -------------------------------------------------------------------- */

typedef struct data_sink {
    int (*fn)(void *ud, const unsigned char *p, size_t n);
    void *ud;
    uint64_t skip;                 /* decompressed bytes still to drop (byte skip) */
} data_sink;

static int feed(data_sink *k, const unsigned char *p, size_t n)
{
    if (k->skip) {
        size_t d = k->skip < n ? (size_t)k->skip : n;
        k->skip -= d;
        p += d;
        n -= d;
    }
    return n == 0 || k->fn(k->ud, p, n);
}

/* Inflates (gzip or zlib, concatenated members continue as in teem's reader) until want bytes
 * came out; then the stream must end there. Returns the reason of a failure or NULL. */
static const char *inflate_to(FILE *f, uint64_t want, data_sink *k, unsigned char *in,
                              unsigned char *out, uint64_t *produced, int *sink_failed)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    if (inflateInit2(&z, 15 + 32) != Z_OK)
        return "zlib cannot start";
    const char *why = NULL;
    int eof = 0, ended = 0;
    while (!why) {
        if (z.avail_in == 0 && !eof) {
            z.avail_in = (uInt)fread(in, 1, STREAM_BUF, f);
            z.next_in = in;
            eof = z.avail_in == 0;
        }
        uint64_t left = want - *produced;
        uInt room = left == 0 ? 1 : left < STREAM_BUF ? (uInt)left : STREAM_BUF; /* 1: probe for more */
        z.next_out = out;
        z.avail_out = room;
        int rc = inflate(&z, Z_NO_FLUSH);
        size_t got = room - z.avail_out;
        if (left == 0 && got > 0) {
            why = "the stream holds more data than the header claims";
            break;
        }
        *produced += got;
        if (got && !feed(k, out, got)) {
            *sink_failed = 1;
            break;
        }
        if (rc == Z_STREAM_END) { /* end of a gzip member: another may follow */
            if (z.avail_in == 0 && !eof) {
                z.avail_in = (uInt)fread(in, 1, STREAM_BUF, f);
                z.next_in = in;
                eof = z.avail_in == 0;
            }
            if (z.avail_in == 0) {
                ended = 1;
                break;
            }
            inflateReset(&z);
        } else if (rc == Z_BUF_ERROR && eof && z.avail_in == 0) {
            break; /* the data end in the middle of the stream */
        } else if (rc != Z_OK && rc != Z_BUF_ERROR) {
            why = z.msg ? z.msg : "corrupt data";
        }
    }
    (void)ended;
    inflateEnd(&z);
    return why;
}

static const char *bunzip_to(FILE *f, uint64_t want, data_sink *k, unsigned char *in,
                             unsigned char *out, uint64_t *produced, int *sink_failed)
{
    bz_stream b;
    memset(&b, 0, sizeof b);
    if (BZ2_bzDecompressInit(&b, 0, 0) != BZ_OK)
        return "libbz2 cannot start";
    const char *why = NULL;
    int eof = 0;
    while (!why) {
        if (b.avail_in == 0 && !eof) {
            b.avail_in = (unsigned)fread(in, 1, STREAM_BUF, f);
            b.next_in = (char *)in;
            eof = b.avail_in == 0;
        }
        uint64_t left = want - *produced;
        unsigned room = left == 0 ? 1 : left < STREAM_BUF ? (unsigned)left : STREAM_BUF;
        b.next_out = (char *)out;
        b.avail_out = room;
        int rc = BZ2_bzDecompress(&b);
        size_t got = room - b.avail_out;
        if (left == 0 && got > 0) {
            why = "the stream holds more data than the header claims";
            break;
        }
        *produced += got;
        if (got && !feed(k, out, got)) {
            *sink_failed = 1;
            break;
        }
        if (rc == BZ_STREAM_END)
            break;
        if (rc != BZ_OK)
            why = rc == BZ_DATA_ERROR_MAGIC ? "not bzip2 data" : rc == BZ_MEM_ERROR ? "out of memory" : "corrupt data";
        else if (eof && got == 0 && b.avail_in == 0)
            break; /* no input left and nothing came out: the data end */
    }
    BZ2_bzDecompressEnd(&b);
    return why;
}

static int discard(void *ud, const unsigned char *p, size_t n)
{
    (void)ud, (void)p, (void)n;
    return 1;
}

/* bzip2 has no useful ratio bound: a stream claiming more than 1032 times its stored bytes
 * (beyond any gzip) is decompressed once, nothing kept, before the volume is allocated. */
static cdvr_status count_bzip2(const char *path, const char *file, uint64_t offset,
                               const nrrd_shape *s, uint64_t need, cdvr_error *err)
{
    FILE *f;
    cdvr_status st = cdvr_fopen_regular_file(file, &f, NULL, err);
    if (st != CDVR_OK)
        return st;
    unsigned char *buf = malloc(2 * STREAM_BUF);
    data_sink k = {discard, NULL, 0};
    uint64_t produced = 0;
    int failed = 0;
    const char *why = "out of memory";
    if (buf && fseeko(f, (off_t)offset, SEEK_SET) == 0 && skip_lines(f, s->line_skip))
        why = bunzip_to(f, need, &k, buf, buf + STREAM_BUF, &produced, &failed);
    else if (buf)
        why = "the file ends before the data";
    free(buf);
    fclose(f);
    if (why)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: corrupt bzip2 data in %s: %s", path, file, why);
    if (produced < need)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD header claims %llu bytes of data (%s), but the bzip2 data in %s end after %llu bytes",
                              path, (unsigned long long)need, s->what, file, (unsigned long long)produced);
    return CDVR_OK;
}

/* Streams one data file's share (want bytes after the byte skip) to the sink. */
static cdvr_status stream_file(const cdvr_nrrd_source *s, const char *file, int attached,
                               uint64_t want, data_sink *k, unsigned char *buf, cdvr_error *err)
{
    const nrrd_shape *sh = &s->shape;
    FILE *f;
    struct stat sb;
    cdvr_status st = cdvr_fopen_regular_file(file, &f, &sb, err);
    if (st != CDVR_OK)
        return st;
    uint64_t offset = attached ? s->h.data_offset : 0;
    int ok = fseeko(f, (off_t)offset, SEEK_SET) == 0 && skip_lines(f, sh->line_skip);
    if (!ok) {
        fclose(f);
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s ends before the %u lines to skip",
                              s->path, file, sh->line_skip);
    }
    int sink_failed = 0;
    uint64_t produced = 0, skip = sh->byte_skip > 0 ? (uint64_t)sh->byte_skip : 0;
    const char *why = NULL, *kind = "raw";
    if (sh->encoding == nrrdEncodingRaw) {
        if (sh->byte_skip < 0) /* -1: the data are the file's last bytes */
            ok = (uint64_t)sb.st_size >= want && fseeko(f, (off_t)((uint64_t)sb.st_size - want), SEEK_SET) == 0;
        else
            ok = fseeko(f, (off_t)skip, SEEK_CUR) == 0;
        while (ok && produced < want) {
            size_t n = want - produced < STREAM_BUF ? (size_t)(want - produced) : STREAM_BUF;
            size_t got = fread(buf, 1, n, f);
            produced += got;
            if (got && !feed(k, buf, got)) {
                sink_failed = 1;
                break;
            }
            if (got < n)
                break;
        }
    } else {
        k->skip = skip;
        kind = sh->encoding == nrrdEncodingBzip2 ? "bzip2" : "gzip";
        if (sh->encoding == nrrdEncodingBzip2)
            why = bunzip_to(f, want + skip, k, buf, buf + STREAM_BUF, &produced, &sink_failed);
        else
            why = inflate_to(f, want + skip, k, buf, buf + STREAM_BUF, &produced, &sink_failed);
        produced = produced > skip ? produced - skip : 0;
    }
    fclose(f);
    if (sink_failed)
        return CDVR_ERR_FORMAT; /* the sink's message is in err */
    if (why)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: corrupt %s data in %s: %s", s->path, kind,
                              file, why);
    if (produced < want)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD header claims %llu bytes of data (%s), but the %s data in %s end after %llu bytes",
                              s->path, (unsigned long long)want, sh->what, kind, file,
                              (unsigned long long)produced);
    return CDVR_OK;
}

cdvr_status cdvr_nrrd_stream(const cdvr_nrrd_source *s,
                             int (*sink)(void *ud, const unsigned char *p, size_t n), void *ud,
                             cdvr_error *err)
{
    unsigned char *buf = malloc(2 * STREAM_BUF);
    if (!buf)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", s->path);
    data_sink k = {sink, ud, 0};
    cdvr_status st = CDVR_OK;
    if (!s->files)
        st = stream_file(s, s->path, 1, s->shape.bytes, &k, buf, err);
    for (size_t i = 0; s->files && st == CDVR_OK && i < s->nfiles; i++)
        st = stream_file(s, s->files[i], 0, s->shape.bytes / s->nfiles, &k, buf, err);
    free(buf);
    return st;
}
