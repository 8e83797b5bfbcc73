/* tests/test_io_mha.c - the MetaImage loader (core/io/io_mha.c): .mha (LOCAL data) and .mhd
 * with a detached .raw or zlib .zraw file, written here with known values of odd dims, little
 * and big endian, HeaderSize (bytes to skip, and -1: the data end the file), 2D, 3D and 4D
 * (time), and an oblique TransformMatrix (ITK's layout: the direction of axis 0, then axis 1,
 * ...), load voxel for voxel through cdvr_volume_load with the world box that direction gives;
 * the probe agrees; double and int32 become float32 with the window computed in double;
 * hostile headers (DimSize beyond the file, CompressedDataSize beyond it, a zlib stream that
 * inflates to more, file lists, ASCII data) and special files are refused naming the file. */
#include "check.h"
#include "cdvr/format.h"
#include "cdvr/volume.h"

#include <stdint.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

static char tmpdir[] = "/tmp/cdvr_test_io_mha_XXXXXX";

enum { T_F32, T_U16, T_I16, T_F64, T_I32, T_U8 };
static const char *const MET[] = {"MET_FLOAT", "MET_USHORT", "MET_SHORT", "MET_DOUBLE",
                                  "MET_INT", "MET_UCHAR"};
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

/* count values of type as bytes (big endian when big) into a malloc'd buffer. */
static uint8_t *values(int type, size_t count, int big)
{
    size_t k = TSIZE[type];
    uint8_t *out = malloc(count * k);
    for (size_t i = 0; i < count; i++) {
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
        for (size_t j = 0; j < k; j++)
            out[i * k + j] = big ? w[k - 1 - j] : w[j];
    }
    return out;
}

static void write_bytes(const char *path, const void *a, size_t an, const void *b, size_t bn)
{
    FILE *f = fopen(path, "wb");
    fwrite(a, 1, an, f);
    if (bn)
        fwrite(b, 1, bn, f);
    fclose(f);
}

static double D[9]; /* oblique, row-major: column c is axis c */

typedef struct mha_case {
    const char *label;
    int type, ndims, big, compressed, detached, header_size; /* header_size: 0, 7 or -1 */
} mha_case;

static const size_t DIMS[4] = {5, 4, 3, 2};

/* Writes the case's file(s); returns the header path in path. */
static void write_case(const mha_case *c, char *path, size_t pn)
{
    size_t count = 1;
    for (int i = 0; i < c->ndims; i++)
        count *= DIMS[i];
    size_t bytes = count * TSIZE[c->type];
    uint8_t *data = values(c->type, count, c->big), *packed = NULL;
    size_t pbytes = bytes;
    if (c->compressed) {
        uLongf zn = compressBound(bytes);
        packed = malloc(zn);
        compress2(packed, &zn, data, bytes, 6);
        pbytes = zn;
    }
    char head[4096], num[64];
    int n = snprintf(head, sizeof head, "ObjectType = Image\nNDims = %d\nBinaryData = True\n"
                     "BinaryDataByteOrderMSB = %s\nCompressedData = %s\n", c->ndims,
                     c->big ? "True" : "False", c->compressed ? "True" : "False");
    if (c->compressed)
        n += snprintf(head + n, sizeof head - (size_t)n, "CompressedDataSize = %zu\n", pbytes);
    n += snprintf(head + n, sizeof head - (size_t)n, "TransformMatrix =");
    int nd = c->ndims > 3 ? 3 : c->ndims;
    for (int col = 0; col < c->ndims; col++)
        for (int r = 0; r < c->ndims; r++) {
            double x = col < 3 && r < 3 ? D[3 * r + col] : col == r;
            if (nd == 2) /* a rotation in the plane */
                x = col == r ? cos(0.7) : col > r ? -sin(0.7) : sin(0.7);
            snprintf(num, sizeof num, " %.17g", x);
            n += snprintf(head + n, sizeof head - (size_t)n, "%s", num);
        }
    static const char *const geo[5] = {"", "", "\nOffset = 10 -2\nElementSpacing = 0.5 2\n",
                                        "\nOffset = 10 -2 0.5\nElementSpacing = 0.5 2 1.25\n",
                                        "\nOffset = 10 -2 0.5 0\nElementSpacing = 0.5 2 1.25 1\n"};
    n += snprintf(head + n, sizeof head - (size_t)n, "%sDimSize =", geo[c->ndims]);
    for (int i = 0; i < c->ndims; i++)
        n += snprintf(head + n, sizeof head - (size_t)n, " %zu", DIMS[i]);
    n += snprintf(head + n, sizeof head - (size_t)n, "\nElementType = %s\n", MET[c->type]);
    if (c->header_size)
        n += snprintf(head + n, sizeof head - (size_t)n, "HeaderSize = %d\n", c->header_size);
    const uint8_t *payload = c->compressed ? packed : data;
    if (c->detached) {
        snprintf(path, pn, "%s/case.mhd", tmpdir);
        n += snprintf(head + n, sizeof head - (size_t)n, "ElementDataFile = case.%s\n",
                      c->compressed ? "zraw" : "raw");
        write_bytes(path, head, (size_t)n, NULL, 0);
        char dpath[512];
        snprintf(dpath, sizeof dpath, "%s/case.%s", tmpdir, c->compressed ? "zraw" : "raw");
        const char junk[7] = "JUNKJUN";
        FILE *f = fopen(dpath, "wb");
        if (c->header_size)
            fwrite(junk, 1, 7, f);
        fwrite(payload, 1, pbytes, f);
        fclose(f);
    } else {
        snprintf(path, pn, "%s/case.mha", tmpdir);
        n += snprintf(head + n, sizeof head - (size_t)n, "ElementDataFile = LOCAL\n");
        write_bytes(path, head, (size_t)n, payload, pbytes);
    }
    free(data);
    free(packed);
}

static void check_case(const mha_case *c)
{
    char path[512];
    write_case(c, path, sizeof path);
    cdvr_volume *vol = NULL, head;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK(st == CDVR_OK, "%s: %s", c->label, err.msg);
    if (st != CDVR_OK)
        return;
    size_t t_n = c->ndims > 3 ? DIMS[3] : 1, z_n = c->ndims > 2 ? DIMS[2] : 1;
    CHECK(vol->dims[0] == 5 && vol->dims[1] == 4 && vol->dims[2] == z_n && vol->timesteps == t_n,
          "%s: dims %zux%zux%zu x %zu", c->label, vol->dims[0], vol->dims[1], vol->dims[2],
          vol->timesteps);
    size_t bad = 0, count = 20 * z_n * t_n;
    for (size_t i = 0; i < count; i++) {
        double want = value(c->type, i);
        if (c->type == T_F64 || c->type == T_I32)
            want = (float)want;
        bad += cdvr_volume_get(vol, i % 5, i / 5 % 4, i / 20 % z_n, i / (20 * z_n)) != want;
    }
    CHECK(bad == 0, "%s: %zu voxels differ", c->label, bad);
    if (c->type == T_F64 || c->type == T_I32) {
        double w[2];
        cdvr_volume_window(vol, w);
        CHECK(w[0] == value(c->type, 0) && w[1] == value(c->type, count - 1),
              "%s: window [%.17g, %.17g]", c->label, w[0], w[1]);
    }
    /* world box: Offset + D * (ijk * spacing) over the corners */
    const double O[3] = {10, -2, c->ndims > 2 ? 0.5 : 0}, S[3] = {0.5, 2, 1.25};
    double Dc[9];
    memcpy(Dc, D, sizeof Dc);
    if (c->ndims == 2) { /* the plane's rotation; the third axis is their normal */
        double cs = cos(0.7), sn = sin(0.7), m[9] = {cs, -sn, 0, sn, cs, 0, 0, 0, 1};
        memcpy(Dc, m, sizeof m);
    }
    double lo[3], hi[3], wlo[3] = {1e300, 1e300, 1e300}, whi[3] = {-1e300, -1e300, -1e300};
    for (int k = 0; k < 8; k++) {
        double ijk[3] = {k & 1 ? 4 : 0, k & 2 ? 3 : 0, k & 4 ? (double)z_n - 1 : 0};
        for (int r = 0; r < 3; r++) {
            double w = O[r];
            for (int col = 0; col < 3; col++)
                w += Dc[3 * r + col] * ijk[col] * S[col];
            wlo[r] = fmin(wlo[r], w);
            whi[r] = fmax(whi[r], w);
        }
    }
    cdvr_volume_bounds(vol, lo, hi);
    double e = 0, ed = 0;
    for (int r = 0; r < 3; r++)
        e = fmax(e, fmax(fabs(lo[r] - wlo[r]), fabs(hi[r] - whi[r])));
    for (int i = 0; i < 9; i++)
        ed = fmax(ed, fabs(vol->direction[i] - Dc[i]));
    CHECK(e < 1e-9 && ed < 1e-9, "%s: world box off by %g, direction by %g", c->label, e, ed);
    st = cdvr_volume_probe(path, NULL, &head, &err);
    CHECK(st == CDVR_OK && head.type == vol->type && head.timesteps == vol->timesteps &&
          memcmp(head.dims, vol->dims, sizeof head.dims) == 0 &&
          memcmp(head.origin, vol->origin, sizeof head.origin) == 0 &&
          memcmp(head.direction, vol->direction, sizeof head.direction) == 0,
          "%s: the probe differs from the load: %s", c->label, err.msg);
    cdvr_volume_free(vol);
}

static void expect_refused(const char *label, const char *path, const char *needle)
{
    cdvr_volume *vol = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK(st != CDVR_OK && vol == NULL && strstr(err.msg, path) && strstr(err.msg, needle),
          "%s: status %d: %s", label, (int)st, err.msg);
    cdvr_volume_free(vol);
}

static void test_hostile(void)
{
    char path[512], text[1024];
    snprintf(path, sizeof path, "%s/h.mha", tmpdir);
    const char *base = "ObjectType = Image\nNDims = 3\nDimSize = 100000 100000 1000\n"
                       "ElementType = MET_DOUBLE\n%sElementDataFile = LOCAL\nxxxxxxxx";
    int n = snprintf(text, sizeof text, base, "");
    write_bytes(path, text, (size_t)n, NULL, 0);
    expect_refused("DimSize beyond the file", path, "need");
    n = snprintf(text, sizeof text, base, "CompressedData = True\n");
    write_bytes(path, text, (size_t)n, NULL, 0);
    expect_refused("compressed beyond zlib's ratio", path, "more than zlib can pack");
    n = snprintf(text, sizeof text, base, "CompressedData = True\nCompressedDataSize = 999999\n");
    write_bytes(path, text, (size_t)n, NULL, 0);
    expect_refused("CompressedDataSize beyond the file", path, "CompressedDataSize");
    /* a zlib stream holding more than DimSize */
    uint8_t big[400] = {0}, packed[600];
    uLongf zn = sizeof packed;
    compress2(packed, &zn, big, sizeof big, 6);
    n = snprintf(text, sizeof text, "NDims = 3\nDimSize = 3 3 3\nElementType = MET_UCHAR\n"
                 "CompressedData = True\nElementDataFile = LOCAL\n");
    write_bytes(path, text, (size_t)n, packed, zn);
    expect_refused("zlib inflating to more", path, "more than");
    n = snprintf(text, sizeof text, "NDims = 3\nDimSize = 3 3 3\nElementType = MET_UCHAR\n"
                 "ElementDataFile = LIST\nslice0.raw\n");
    write_bytes(path, text, (size_t)n, NULL, 0);
    expect_refused("LIST", path, "LIST");
    n = snprintf(text, sizeof text, "NDims = 3\nDimSize = 3 3 3\nElementType = MET_UCHAR\n"
                 "BinaryData = False\nElementDataFile = LOCAL\n1 2 3");
    write_bytes(path, text, (size_t)n, NULL, 0);
    expect_refused("ASCII", path, "ASCII");
    n = snprintf(text, sizeof text, "NDims = 3\nDimSize = 3 3 3\nElementType = MET_UCHAR\n"
                 "ElementNumberOfChannels = 3\nElementDataFile = LOCAL\n");
    write_bytes(path, text, (size_t)n, NULL, 0);
    expect_refused("channels", path, "channels");
    /* a detached data file that is a FIFO; a header that is one */
    snprintf(path, sizeof path, "%s/f.mhd", tmpdir);
    n = snprintf(text, sizeof text, "NDims = 3\nDimSize = 3 3 3\nElementType = MET_UCHAR\n"
                 "ElementDataFile = fifo.raw\n");
    write_bytes(path, text, (size_t)n, NULL, 0);
    char fifo[512];
    snprintf(fifo, sizeof fifo, "%s/fifo.raw", tmpdir);
    CHECK(mkfifo(fifo, 0600) == 0, "mkfifo");
    cdvr_volume *vol = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK(st == CDVR_ERR_IO && strstr(err.msg, "fifo.raw") && strstr(err.msg, "regular"),
          "fifo data file: %s", err.msg);
    snprintf(path, sizeof path, "%s/fifo.mha", tmpdir);
    CHECK(mkfifo(path, 0600) == 0, "mkfifo");
    expect_refused("fifo header", path, "regular");
    unlink(path);
    unlink(fifo);
}

int main(void)
{
    double c = cos(0.7), s = sin(0.7);
    double m[9] = {c, -s * 0.6, s * 0.8, s, c * 0.6, -c * 0.8, 0, 0.8, 0.6};
    memcpy(D, m, sizeof m);
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    CHECK(cdvr_format_find("mha") != NULL, "mha format registered");
    static const mha_case cases[] = {
        {"mha f32", T_F32, 3, 0, 0, 0, 0},
        {"mha u16 big", T_U16, 3, 1, 0, 0, 0},
        {"mha zlib i16", T_I16, 3, 0, 1, 0, 0},
        {"mha f64 4D", T_F64, 4, 0, 0, 0, 0},
        {"mha i32 big zlib", T_I32, 3, 1, 1, 0, 0},
        {"mha u8 2D", T_U8, 2, 0, 0, 0, 0},
        {"mhd raw f32", T_F32, 3, 0, 0, 1, 0},
        {"mhd raw HeaderSize 7", T_U16, 3, 0, 0, 1, 7},
        {"mhd raw HeaderSize -1", T_I16, 3, 1, 0, 1, -1},
        {"mhd zraw f64", T_F64, 3, 0, 1, 1, 0},
        {"mhd zraw 4D u16", T_U16, 4, 0, 1, 1, 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        check_case(&cases[i]);
    test_hostile();
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    CHECK(system(cmd) == 0, "cleanup");
    return check_finish();
}
