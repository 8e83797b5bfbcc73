/* core/io/io_vti.c - VTK XML ImageData (.vti) through expat (cdvr/vti.h, format "vti").
 *
 * File layout (VTK's XML formats, "ImageData"):
 *   <VTKFile type="ImageData" version="0.1|1.0|2.x" byte_order="LittleEndian|BigEndian"
 *            header_type="UInt32|UInt64" compressor="vtkZLibDataCompressor|vtkLZ4DataCompressor">
 *     <ImageData WholeExtent="x0 x1 y0 y1 z0 z1" Origin="3" Spacing="3" Direction="9, row-major">
 *       <Piece Extent="= WholeExtent">            (one piece)
 *         <PointData Scalars="active name">
 *           <DataArray type="Float32" Name="..." NumberOfComponents="1"
 *                      format="ascii|binary|appended" offset="bytes after '_'"> inline data
 *     <AppendedData encoding="raw|base64"> _ then each appended array at its offset
 * A binary block (inline: base64 text; appended raw: bytes; appended base64: text) is
 *   uncompressed:  [H: byte count][data]                       (one base64 stream)
 *   compressed:    [H: blocks n][H: block size][H: last block size, 0 = full][H x n: sizes]
 *                  then n compressed blocks (inline: the header and the blocks are two streams)
 * with H the header type (UInt32 when the file has no header_type). Expat parses the XML up to
 * the chosen DataArray (probe) or up to <AppendedData> (whose content is not XML); every size
 * a header claims is checked against the bytes the file holds before anything is allocated. */
#include "cdvr/format.h"
#include "cdvr/vti.h"
#include "io_common.h"
#include "volume_io.h"

#include <expat.h>
#include <lz4.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

enum { FMT_ASCII, FMT_BINARY, FMT_APPENDED };
enum { COMP_NONE, COMP_ZLIB, COMP_LZ4 };

typedef struct vti_parse {
    const char *path, *want; /* want: the array asked for, or NULL */
    const cdvr_raw_opts *opts; /* the load options (the f32 rule), or NULL */
    int probe;               /* stop at the chosen DataArray */
    cdvr_error *err;
    cdvr_status st;
    XML_Parser xp;
    /* VTKFile */
    int seen_file, big_endian, header64, compressor;
    /* ImageData and Piece */
    int seen_image, pieces;
    long long ext[6];
    double origin[3], spacing[3], dir[9];
    int have_window;  /* CdvrValueWindow="lo hi" (cdvr's attribute: a u8 volume's window) */
    double window[2];
    /* PointData and the chosen DataArray */
    int in_point, in_chosen, found, first_taken;
    char scalars[128];
    char names[256]; /* the point-data arrays seen, for the "no such array" message */
    char name[128];
    cdvr_io_etype type;
    int format;
    unsigned long long offset;
    /* inline text of the chosen array (load) */
    uint8_t *text;
    size_t text_n, text_cap;
    /* AppendedData */
    int appended, appended_base64;
    size_t appended_at; /* byte after '_' */
    const cdvr_io_map *map;
} vti_parse;

static const char *attr(const XML_Char **a, const char *name)
{
    for (size_t i = 0; a[i]; i += 2)
        if (strcmp(a[i], name) == 0)
            return a[i + 1];
    return NULL;
}

static void fail(vti_parse *v, cdvr_status st, const char *fmt, const char *x1, const char *x2)
{
    if (v->st == CDVR_OK) {
        char msg[CDVR_ERRMSG_MAX];
        snprintf(msg, sizeof msg, fmt, x1 ? x1 : "", x2 ? x2 : "");
        v->st = cdvr_error_set(v->err, st, "%s: %s", v->path, msg);
    }
    XML_StopParser(v->xp, XML_FALSE);
}

static int parse_type(const char *s, cdvr_io_etype *t)
{
    static const char *const names[][2] = {
        {"Int8", "Char"}, {"UInt8", "UnsignedChar"}, {"Int16", "Short"},
        {"UInt16", "UnsignedShort"}, {"Int32", "Int"}, {"UInt32", "UnsignedInt"},
        {"Int64", "Long"}, {"UInt64", "UnsignedLong"}, {"Float32", "Float"},
        {"Float64", "Double"}};
    for (int i = 0; s && i < CDVR_IO_ETYPES; i++)
        if (strcmp(s, names[i][0]) == 0 || strcmp(s, names[i][1]) == 0) {
            *t = (cdvr_io_etype)i;
            return 1;
        }
    return 0;
}

static void start_file(vti_parse *v, const XML_Char **a)
{
    const char *type = attr(a, "type"), *order = attr(a, "byte_order");
    const char *header = attr(a, "header_type"), *comp = attr(a, "compressor");
    v->seen_file = 1;
    if (!type || strcmp(type, "ImageData") != 0)
        return fail(v, CDVR_ERR_FORMAT, "VTKFile type '%s' is not ImageData (cdvr reads image "
                    "data)", type ? type : "(none)", NULL);
    v->big_endian = order && strcmp(order, "BigEndian") == 0;
    if (order && !v->big_endian && strcmp(order, "LittleEndian") != 0)
        return fail(v, CDVR_ERR_FORMAT, "byte_order '%s' is not LittleEndian or BigEndian",
                    order, NULL);
    if (header && strcmp(header, "UInt64") == 0)
        v->header64 = 1;
    else if (header && strcmp(header, "UInt32") != 0)
        return fail(v, CDVR_ERR_FORMAT, "header_type '%s' is not UInt32 or UInt64", header,
                    NULL);
    if (!comp || !*comp)
        v->compressor = COMP_NONE;
    else if (strcmp(comp, "vtkZLibDataCompressor") == 0)
        v->compressor = COMP_ZLIB;
    else if (strcmp(comp, "vtkLZ4DataCompressor") == 0)
        v->compressor = COMP_LZ4;
    else
        fail(v, CDVR_ERR_UNSUPPORTED, "compressor '%s' is not supported (zlib and LZ4 are)",
             comp, NULL);
}

static void start_image(vti_parse *v, const XML_Char **a)
{
    const char *ext = attr(a, "WholeExtent"), *o = attr(a, "Origin"), *s = attr(a, "Spacing");
    const char *d = attr(a, "Direction");
    double e[6];
    v->seen_image = 1;
    if (!ext || !cdvr_io_parse_doubles(ext, e, 6))
        return fail(v, CDVR_ERR_FORMAT, "ImageData WholeExtent '%s' is not 6 numbers",
                    ext ? ext : "(none)", NULL);
    for (int i = 0; i < 6; i++) {
        if (e[i] != floor(e[i]) || fabs(e[i]) > 1e15)
            return fail(v, CDVR_ERR_FORMAT, "ImageData WholeExtent '%s' is not integers", ext,
                        NULL);
        v->ext[i] = (long long)e[i];
    }
    for (int i = 0; i < 3; i++)
        if (v->ext[2 * i + 1] < v->ext[2 * i])
            return fail(v, CDVR_ERR_FORMAT, "ImageData WholeExtent '%s' is empty", ext, NULL);
    if (o && !cdvr_io_parse_doubles(o, v->origin, 3))
        return fail(v, CDVR_ERR_FORMAT, "ImageData Origin '%s' is not 3 finite numbers", o, NULL);
    if (s && !cdvr_io_parse_doubles(s, v->spacing, 3))
        return fail(v, CDVR_ERR_FORMAT, "ImageData Spacing '%s' is not 3 finite numbers", s,
                    NULL);
    for (int i = 0; i < 3; i++)
        if (!(v->spacing[i] > 0))
            return fail(v, CDVR_ERR_FORMAT, "ImageData Spacing '%s' is not positive", s, NULL);
    if (d && !cdvr_io_parse_doubles(d, v->dir, 9))
        return fail(v, CDVR_ERR_FORMAT, "ImageData Direction '%s' is not 9 finite numbers", d,
                    NULL);
    const char *w = attr(a, "CdvrValueWindow");
    if (w && !cdvr_io_parse_doubles(w, v->window, 2))
        return fail(v, CDVR_ERR_FORMAT, "ImageData CdvrValueWindow '%s' is not 2 finite numbers",
                    w, NULL);
    v->have_window = w != NULL;
}

static void start_piece(vti_parse *v, const XML_Char **a)
{
    const char *ext = attr(a, "Extent");
    double e[6];
    if (++v->pieces > 1)
        return fail(v, CDVR_ERR_UNSUPPORTED, "ImageData has several Pieces (cdvr reads one)",
                    NULL, NULL);
    if (!v->seen_image || !ext || !cdvr_io_parse_doubles(ext, e, 6))
        return fail(v, CDVR_ERR_FORMAT, "Piece Extent '%s' is not 6 numbers",
                    ext ? ext : "(none)", NULL);
    for (int i = 0; i < 6; i++)
        if (e[i] != (double)v->ext[i])
            return fail(v, CDVR_ERR_UNSUPPORTED, "Piece Extent '%s' is not the WholeExtent "
                        "(cdvr reads a whole image in one piece)", ext, NULL);
}

static void start_array(vti_parse *v, const XML_Char **a)
{
    const char *name = attr(a, "Name"), *type = attr(a, "type"), *fmt = attr(a, "format");
    const char *comps = attr(a, "NumberOfComponents"), *off = attr(a, "offset");
    name = name ? name : "";
    size_t used = strlen(v->names);
    if (used + strlen(name) + 4 < sizeof v->names)
        snprintf(v->names + used, sizeof v->names - used, "%s'%s'", used ? ", " : "", name);
    const char *chosen = v->want ? v->want : v->scalars[0] ? v->scalars : NULL;
    if (v->found || (chosen ? strcmp(name, chosen) != 0 : v->first_taken)) {
        v->first_taken = 1;
        return;
    }
    v->first_taken = v->found = 1;
    snprintf(v->name, sizeof v->name, "%s", name);
    if (!parse_type(type, &v->type))
        return fail(v, CDVR_ERR_UNSUPPORTED, "DataArray '%s': type '%s' is not a scalar type",
                    name, type ? type : "(none)");
    if (comps && strcmp(comps, "1") != 0)
        return fail(v, CDVR_ERR_UNSUPPORTED, "DataArray '%s' has %s components (cdvr reads "
                    "scalars)", name, comps);
    if (fmt && strcmp(fmt, "ascii") == 0)
        v->format = FMT_ASCII;
    else if (fmt && strcmp(fmt, "binary") == 0)
        v->format = FMT_BINARY;
    else if (fmt && strcmp(fmt, "appended") == 0) {
        v->format = FMT_APPENDED;
        char *end;
        v->offset = off ? strtoull(off, &end, 10) : 0;
        if (!off || end == off || *end || off[0] == '-')
            return fail(v, CDVR_ERR_FORMAT, "DataArray '%s': offset '%s' is not a byte count",
                        name, off ? off : "(none)");
    } else
        return fail(v, CDVR_ERR_FORMAT, "DataArray '%s': format '%s' is not ascii, binary or "
                    "appended", name, fmt ? fmt : "(none)");
    if (v->probe)
        XML_StopParser(v->xp, XML_FALSE); /* all the header is known */
    else if (v->format != FMT_APPENDED)
        v->in_chosen = 1;
}

static void start_appended(vti_parse *v, const XML_Char **a)
{
    const char *enc = attr(a, "encoding");
    v->appended = 1;
    v->appended_base64 = enc && strcmp(enc, "base64") == 0;
    if (!v->appended_base64 && (!enc || strcmp(enc, "raw") != 0))
        return fail(v, CDVR_ERR_FORMAT, "AppendedData encoding '%s' is not raw or base64",
                    enc ? enc : "(none)", NULL);
    size_t at = (size_t)(XML_GetCurrentByteIndex(v->xp) + XML_GetCurrentByteCount(v->xp));
    while (at < v->map->n && (v->map->p[at] == ' ' || v->map->p[at] == '\n' ||
                              v->map->p[at] == '\r' || v->map->p[at] == '\t'))
        at++;
    if (at >= v->map->n || v->map->p[at] != '_')
        return fail(v, CDVR_ERR_FORMAT, "AppendedData does not start with '_'", NULL, NULL);
    v->appended_at = at + 1;
    XML_StopParser(v->xp, XML_FALSE); /* what follows is not XML */
}

static void XMLCALL on_start(void *ud, const XML_Char *el, const XML_Char **a)
{
    vti_parse *v = ud;
    if (strcmp(el, "VTKFile") == 0)
        start_file(v, a);
    else if (!v->seen_file)
        fail(v, CDVR_ERR_FORMAT, "not a VTK XML file (first element <%s>)", el, NULL);
    else if (strcmp(el, "ImageData") == 0)
        start_image(v, a);
    else if (strcmp(el, "Piece") == 0)
        start_piece(v, a);
    else if (strcmp(el, "PointData") == 0) {
        const char *s = attr(a, "Scalars");
        v->in_point = 1;
        snprintf(v->scalars, sizeof v->scalars, "%s", s ? s : "");
    } else if (strcmp(el, "DataArray") == 0 && v->in_point)
        start_array(v, a);
    else if (strcmp(el, "AppendedData") == 0)
        start_appended(v, a);
}

static void XMLCALL on_end(void *ud, const XML_Char *el)
{
    vti_parse *v = ud;
    if (strcmp(el, "PointData") == 0)
        v->in_point = 0;
    else if (strcmp(el, "DataArray") == 0 && v->in_chosen) {
        v->in_chosen = 0;
        XML_StopParser(v->xp, XML_FALSE); /* the inline data is in hand */
    }
}

static void XMLCALL on_text(void *ud, const XML_Char *s, int len)
{
    vti_parse *v = ud;
    if (!v->in_chosen || len <= 0)
        return;
    if (v->text_n + (size_t)len > v->text_cap) {
        size_t cap = 2 * (v->text_n + (size_t)len) + 256;
        uint8_t *p = realloc(v->text, cap);
        if (!p)
            return fail(v, CDVR_ERR_NOMEM, "out of memory for the inline data%s%s", NULL, NULL);
        v->text = p;
        v->text_cap = cap;
    }
    memcpy(v->text + v->text_n, s, (size_t)len);
    v->text_n += (size_t)len;
}

static void XMLCALL on_doctype(void *ud, const XML_Char *name, const XML_Char *sys,
                               const XML_Char *pub, int internal)
{
    (void)name, (void)sys, (void)pub, (void)internal;
    fail(ud, CDVR_ERR_FORMAT, "a DOCTYPE is not allowed in a VTK file%s%s", NULL, NULL);
}

/* Parses the header (and for a load the chosen array's inline text or the appended start). */
static cdvr_status vti_header(vti_parse *v, const cdvr_io_map *map)
{
    v->spacing[0] = v->spacing[1] = v->spacing[2] = 1;
    v->dir[0] = v->dir[4] = v->dir[8] = 1;
    v->map = map;
    v->xp = XML_ParserCreate(NULL);
    if (!v->xp)
        return cdvr_error_set(v->err, CDVR_ERR_NOMEM, "%s: cannot create an XML parser", v->path);
    XML_SetUserData(v->xp, v);
    XML_SetElementHandler(v->xp, on_start, on_end);
    XML_SetCharacterDataHandler(v->xp, on_text);
    XML_SetStartDoctypeDeclHandler(v->xp, on_doctype);
    const size_t CHUNK = (size_t)1 << 16; /* expat copies what a stopped parse left of its buffer */
    size_t done = 0;
    enum XML_Status xs = XML_STATUS_OK;
    do {
        size_t n = map->n - done < CHUNK ? map->n - done : CHUNK;
        xs = XML_Parse(v->xp, map->p ? (const char *)map->p + done : "", (int)n,
                       done + n == map->n);
        done += n;
    } while (xs == XML_STATUS_OK && done < map->n);
    if (xs == XML_STATUS_ERROR && v->st == CDVR_OK && XML_GetErrorCode(v->xp) != XML_ERROR_ABORTED)
        v->st = cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: XML error at line %lu: %s", v->path,
                               (unsigned long)XML_GetCurrentLineNumber(v->xp),
                               XML_ErrorString(XML_GetErrorCode(v->xp)));
    XML_ParserFree(v->xp);
    v->xp = NULL;
    if (v->st != CDVR_OK)
        return v->st;
    if (!v->seen_image)
        return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: no <ImageData> element", v->path);
    if (!v->found)
        return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: no point-data array %s%s%s (arrays: "
                              "%s)", v->path, v->want || v->scalars[0] ? "named '" : "",
                              v->want ? v->want : v->scalars, v->want || v->scalars[0] ? "'" : "",
                              v->names[0] ? v->names : "none");
    if (!v->probe && v->format == FMT_APPENDED && !v->appended)
        return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: DataArray '%s' is appended but the "
                              "file has no <AppendedData>", v->path, v->name);
    return CDVR_OK;
}

/* Dims and geometry into head. */
static cdvr_status vti_geometry(const vti_parse *v, cdvr_volume *head, cdvr_error *err)
{
    for (int i = 0; i < 3; i++) {
        head->dims[i] = (size_t)(v->ext[2 * i + 1] - v->ext[2 * i] + 1);
        head->spacing[i] = v->spacing[i];
    }
    head->timesteps = 1;
    cdvr_io_set_type(head, v->type);
    if (head->type == CDVR_TYPE_U8) {
        head->window[0] = 0;
        head->window[1] = 255;
        if (v->have_window)
            cdvr_u8_window_set(head, v->window[0], v->window[1]);
    }
    double start[3];
    for (int c = 0; c < 3; c++)
        start[c] = (double)v->ext[2 * c] * v->spacing[c];
    for (int r = 0; r < 3; r++)
        head->origin[r] = v->origin[r] + v->dir[3 * r] * start[0] + v->dir[3 * r + 1] * start[1] +
                          v->dir[3 * r + 2] * start[2];
    size_t bytes;
    if (!cdvr_volume_bytes_for(head->dims, 1, CDVR_TYPE_F32, &bytes))
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: extent %zux%zux%zu overflows", v->path,
                              head->dims[0], head->dims[1], head->dims[2]);
    return cdvr_io_set_direction(v->path, "ImageData Direction", v->dir, head, err);
}

/* ---- binary blocks ----------------------------------------------------------------------- */

/* Sequential source of a block's bytes: raw bytes or base64 text. */
typedef struct src {
    const uint8_t *p;
    size_t n, pos;
    int base64;
} src;

/* Bytes the source can still give, at most. */
static size_t src_left(const src *s)
{
    return s->base64 ? cdvr_io_base64_bound(s->pos, s->n) : s->n - s->pos;
}

static int src_read(src *s, uint8_t *out, size_t k, int peek)
{
    if (s->base64) {
        size_t pos = s->pos;
        int ok = cdvr_io_base64(s->p, s->n, &pos, out, k);
        if (ok && !peek)
            s->pos = pos;
        return ok;
    }
    if (s->n - s->pos < k)
        return 0;
    memcpy(out, s->p + s->pos, k);
    s->pos += peek ? 0 : k;
    return 1;
}

static uint64_t header_word(const vti_parse *v, const uint8_t *b)
{
    int k = v->header64 ? 8 : 4;
    uint64_t x = 0;
    for (int i = 0; i < k; i++)
        x |= (uint64_t)b[v->big_endian ? k - 1 - i : i] << (8 * i);
    return x;
}

static cdvr_status block_error(const vti_parse *v, const char *what, unsigned long long claim,
                               unsigned long long have)
{
    return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: DataArray '%s': %s (%llu bytes; the file "
                          "holds %llu)", v->path, v->name, what, claim, have);
}

/* Uncompressed: [H count][data]; the data into buf (bytes long). */
static cdvr_status read_plain(const vti_parse *v, src *s, uint8_t *buf, size_t bytes)
{
    size_t h = v->header64 ? 8 : 4;
    uint8_t hb[8];
    if (!src_read(s, hb, h, 1))
        return block_error(v, "the block header is cut", h, src_left(s));
    uint64_t count = header_word(v, hb);
    if (count != bytes)
        return block_error(v, "the block's byte count is not the extent's", count, bytes);
    if (src_left(s) < h + bytes)
        return block_error(v, "the block is longer than the file", h + bytes, src_left(s));
    if (!s->base64)
        return s->pos += h, src_read(s, buf, bytes, 0), CDVR_OK;
    uint8_t *all = malloc(h + bytes);
    if (!all)
        return cdvr_error_set(v->err, CDVR_ERR_NOMEM, "%s: out of memory", v->path);
    int ok = src_read(s, all, h + bytes, 0);
    if (ok)
        memcpy(buf, all + h, bytes);
    free(all);
    return ok ? CDVR_OK : block_error(v, "the base64 data are cut or corrupt", h + bytes, 0);
}

static cdvr_status decompress(const vti_parse *v, const uint8_t *in, size_t n, uint8_t *out,
                              size_t out_n, size_t block)
{
    char what[192];
    snprintf(what, sizeof what, "DataArray '%s' block %zu", v->name, block);
    if (v->compressor == COMP_ZLIB)
        return cdvr_io_inflate(v->path, what, in, n, out, out_n, v->err);
    int got = n <= (size_t)INT32_MAX && out_n <= (size_t)INT32_MAX
                  ? LZ4_decompress_safe((const char *)in, (char *)out, (int)n, (int)out_n) : -1;
    if (got < 0 || (size_t)got != out_n)
        return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: %s: corrupt LZ4 data", v->path, what);
    return CDVR_OK;
}

/* Compressed: header words, then the blocks, each inflated into its place in buf. */
static cdvr_status read_compressed(const vti_parse *v, src *s, uint8_t *buf, size_t bytes)
{
    size_t h = v->header64 ? 8 : 4;
    uint8_t hb[24];
    if (!src_read(s, hb, 3 * h, 1))
        return block_error(v, "the compression header is cut", 3 * h, src_left(s));
    uint64_t nb = header_word(v, hb), bs = header_word(v, hb + h), last = header_word(v, hb + 2 * h);
    uint64_t total = nb == 0 ? 0 : (nb - 1) * bs + (last ? last : bs);
    if (nb == 0 || bs == 0 || last > bs || nb > bytes / bs + 1 || total != bytes)
        return block_error(v, "the compression header does not give the extent's size",
                           nb && bs && nb <= bytes / bs + 1 ? total : 0, bytes);
    size_t head_n = (size_t)(3 + nb) * h;
    if (src_left(s) < head_n)
        return block_error(v, "the compression header is longer than the file", head_n,
                           src_left(s));
    uint8_t *head = malloc(head_n);
    uint8_t *packed = NULL;
    cdvr_status st = CDVR_OK;
    if (!head || !src_read(s, head, head_n, 0))
        st = head ? block_error(v, "the compression header is corrupt", head_n, 0)
                  : cdvr_error_set(v->err, CDVR_ERR_NOMEM, "%s: out of memory", v->path);
    uint64_t sum = 0;
    for (size_t b = 0; st == CDVR_OK && b < nb; b++) {
        sum += header_word(v, head + (3 + b) * h);
        if (sum > src_left(s))
            st = block_error(v, "the compressed blocks are longer than the file", sum,
                             src_left(s));
    }
    if (st == CDVR_OK && !(packed = malloc(sum ? sum : 1)))
        st = cdvr_error_set(v->err, CDVR_ERR_NOMEM, "%s: out of memory", v->path);
    if (st == CDVR_OK && !src_read(s, packed, sum, 0))
        st = block_error(v, "the compressed blocks are cut or corrupt", sum, 0);
    size_t at = 0;
    for (size_t b = 0; st == CDVR_OK && b < nb; b++) {
        size_t cn = (size_t)header_word(v, head + (3 + b) * h);
        size_t un = b + 1 == nb && last ? (size_t)last : (size_t)bs;
        st = decompress(v, packed + at, cn, buf + b * bs, un, b);
        at += cn;
    }
    free(packed);
    free(head);
    return st;
}

/* Before allocating: the bytes the file holds for the chosen array bound what its extent may
 * claim (ASCII: two bytes a value; raw: the exact size; compressed: zlib's largest ratio). */
static cdvr_status vti_size_check(const vti_parse *v, const cdvr_io_map *map, const cdvr_volume *head)
{
    size_t count = head->dims[0] * head->dims[1] * head->dims[2]; /* checked by vti_geometry */
    size_t bytes = count * cdvr_io_etype_size(v->type), avail, need = bytes;
    if (v->format == FMT_ASCII) {
        avail = v->text_n;
        need = count > avail / 2 + 1 ? SIZE_MAX : 0;
    } else {
        size_t at = v->format == FMT_APPENDED ? v->appended_at : 0;
        if (v->format == FMT_APPENDED && v->offset > map->n - at)
            return block_error(v, "the appended offset is past the end of the file", v->offset,
                               map->n - at);
        at += v->format == FMT_APPENDED ? (size_t)v->offset : 0;
        int text = v->format == FMT_BINARY || v->appended_base64;
        avail = v->format == FMT_BINARY ? cdvr_io_base64_bound(0, v->text_n)
                : text ? cdvr_io_base64_bound(at, map->n) : map->n - at;
        if (v->compressor != COMP_NONE)
            need = bytes / 1032;
    }
    if (need > avail)
        return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: DataArray '%s': the extent's %zu "
                              "values (%zu bytes) cannot be in the %zu bytes the file holds for "
                              "them", v->path, v->name, count, bytes, avail);
    return CDVR_OK;
}

/* The chosen array's voxels into vol. */
static cdvr_status vti_voxels(const vti_parse *v, const cdvr_io_map *map, cdvr_volume *vol)
{
    size_t count = cdvr_volume_voxels(vol), esize = cdvr_io_etype_size(v->type);
    cdvr_io_range range;
    cdvr_io_range_init(&range, v->opts);
    if (v->format == FMT_ASCII) {
        size_t pos = 0;
        double x;
        for (size_t i = 0; i < count; i++) {
            if (!cdvr_io_ascii_number(v->text, v->text_n, &pos, &x))
                return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: DataArray '%s': ASCII value "
                                      "%zu of %zu is missing or not a number", v->path, v->name,
                                      i, count);
            cdvr_io_store_double(vol, i, x, &range);
        }
        if (cdvr_io_ascii_number(v->text, v->text_n, &pos, &x))
            return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: DataArray '%s' holds more than "
                                  "the extent's %zu values", v->path, v->name, count);
        return cdvr_io_finish(vol, v->type, &range, v->path, "VTK", v->err);
    }
    src s = {v->text, v->text_n, 0, 1};
    if (v->format == FMT_APPENDED) {
        if (v->offset > map->n - v->appended_at)
            return block_error(v, "the appended offset is past the end of the file", v->offset,
                               map->n - v->appended_at);
        s = (src){map->p, map->n, v->appended_at + (size_t)v->offset, v->appended_base64};
    }
    size_t bytes = count * esize; /* checked by vti_geometry (count * 8 fits) */
    if (!s.base64 && v->compressor == COMP_NONE) { /* straight from the mapping: one copy */
        size_t h = v->header64 ? 8 : 4;
        uint8_t hb[8];
        if (!src_read(&s, hb, h, 0))
            return block_error(v, "the block header is cut", h, src_left(&s));
        if (header_word(v, hb) != bytes)
            return block_error(v, "the block's byte count is not the extent's", header_word(v, hb),
                               bytes);
        if (src_left(&s) < bytes)
            return block_error(v, "the block is longer than the file", bytes, src_left(&s));
        cdvr_io_store(vol, 0, s.p + s.pos, v->type, v->big_endian, count, &range);
        return cdvr_io_finish(vol, v->type, &range, v->path, "VTK", v->err);
    }
    uint8_t *buf = malloc(bytes);
    if (!buf)
        return cdvr_error_set(v->err, CDVR_ERR_NOMEM, "%s: out of memory", v->path);
    cdvr_status st = v->compressor == COMP_NONE ? read_plain(v, &s, buf, bytes)
                                                : read_compressed(v, &s, buf, bytes);
    if (st == CDVR_OK) {
        cdvr_io_store(vol, 0, buf, v->type, v->big_endian, count, &range);
        st = cdvr_io_finish(vol, v->type, &range, v->path, "VTK", v->err);
    }
    free(buf);
    return st;
}

static void fill_info(const vti_parse *v, cdvr_vti_info *info)
{
    if (!info)
        return;
    snprintf(info->array, sizeof info->array, "%s", v->name);
    snprintf(info->file_type, sizeof info->file_type, "%s", cdvr_io_etype_name(v->type));
    info->converted = cdvr_io_etype_converted(v->type);
}

static void preset(cdvr_volume *head)
{
    memset(head->dims, 0, sizeof head->dims);
    head->timesteps = 0;
    for (int i = 0; i < 3; i++) {
        head->spacing[i] = 1;
        head->origin[i] = 0;
    }
    memset(head->direction, 0, sizeof head->direction);
    head->direction[0] = head->direction[4] = head->direction[8] = 1;
}

static cdvr_status vti_probe_file(const char *path, const char *array, cdvr_volume *head,
                                  cdvr_vti_info *info, cdvr_error *err)
{
    cdvr_io_map map;
    cdvr_status st = cdvr_io_map_open(path, &map, err);
    if (st != CDVR_OK)
        return st;
    vti_parse v = {.path = path, .want = array, .probe = 1, .err = err};
    st = vti_header(&v, &map);
    if (st == CDVR_OK)
        st = vti_geometry(&v, head, err);
    if (st == CDVR_OK)
        fill_info(&v, info);
    free(v.text);
    cdvr_io_map_close(&map);
    return st;
}

static cdvr_status vti_load_file(const char *path, const char *array, const cdvr_raw_opts *opts,
                                 cdvr_volume **out, cdvr_vti_info *info, cdvr_error *err)
{
    *out = NULL;
    cdvr_io_map map;
    cdvr_status st = cdvr_io_map_open(path, &map, err);
    if (st != CDVR_OK)
        return st;
    vti_parse v = {.path = path, .want = array, .opts = opts, .err = err};
    cdvr_volume head, *vol = NULL;
    preset(&head);
    st = vti_header(&v, &map);
    if (st == CDVR_OK)
        st = vti_geometry(&v, &head, err);
    if (st == CDVR_OK)
        st = vti_size_check(&v, &map, &head);
    if (st == CDVR_OK)
        st = cdvr_volume_create(head.dims, 1, head.type, &vol, err);
    if (st == CDVR_OK) {
        memcpy(vol->spacing, head.spacing, sizeof head.spacing);
        memcpy(vol->origin, head.origin, sizeof head.origin);
        memcpy(vol->direction, head.direction, sizeof head.direction);
        if (vol->type == CDVR_TYPE_U8)
            memcpy(vol->window, head.window, sizeof head.window);
        st = vti_voxels(&v, &map, vol);
    }
    if (st == CDVR_OK) {
        fill_info(&v, info);
        *out = vol;
    } else
        cdvr_volume_free(vol);
    free(v.text);
    cdvr_io_map_close(&map);
    return st;
}

/* ---- public calls and the format table --------------------------------------------------- */

static int is_vti(const char *path)
{
    size_t n = strlen(path);
    return n >= 4 && strcasecmp(path + n - 4, ".vti") == 0;
}

cdvr_status cdvr_vtk_legacy_probe(const char *path, const char *array, cdvr_volume *head,
                                  cdvr_vti_info *info, cdvr_error *err);
cdvr_status cdvr_vtk_legacy_load(const char *path, const char *array, const cdvr_raw_opts *opts,
                                 cdvr_volume **out, cdvr_vti_info *info, cdvr_error *err);

cdvr_status cdvr_vti_probe(const char *path, const char *array, cdvr_volume *head,
                           cdvr_vti_info *info, cdvr_error *err)
{
    preset(head);
    return is_vti(path) ? vti_probe_file(path, array, head, info, err)
                        : cdvr_vtk_legacy_probe(path, array, head, info, err);
}

cdvr_status cdvr_vti_load(const char *path, const char *array, cdvr_volume **out,
                          cdvr_vti_info *info, cdvr_error *err)
{
    return is_vti(path) ? vti_load_file(path, array, NULL, out, info, err)
                        : cdvr_vtk_legacy_load(path, array, NULL, out, info, err);
}

/* The array the load option select= names (cdvr_raw_opts.select), or NULL: the default. */
static const char *selected_array(const cdvr_raw_opts *opts)
{
    return opts && opts->select && opts->select[0] ? opts->select : NULL;
}

/* "<?xml" or "<VTKFile" and, within the first bytes, type="ImageData". */
static int vti_magic(const uint8_t *head, size_t n)
{
    static const char key[] = "<VTKFile";
    static const char type[] = "type=\"ImageData\"";
    int at = -1;
    for (size_t i = 0; at < 0 && i + sizeof key - 1 <= n; i++)
        if (memcmp(head + i, key, sizeof key - 1) == 0)
            at = (int)i;
    for (size_t i = at < 0 ? n : (size_t)at; i + sizeof type - 1 <= n; i++)
        if (memcmp(head + i, type, sizeof type - 1) == 0)
            return 1;
    return 0;
}

static cdvr_status vti_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                             cdvr_error *err)
{
    return vti_probe_file(path, selected_array(opts), head, NULL, err);
}

static cdvr_status vti_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                            cdvr_error *err)
{
    return vti_load_file(path, selected_array(opts), opts, out, NULL, err);
}

static const char *const vti_suffixes[] = {".vti", NULL};

const cdvr_format cdvr_format_vti = {
    .name = "vti",
    .description = "VTK XML ImageData through expat: ascii, base64 or appended raw data, zlib "
                   "or LZ4, the active scalars or select= (64-bit and int32 types as float32, window in "
                   "double)",
    .suffixes = vti_suffixes,
    .magic = vti_magic,
    .probe = vti_probe,
    .load = vti_load,
};
