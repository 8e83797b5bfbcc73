/* tests/test_io_vtk.c - the VTK loaders (core/io/io_vti.c through expat, io_vtk.c legacy):
 * files written here with known values, odd dims, an extent that does not start at 0 and an
 * oblique Direction, in every encoding (.vti: ascii, base64 inline, appended raw and appended
 * base64; none, zlib and LZ4 compressors, several blocks with a partial last one; UInt32 and
 * UInt64 headers; little and big endian; legacy: ASCII and BINARY), load voxel for voxel through
 * cdvr_volume_load (the format table) and give the world box and direction matrix VTK gives
 * (origin + D * ((extent start + ijk) * spacing)); the probe agrees without reading voxels;
 * an array is chosen by name, the active scalars by default; float64 and int32 become float32
 * with the window computed in double and reported; hostile headers (sizes beyond the file,
 * block counts, offsets) and special files are refused at once with a message naming the
 * file. */
#include "check.h"
#include "cdvr/format.h"
#include "cdvr/vti.h"
#include "cdvr/volume.h"

#include <lz4.h>
#include <stdint.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

typedef struct buf {
    uint8_t *p;
    size_t n, cap;
} buf;

static void put(buf *b, const void *src, size_t n)
{
    if (b->n + n > b->cap) {
        b->cap = 2 * (b->n + n) + 256;
        b->p = realloc(b->p, b->cap);
    }
    memcpy(b->p + b->n, src, n);
    b->n += n;
}

static void puts_(buf *b, const char *s) { put(b, s, strlen(s)); }

static void putf(buf *b, const char *fmt, double v)
{
    char s[64];
    snprintf(s, sizeof s, fmt, v);
    puts_(b, s);
}

static void put_word(buf *b, uint64_t v, int bytes, int big)
{
    uint8_t w[8];
    for (int i = 0; i < bytes; i++)
        w[big ? bytes - 1 - i : i] = (uint8_t)(v >> (8 * i));
    put(b, w, (size_t)bytes);
}

static void base64(buf *out, const uint8_t *p, size_t n)
{
    static const char a[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0) |
                     (i + 2 < n ? p[i + 2] : 0);
        char g[4] = {a[v >> 18], a[(v >> 12) & 63], i + 1 < n ? a[(v >> 6) & 63] : '=',
                     i + 2 < n ? a[v & 63] : '='};
        put(out, g, 4);
    }
}

/* The test volume: values of type `type` ("Float32", ...) for voxel i, as bytes. */
enum { T_F32, T_U16, T_I16, T_F64, T_I32, T_U8 };
static const char *const TNAME[] = {"Float32", "UInt16", "Int16", "Float64", "Int32", "UInt8"};
static const char *const LNAME[] = {"float", "unsigned_short", "short", "double", "int",
                                    "unsigned_char"};
static const size_t TSIZE[] = {4, 2, 2, 8, 4, 1};

static double value(int type, size_t i)
{
    switch (type) {
    case T_F32: return (float)(0.25 * (double)i - 7.5);
    case T_U16: return (double)((i * 977) % 65536);
    case T_I16: return (double)((long)(i * 131) % 60000 - 30000);
    case T_F64: return 1e36 * ((double)i - 30.0) + 0.125 * (double)i; /* within f32 (test_io_f32_rule: beyond) */
    case T_I32: return (double)((long long)i * 50000001LL - 2000000000LL);
    default: return (double)(i * 7 % 256);
    }
}

static void put_value(buf *b, int type, size_t i, int big)
{
    double v = value(type, i);
    uint8_t w[8];
    switch (type) {
    case T_F32: { float f = (float)v; memcpy(w, &f, 4); break; }
    case T_U16: { uint16_t x = (uint16_t)v; memcpy(w, &x, 2); break; }
    case T_I16: { int16_t x = (int16_t)v; memcpy(w, &x, 2); break; }
    case T_F64: memcpy(w, &v, 8); break;
    case T_I32: { int32_t x = (int32_t)v; memcpy(w, &x, 4); break; }
    default: w[0] = (uint8_t)v; break;
    }
    size_t k = TSIZE[type];
    if (big)
        for (size_t j = 0; j < k / 2; j++) {
            uint8_t c = w[j];
            w[j] = w[k - 1 - j];
            w[k - 1 - j] = c;
        }
    put(b, w, k);
}

static const long EXT0[3] = {2, -1, 0};
static const double ORIGIN[3] = {10, -2, 0.5}, SPACING[3] = {0.5, 2, 1.25};
/* a rotation about (1,1,1)/sqrt(3) by 40 degrees, row-major; its columns are the axes */
static double DIR[9];

static void make_dir(void)
{
    double c = cos(40 * M_PI / 180), s = sin(40 * M_PI / 180), t = 1 - c, u = 1 / sqrt(3.0);
    double m[9] = {t * u * u + c, t * u * u - s * u, t * u * u + s * u,
                   t * u * u + s * u, t * u * u + c, t * u * u - s * u,
                   t * u * u - s * u, t * u * u + s * u, t * u * u + c};
    memcpy(DIR, m, sizeof m);
}

#define NVOX (5 * 4 * 3)

/* The binary block of an array (header + data, maybe compressed). comp: 0 none, 1 zlib, 2 lz4.
 * Inline base64 (b64): VTK's layout - one stream uncompressed, header and blocks as two. */
static void block(buf *out, int type, int comp, int h64, int big, int b64)
{
    buf raw = {0}, blk = {0};
    for (size_t i = 0; i < NVOX; i++)
        put_value(&raw, type, i, big);
    int hb = h64 ? 8 : 4;
    if (comp == 0) {
        put_word(&blk, raw.n, hb, big);
        put(&blk, raw.p, raw.n);
        if (b64)
            base64(out, blk.p, blk.n);
        else
            put(out, blk.p, blk.n);
    } else {
        size_t bs = 64, nb = (raw.n + bs - 1) / bs, last = raw.n % bs;
        buf head = {0}, data = {0};
        put_word(&head, nb, hb, big);
        put_word(&head, bs, hb, big);
        put_word(&head, last, hb, big);
        for (size_t b = 0; b < nb; b++) {
            size_t un = b + 1 == nb && last ? last : bs;
            uint8_t packed[256];
            size_t pn = sizeof packed;
            if (comp == 1) {
                uLongf zn = pn;
                compress2(packed, &zn, raw.p + b * bs, un, 6);
                pn = zn;
            } else
                pn = (size_t)LZ4_compress_default((const char *)raw.p + b * bs, (char *)packed,
                                                  (int)un, (int)pn);
            put_word(&head, pn, hb, big);
            put(&data, packed, pn);
        }
        if (b64) {
            base64(out, head.p, head.n);
            base64(out, data.p, data.n);
        } else {
            put(out, head.p, head.n);
            put(out, data.p, data.n);
        }
        free(head.p);
        free(data.p);
    }
    free(raw.p);
    free(blk.p);
}

typedef struct vti_case {
    const char *label;
    int type, format; /* 0 ascii, 1 binary, 2 appended raw, 3 appended base64 */
    int comp, h64, big;
} vti_case;

/* A .vti with two point-data arrays: "other" (UInt8, first) and "field" (the case's type); the
 * active scalars are "field". */
static void write_vti(const char *path, const vti_case *c)
{
    buf b = {0}, app = {0};
    puts_(&b, "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"");
    puts_(&b, c->big ? "BigEndian" : "LittleEndian");
    puts_(&b, c->h64 ? "\" header_type=\"UInt64\"" : "\" header_type=\"UInt32\"");
    if (c->comp)
        puts_(&b, c->comp == 1 ? " compressor=\"vtkZLibDataCompressor\"" : " compressor=\"vtkLZ4DataCompressor\"");
    puts_(&b, ">\n  <ImageData WholeExtent=\"");
    char ext[128];
    snprintf(ext, sizeof ext, "%ld %ld %ld %ld %ld %ld", EXT0[0], EXT0[0] + 4, EXT0[1],
             EXT0[1] + 3, EXT0[2], EXT0[2] + 2);
    puts_(&b, ext);
    puts_(&b, "\" Origin=\"");
    for (int i = 0; i < 3; i++)
        putf(&b, i ? " %.17g" : "%.17g", ORIGIN[i]);
    puts_(&b, "\" Spacing=\"");
    for (int i = 0; i < 3; i++)
        putf(&b, i ? " %.17g" : "%.17g", SPACING[i]);
    puts_(&b, "\" Direction=\"");
    for (int i = 0; i < 9; i++)
        putf(&b, i ? " %.17g" : "%.17g", DIR[i]);
    puts_(&b, "\">\n  <Piece Extent=\"");
    puts_(&b, ext);
    puts_(&b, "\">\n    <PointData Scalars=\"field\">\n");
    for (int a = 0; a < 2; a++) {
        int type = a == 0 ? T_U8 : c->type;
        static const char *const fmts[] = {"ascii", "binary", "appended", "appended"};
        puts_(&b, "      <DataArray type=\"");
        puts_(&b, TNAME[type]);
        puts_(&b, a == 0 ? "\" Name=\"other\" format=\"" : "\" Name=\"field\" format=\"");
        puts_(&b, fmts[c->format]);
        if (c->format >= 2)
            putf(&b, "\" offset=\"%.0f", (double)app.n);
        puts_(&b, "\">\n");
        if (c->format == 0)
            for (size_t i = 0; i < NVOX; i++)
                putf(&b, type == T_F32 || type == T_F64 ? " %.17g" : " %.0f", value(type, i));
        else if (c->format == 1)
            block(&b, type, c->comp, c->h64, c->big, 1);
        else
            block(&app, type, c->comp, c->h64, c->big, c->format == 3);
        puts_(&b, "\n      </DataArray>\n");
    }
    puts_(&b, "    </PointData>\n    <CellData>\n    </CellData>\n  </Piece>\n  </ImageData>\n");
    if (c->format >= 2) {
        puts_(&b, c->format == 2 ? "  <AppendedData encoding=\"raw\">\n   _"
                                 : "  <AppendedData encoding=\"base64\">\n   _");
        put(&b, app.p, app.n);
        puts_(&b, "\n  </AppendedData>\n");
    }
    puts_(&b, "</VTKFile>\n");
    FILE *f = fopen(path, "wb");
    fwrite(b.p, 1, b.n, f);
    fclose(f);
    free(b.p);
    free(app.p);
}

static void write_legacy(const char *path, int type, int binary, const char *extra)
{
    buf b = {0};
    puts_(&b, "# vtk DataFile Version 3.0\ncdvr test\n");
    puts_(&b, binary ? "BINARY\n" : "ASCII\n");
    puts_(&b, "DATASET STRUCTURED_POINTS\nDIMENSIONS 5 4 3\n");
    puts_(&b, "ORIGIN");
    for (int i = 0; i < 3; i++)
        putf(&b, " %.17g", ORIGIN[i]);
    puts_(&b, "\nSPACING");
    for (int i = 0; i < 3; i++)
        putf(&b, " %.17g", SPACING[i]);
    puts_(&b, "\nPOINT_DATA 60\n");
    puts_(&b, extra);
    for (int a = 0; a < 2; a++) {
        int t = a == 0 ? T_U8 : type;
        puts_(&b, a == 0 ? "SCALARS other " : "SCALARS field ");
        puts_(&b, LNAME[t]);
        puts_(&b, " 1\nLOOKUP_TABLE default\n");
        for (size_t i = 0; i < NVOX; i++) {
            if (binary)
                put_value(&b, t, i, 1);
            else
                putf(&b, t == T_F32 || t == T_F64 ? "%.17g " : "%.0f ", value(t, i));
        }
        puts_(&b, "\n");
    }
    FILE *f = fopen(path, "wb");
    fwrite(b.p, 1, b.n, f);
    fclose(f);
    free(b.p);
}

/* Voxels of vol against the values of type (f32 conversion for converted types). */
static void check_voxels(const char *label, const cdvr_volume *vol, int type)
{
    size_t bad = 0;
    for (size_t i = 0; i < NVOX; i++) {
        double want = value(type, i), got = cdvr_volume_get(vol, i % 5, i / 5 % 4, i / 20, 0);
        if (type == T_F64 || type == T_I32)
            want = (float)want;
        bad += got != want;
    }
    CHECK(bad == 0, "%s: %zu voxels differ", label, bad);
}

/* World box and direction as VTK computes them: origin + D * ((ext0 + ijk) * spacing). */
static void check_geometry(const char *label, const cdvr_volume *vol, const long ext0[3],
                           const double D[9])
{
    double lo[3], hi[3], wlo[3] = {1e300, 1e300, 1e300}, whi[3] = {-1e300, -1e300, -1e300};
    for (int k = 0; k < 8; k++) {
        double ijk[3] = {(double)ext0[0] + (k & 1 ? 4 : 0), (double)ext0[1] + (k & 2 ? 3 : 0),
                         (double)ext0[2] + (k & 4 ? 2 : 0)};
        for (int r = 0; r < 3; r++) {
            double w = ORIGIN[r];
            for (int c = 0; c < 3; c++)
                w += D[3 * r + c] * ijk[c] * SPACING[c];
            wlo[r] = fmin(wlo[r], w);
            whi[r] = fmax(whi[r], w);
        }
    }
    cdvr_volume_bounds(vol, lo, hi);
    double e = 0, ed = 0;
    for (int r = 0; r < 3; r++)
        e = fmax(e, fmax(fabs(lo[r] - wlo[r]), fabs(hi[r] - whi[r])));
    for (int i = 0; i < 9; i++)
        ed = fmax(ed, fabs(vol->direction[i] - D[i]));
    CHECK(e < 1e-9 && ed < 1e-12, "%s: world box off by %g, direction by %g", label, e, ed);
    CHECK(vol->dims[0] == 5 && vol->dims[1] == 4 && vol->dims[2] == 3 && vol->timesteps == 1,
          "%s: dims %zux%zux%zu", label, vol->dims[0], vol->dims[1], vol->dims[2]);
}

static void check_file(const char *label, const char *path, int type, const long ext0[3],
                       const double D[9], int other)
{
    cdvr_volume *vol = NULL, head;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK_OK(st, err);
    if (st != CDVR_OK)
        return;
    check_voxels(label, vol, type);
    check_geometry(label, vol, ext0, D);
    static const cdvr_type vt[] = {CDVR_TYPE_F32, CDVR_TYPE_U16, CDVR_TYPE_I16, CDVR_TYPE_F32,
                                   CDVR_TYPE_F32, CDVR_TYPE_U8};
    CHECK(vol->type == vt[type], "%s: type %s", label, cdvr_type_name(vol->type));
    if (type == T_F64 || type == T_I32) { /* window in double, from the file's values */
        double w[2];
        cdvr_volume_window(vol, w);
        CHECK(w[0] == value(type, 0) && w[1] == value(type, NVOX - 1),
              "%s: window [%.17g, %.17g]", label, w[0], w[1]);
    }
    st = cdvr_volume_probe(path, NULL, &head, &err);
    CHECK_OK(st, err);
    CHECK(st == CDVR_OK && head.type == vol->type && head.dims[0] == 5 && head.dims[2] == 3 &&
          head.timesteps == 1 && memcmp(head.origin, vol->origin, sizeof head.origin) == 0 &&
          memcmp(head.direction, vol->direction, sizeof head.direction) == 0 &&
          memcmp(head.spacing, vol->spacing, sizeof head.spacing) == 0,
          "%s: the probe differs from the load", label);
    cdvr_volume_free(vol);
    /* the first array by name, with the info report */
    cdvr_vti_info info;
    st = other ? cdvr_vti_load(path, "other", &vol, &info, &err) : CDVR_ERR_ARG;
    CHECK(!other || st == CDVR_OK, "%s: %s", label, err.msg);
    if (st == CDVR_OK) {
        check_voxels(label, vol, T_U8);
        CHECK(strcmp(info.array, "other") == 0 && strcmp(info.file_type, "uint8") == 0 &&
              !info.converted, "%s: info %s %s", label, info.array, info.file_type);
        cdvr_volume_free(vol);
    }
    st = cdvr_vti_load(path, "field", &vol, &info, &err);
    CHECK(st == CDVR_OK && info.converted == (type == T_F64 || type == T_I32),
          "%s: info.converted %d", label, info.converted);
    cdvr_volume_free(vol);
    st = cdvr_vti_probe(path, "nosuch", &head, NULL, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "nosuch") && strstr(err.msg, path),
          "%s: unknown array: %s", label, err.msg);
}

static char tmpdir[] = "/tmp/cdvr_test_io_vtk_XXXXXX";

static void test_vti(void)
{
    static const vti_case cases[] = {
        {"ascii f32", T_F32, 0, 0, 0, 0},
        {"ascii f64", T_F64, 0, 0, 0, 0},
        {"base64 u16", T_U16, 1, 0, 0, 0},
        {"base64 u16 h64", T_U16, 1, 0, 1, 0},
        {"base64 zlib i16", T_I16, 1, 1, 0, 0},
        {"base64 zlib f32 h64", T_F32, 1, 1, 1, 0},
        {"base64 lz4 f64", T_F64, 1, 2, 0, 0},
        {"appended raw f32", T_F32, 2, 0, 0, 0},
        {"appended raw u16 big", T_U16, 2, 0, 1, 1},
        {"appended raw zlib i32", T_I32, 2, 1, 1, 0},
        {"appended raw zlib f64 big", T_F64, 2, 1, 0, 1},
        {"appended raw lz4 i16", T_I16, 2, 2, 1, 0},
        {"appended base64 zlib f32", T_F32, 3, 1, 0, 0},
        {"appended base64 u16", T_U16, 3, 0, 0, 0},
    };
    char path[256];
    snprintf(path, sizeof path, "%s/a.vti", tmpdir);
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        write_vti(path, &cases[i]);
        check_file(cases[i].label, path, cases[i].type, EXT0, DIR, 1);
    }
}

static void test_legacy(void)
{
    char path[256];
    snprintf(path, sizeof path, "%s/a.vtk", tmpdir);
    static const long zero[3] = {0, 0, 0};
    static const int types[] = {T_F32, T_U16, T_I16, T_F64, T_I32, T_U8};
    char extra[512] = "";
    for (int binary = 0; binary < 2; binary++)
        for (size_t t = 0; t < sizeof types / sizeof *types; t++) {
            char label[64];
            snprintf(label, sizeof label, "legacy %s %s", binary ? "binary" : "ascii",
                     TNAME[types[t]]);
            write_legacy(path, types[t], binary, "");
            /* the second SCALARS is "field": the default is the first array, so load by name */
            cdvr_volume *vol = NULL;
            cdvr_error err;
            cdvr_status st = cdvr_vti_load(path, "field", &vol, NULL, &err);
            CHECK_OK(st, err);
            if (st == CDVR_OK) {
                static const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
                check_voxels(label, vol, types[t]);
                check_geometry(label, vol, zero, I);
                cdvr_volume_free(vol);
            }
            st = cdvr_volume_load(path, NULL, &vol, &err);
            CHECK_OK(st, err);
            if (st == CDVR_OK)
                check_voxels(label, vol, T_U8);
            cdvr_volume_free(vol);
        }
    /* a DIRECTION line (oblique) */
    snprintf(extra, sizeof extra, "%s", "");
    char dirline[400] = "";
    size_t k = (size_t)snprintf(dirline, sizeof dirline, "DIRECTION");
    for (int i = 0; i < 9; i++)
        k += (size_t)snprintf(dirline + k, sizeof dirline - k, " %.17g", DIR[i]);
    snprintf(dirline + k, sizeof dirline - k, "\n");
    buf b = {0};
    puts_(&b, "# vtk DataFile Version 5.1\nt\nBINARY\nDATASET STRUCTURED_POINTS\n");
    puts_(&b, dirline);
    puts_(&b, "DIMENSIONS 5 4 3\nORIGIN 10 -2 0.5\nSPACING 0.5 2 1.25\nPOINT_DATA 60\n"
              "SCALARS field float\nLOOKUP_TABLE default\n");
    for (size_t i = 0; i < NVOX; i++)
        put_value(&b, T_F32, i, 1);
    FILE *f = fopen(path, "wb");
    fwrite(b.p, 1, b.n, f);
    fclose(f);
    check_file("legacy direction", path, T_F32, zero, DIR, 0);
    free(b.p);
}

/* Writes text to path. */
static void write_text(const char *path, const char *text, size_t n)
{
    FILE *f = fopen(path, "wb");
    fwrite(text, 1, n, f);
    fclose(f);
}

static void expect_refused(const char *label, const char *path, const char *needle)
{
    cdvr_volume *vol = NULL, head;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK(st != CDVR_OK && vol == NULL && strstr(err.msg, path) &&
          (!needle || strstr(err.msg, needle)), "%s: status %d: %s", label, (int)st, err.msg);
    cdvr_volume_free(vol);
    (void)head;
}

static void test_hostile(void)
{
    char path[256], msg[4096];
    snprintf(path, sizeof path, "%s/h.vti", tmpdir);
    const char *pre = "<VTKFile type=\"ImageData\" version=\"1.0\" header_type=\"UInt64\" %s>"
                      "<ImageData WholeExtent=\"0 %s 0 999 0 999\"><Piece Extent=\"0 %s 0 999 0 999\">"
                      "<PointData><DataArray type=\"Float32\" Name=\"a\" format=\"%s\" "
                      "offset=\"%s\">%s</DataArray></PointData></Piece></ImageData>%s</VTKFile>";
    /* appended raw: a byte count of 4e9 voxels in a 300-byte file */
    uint8_t app[] = "<AppendedData encoding=\"raw\">_\x00\x40\x7a\x10\xf3\x5a\x00\x00xxxx</AppendedData>";
    int n = snprintf(msg, sizeof msg, pre, "", "3999", "3999", "appended", "0", "", "");
    memcpy(msg + n - 10, app, sizeof app - 1);
    memcpy(msg + n - 10 + sizeof app - 1, "</VTKFile>", 10);
    write_text(path, msg, (size_t)n + sizeof app - 1);
    expect_refused("appended count beyond the file", path, "the file holds for them");
    /* zlib: 2^40 blocks claimed (a small extent: the header itself is refused) */
    n = snprintf(msg, sizeof msg, "<VTKFile type=\"ImageData\" header_type=\"UInt64\" "
                 "compressor=\"vtkZLibDataCompressor\"><ImageData WholeExtent=\"0 3 0 0 0 0\">"
                 "<Piece Extent=\"0 3 0 0 0 0\"><PointData><DataArray type=\"Float32\" Name=\"a\" "
                 "format=\"binary\">AAAAAAAAAQAAAAAAAAAAAAAAAAAAAAAAAAA=</DataArray></PointData>"
                 "</Piece></ImageData></VTKFile>");
    write_text(path, msg, (size_t)n);
    expect_refused("zlib block count", path, "compression header");
    /* an appended offset past the end */
    n = snprintf(msg, sizeof msg, pre, "", "0", "0", "appended", "999999999999",
                 "", "<AppendedData encoding=\"raw\">_</AppendedData>");
    write_text(path, msg, (size_t)n);
    expect_refused("offset past the end", path, "past the end");
    /* ASCII with too few values */
    n = snprintf(msg, sizeof msg, pre, "", "0", "0", "ascii", "0", "1 2 3", "");
    write_text(path, msg, (size_t)n);
    expect_refused("ascii beyond the file", path, "the file holds for them");
    n = snprintf(msg, sizeof msg, "<VTKFile type=\"ImageData\"><ImageData WholeExtent=\"0 3 0 0 "
                 "0 0\"><Piece Extent=\"0 3 0 0 0 0\"><PointData><DataArray type=\"Int16\" "
                 "Name=\"a\" format=\"ascii\">1 2 3    </DataArray></PointData></Piece></ImageData>"
                 "</VTKFile>");
    write_text(path, msg, (size_t)n);
    expect_refused("ascii short", path, "value 3 of 4 is missing");
    /* a DOCTYPE (entity expansion) */
    n = snprintf(msg, sizeof msg, "<!DOCTYPE a [<!ENTITY x \"xx\">]><VTKFile type=\"ImageData\"/>");
    write_text(path, msg, (size_t)n);
    expect_refused("doctype", path, "DOCTYPE");
    /* not image data */
    n = snprintf(msg, sizeof msg, "<VTKFile type=\"PolyData\"></VTKFile>");
    write_text(path, msg, (size_t)n);
    expect_refused("polydata", path, "ImageData");
    /* legacy: DIMENSIONS claiming far more than the file */
    snprintf(path, sizeof path, "%s/h.vtk", tmpdir);
    n = snprintf(msg, sizeof msg, "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET "
                 "STRUCTURED_POINTS\nDIMENSIONS 100000 100000 1000\nPOINT_DATA 10000000000000\n"
                 "SCALARS a double\nLOOKUP_TABLE default\nxxxxxxxx");
    write_text(path, msg, (size_t)n);
    expect_refused("legacy beyond the file", path, "the file holds");
    n = snprintf(msg, sizeof msg, "# vtk DataFile Version 3.0\nt\nASCII\nDATASET "
                 "STRUCTURED_POINTS\nDIMENSIONS 1000 1000 1000\nPOINT_DATA 1000000000\n"
                 "SCALARS a float\n1 2 3");
    write_text(path, msg, (size_t)n);
    expect_refused("legacy ascii beyond the file", path, "cannot fit");
    n = snprintf(msg, sizeof msg, "# vtk DataFile Version 3.0\nt\nASCII\nDATASET "
                 "POLYDATA\nPOINTS 3 float\n");
    write_text(path, msg, (size_t)n);
    expect_refused("legacy polydata", path, "STRUCTURED_POINTS");
    /* special files: a FIFO named .vti */
    snprintf(path, sizeof path, "%s/fifo.vti", tmpdir);
    CHECK(mkfifo(path, 0600) == 0, "mkfifo");
    expect_refused("fifo", path, "regular");
    unlink(path);
    /* found by magic without the suffix */
    vti_case c = {"magic", T_F32, 2, 1, 0, 0};
    snprintf(path, sizeof path, "%s/noext", tmpdir);
    write_vti(path, &c);
    cdvr_volume *vol = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK_OK(st, err);
    cdvr_volume_free(vol);
    unlink(path);
}

int main(void)
{
    make_dir();
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    CHECK(cdvr_format_find("vti") && cdvr_format_find("vtk"), "vti/vtk formats registered");
    test_vti();
    test_legacy();
    test_hostile();
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    CHECK(system(cmd) == 0, "cleanup");
    return check_finish();
}
