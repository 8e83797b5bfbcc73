/* core/io/io_nrrd_check.c - refuses hostile NRRD files before teem touches their data.
 *
 * teem trusts the header: nrrdLoad allocates (and zeroes) what "sizes" claims before reading a
 * byte, so a 100-byte file can claim 8 GB; it opens detached data files with fopen, so a FIFO
 * blocks forever, "-" reads standard input and /dev/zero never ends; and it leaks inside libbz2
 * (3.6 MB) and its gzip reader when a stream is corrupt. cdvr_nrrd_check runs before nrrdLoad:
 *
 *  1. The header is read here, from a regular file (at most CDVR_NRRD_HEADER_MAX bytes), and
 *     parsed by teem from that text (nrrdStringRead, skipData) with the "data file" field taken
 *     out, so teem opens nothing. The data files are resolved here as teem does
 *     (nrrdIoStateDataFileIterNext): a single name, "LIST" (the remaining lines), or
 *     "FORMAT min max step [subdim]" (FORMAT with exactly one %d-like conversion); names not
 *     starting with '/' are relative to the header's directory.
 *  2. Every data file must be a regular file other than the header itself ("-", standard input,
 *     is refused).
 *  3. Each file's data must be able to hold its share of what the header claims
 *     (elements x element size / number of files), before anything is allocated:
 *       raw    bytes after the header (attached data) and byte skip >= claimed bytes
 *       ascii  at least one byte per value;  hex: two bytes per data byte
 *       zrl    at most 256 data bytes per stored byte
 *       gzip   at most 1032 bytes per stored byte (deflate's largest ratio), then the stream
 *              is inflated once (nothing kept) until it has produced byte skip + claimed bytes
 *       bzip2  the stream is decompressed once the same way (bzip2's ratio has no useful bound)
 *     A gzip or bzip2 stream that is corrupt or ends early is refused here, so teem never reads
 *     one (and never leaks on one). The price is one extra decompression pass for compressed
 *     NRRDs; raw ones (the common case) cost a stat.
 * The file can still change between this check and nrrdLoad; this guards against mistakes and
 * broken files, not against a concurrent attacker.
 */
#include "cdvr/regular_file.h"
#include "cdvr/volume.h"
#include "volume_io.h"

#include <bzlib.h>
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <teem/nrrd.h>
#include <unistd.h>
#include <zlib.h>

#define CDVR_NRRD_HEADER_MAX (4u << 20) /* header bytes (with a LIST of data files) */
#define CDVR_NRRD_FILES_MAX 1000000     /* detached data files */
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
    if (name[0] == '/' || (len > 1 && name[1] == ':') || !slash)
        n = snprintf(out, size, "%.*s", (int)len, name);
    else
        n = snprintf(out, size, "%.*s/%.*s", (int)(slash - header), header, (int)len, name);
    return n > 0 && (size_t)n < size;
}

/* ---- the checks per data file ----------------------------------------------------------- */

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

typedef struct stream_result {
    uint64_t produced;
    const char *error;             /* the library's reason, or NULL */
} stream_result;

/* Inflates gzip (or zlib) data from f until `want` bytes came out, the data end or fail;
 * concatenated gzip members continue, as teem's reader does. */
static void inflate_count(FILE *f, uint64_t want, unsigned char *in, unsigned char *out, stream_result *r)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    if (inflateInit2(&z, 15 + 32) != Z_OK) {
        r->error = "zlib cannot start";
        return;
    }
    int eof = 0;
    while (r->produced < want) {
        if (z.avail_in == 0 && !eof) {
            z.avail_in = (uInt)fread(in, 1, STREAM_BUF, f);
            z.next_in = in;
            eof = z.avail_in == 0;
        }
        z.next_out = out;
        z.avail_out = STREAM_BUF;
        int rc = inflate(&z, Z_NO_FLUSH);
        r->produced += STREAM_BUF - z.avail_out;
        if (rc == Z_STREAM_END) {  /* end of a gzip member: another may follow */
            if (z.avail_in == 0 && !eof) {
                z.avail_in = (uInt)fread(in, 1, STREAM_BUF, f);
                z.next_in = in;
            }
            if (z.avail_in == 0)
                break;
            inflateReset(&z);
        } else if (rc == Z_BUF_ERROR && eof) {
            break;                 /* the data end in the middle of the stream */
        } else if (rc != Z_OK && rc != Z_BUF_ERROR) {
            r->error = z.msg ? z.msg : "corrupt data";
            break;
        }
    }
    inflateEnd(&z);
}

/* Decompresses bzip2 data from f until `want` bytes came out, the stream ends or fails. */
static void bunzip_count(FILE *f, uint64_t want, unsigned char *in, unsigned char *out, stream_result *r)
{
    bz_stream b;
    memset(&b, 0, sizeof b);
    if (BZ2_bzDecompressInit(&b, 0, 0) != BZ_OK) {
        r->error = "libbz2 cannot start";
        return;
    }
    int eof = 0;
    while (r->produced < want) {
        if (b.avail_in == 0 && !eof) {
            b.avail_in = (unsigned)fread(in, 1, STREAM_BUF, f);
            b.next_in = (char *)in;
            eof = b.avail_in == 0;
        }
        b.next_out = (char *)out;
        b.avail_out = STREAM_BUF;
        int rc = BZ2_bzDecompress(&b);
        r->produced += STREAM_BUF - b.avail_out;
        if (rc == BZ_STREAM_END)
            break;
        if (rc != BZ_OK) {
            r->error = rc == BZ_DATA_ERROR_MAGIC ? "not bzip2 data" : rc == BZ_MEM_ERROR ? "out of memory" : "corrupt data";
            break;
        }
        if (eof && b.avail_out == STREAM_BUF)
            break;                 /* no input left and nothing came out: the data end */
    }
    BZ2_bzDecompressEnd(&b);
}

/* Decompresses once, keeping nothing: the stream must produce `want` bytes without error. */
static cdvr_status check_stream(const char *path, const char *file, uint64_t offset, const nrrd_shape *s,
                                uint64_t want, cdvr_error *err)
{
    int bzip = s->encoding == nrrdEncodingBzip2;
    const char *kind = bzip ? "bzip2" : "gzip";
    FILE *f;
    cdvr_status st = cdvr_fopen_regular_file(file, &f, NULL, err);
    if (st != CDVR_OK)
        return st;
    unsigned char *buf = malloc(2 * STREAM_BUF);
    if (!buf) {
        fclose(f);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    stream_result r = {0, NULL};
    int skipped = fseeko(f, (off_t)offset, SEEK_SET) == 0 && skip_lines(f, s->line_skip);
    if (skipped && bzip)
        bunzip_count(f, want, buf, buf + STREAM_BUF, &r);
    else if (skipped)
        inflate_count(f, want, buf, buf + STREAM_BUF, &r);
    free(buf);
    fclose(f);
    if (!skipped)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s ends before the %u lines to skip", path, file,
                              s->line_skip);
    if (r.error)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: corrupt %s data in %s: %s", path, kind, file, r.error);
    if (r.produced < want)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD header claims %llu bytes of data (%s), but the %s data in %s end after %llu bytes",
                              path, (unsigned long long)want, s->what, kind, file, (unsigned long long)r.produced);
    return CDVR_OK;
}

/* Checks data file `file` (its share: `want` bytes) holding data from `offset` on. */
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
    if (s->encoding != nrrdEncodingBzip2 && have < need)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD header claims %llu bytes of data (%s, %s encoding), but %s holds only %llu "
                              "bytes after the header and skips%s",
                              path, (unsigned long long)need, s->what, s->encoding->name, file, (unsigned long long)avail,
                              s->encoding == nrrdEncodingGzip ? " (gzip expands at most 1032 times)" : "");
    if (compressed)
        return check_stream(path, file, offset, s, need, err);
    return CDVR_OK;
}

/* Checks every data file named by the header. */
static cdvr_status check_data_files(const char *path, const nrrd_header *h, const nrrd_shape *s, cdvr_error *err)
{
    char file[PATH_MAX];
    if (!h->data_file) /* attached */
        return check_data_file(path, h, path, 1, s, s->bytes, err);
    const char *v = h->data_file;
    if (h->list) {
        size_t count = 0;
        for (const char *p = h->list; p < h->text + h->len; p += strlen(p) + 1)
            count += strlen(p) > 0;
        if (count == 0 || count > CDVR_NRRD_FILES_MAX)
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file LIST names %zu files", path, count);
        for (const char *p = h->list; p < h->text + h->len; p += strlen(p) + 1) {
            size_t len = strlen(p);
            if (len == 0)
                continue;
            if (!data_path(path, p, len, file, sizeof file))
                return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file name too long", path);
            cdvr_status st = check_data_file(path, h, file, 0, s, s->bytes / count, err);
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
        return check_data_file(path, h, file, 0, s, s->bytes, err);
    }
    size_t flen = strcspn(v, " \t");
    const char *pct = memchr(v, '%', flen);
    const char *conv = pct ? pct + 1 + strspn(pct + 1, "0123456789") : NULL;
    long lo, hi, step;
    if (!pct || *conv != 'd' || memchr(conv, '%', flen - (size_t)(conv - v)) || conv - pct - 1 > 3 ||
        sscanf(v + flen, "%ld %ld %ld", &lo, &hi, &step) != 3 || step == 0 || (hi - lo) / step < 0)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD data file '%s': expected FORMAT min max step with one %%d-like conversion",
                              path, v);
    uint64_t count = (uint64_t)((hi - lo) / step) + 1;
    if (count > CDVR_NRRD_FILES_MAX)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file pattern names %llu files", path,
                              (unsigned long long)count);
    for (uint64_t i = 0; i < count; i++) {
        char name[PATH_MAX];
        if (!format_name(v, flen, lo + (long)i * step, name, sizeof name) ||
            !data_path(path, name, strlen(name), file, sizeof file))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data file name too long", path);
        cdvr_status st = check_data_file(path, h, file, 0, s, s->bytes / count, err);
        if (st != CDVR_OK)
            return st;
    }
    return CDVR_OK;
}

cdvr_status cdvr_nrrd_check_header(const char *path, cdvr_error *err)
{
    nrrd_header h;
    memset(&h, 0, sizeof h);
    FILE *f;
    cdvr_status st = cdvr_fopen_regular_file(path, &f, &h.sb, err);
    if (st != CDVR_OK)
        return st;
    st = read_header(path, f, &h, err);
    fclose(f);
    free(h.data_file);
    free(h.text);
    return st;
}

cdvr_status cdvr_nrrd_check(const char *path, cdvr_error *err)
{
    nrrd_header h;
    memset(&h, 0, sizeof h);
    FILE *f;
    cdvr_status st = cdvr_fopen_regular_file(path, &f, &h.sb, err);
    if (st != CDVR_OK)
        return st;
    st = read_header(path, f, &h, err);
    fclose(f);
    char *text = st == CDVR_OK ? header_for_teem(&h) : NULL;
    if (st == CDVR_OK && !text)
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    Nrrd *nrrd = st == CDVR_OK ? nrrdNew() : NULL;
    NrrdIoState *nio = st == CDVR_OK ? nrrdIoStateNew() : NULL;
    if (st == CDVR_OK && (!nrrd || !nio))
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (st == CDVR_OK) {
        nio->skipData = 1;
        if (nrrdStringRead(nrrd, text, nio))
            st = teem_error(path, "cannot read NRRD header", err);
    }
    nrrd_shape shape;
    if (st == CDVR_OK)
        st = shape_of(path, nrrd, nio, &shape, err);
    if (st == CDVR_OK)
        st = check_data_files(path, &h, &shape, err);
    if (nio) /* teem's Nix functions dereference their argument */
        nrrdIoStateNix(nio);
    if (nrrd)
        nrrdNuke(nrrd);
    free(text);
    free(h.data_file);
    free(h.text);
    return st;
}
