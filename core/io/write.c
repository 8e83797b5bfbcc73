/* core/io/write.c - cdvr_volume_save (cdvr/write.h): the writer table keyed by suffix, the
 * helpers every writer shares, and the two writers that are ours: VTK XML ImageData (.vti) and
 * MetaImage (.mha, .mhd). NRRD (teem) is in write_nrrd.c, NIfTI (niftilib) in write_nifti.c. */
#include "cdvr/atomicfile.h"
#include "cdvr/regular_file.h"
#include "cdvr/write.h"
#include "volume_io.h"
#include "write_io.h"

#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

/* ---- shared helpers ------------------------------------------------------------------------- */

void cdvr_write_matrix(const cdvr_volume *vol, double M[9])
{
    double D[9];
    cdvr_volume_direction(vol, D);
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            M[3 * r + c] = D[3 * r + c] * vol->spacing[c];
}

char *cdvr_write_sibling(const char *path, size_t suffix_len, const char *tail)
{
    size_t n = strlen(path) - suffix_len, k = strlen(tail);
    char *s = malloc(n + k + 1);
    if (!s)
        return NULL;
    memcpy(s, path, n);
    memcpy(s + n, tail, k + 1);
    return s;
}

const char *cdvr_write_basename(const char *p)
{
    const char *slash = strrchr(p, '/');
    return slash ? slash + 1 : p;
}

cdvr_status cdvr_write_check_target(const char *path, cdvr_error *err)
{
    struct stat sb;
    if (stat(path, &sb) != 0) {
        if (errno == ENOENT)
            return CDVR_OK;
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot save: %s", path, strerror(errno));
    }
    if (!S_ISREG(sb.st_mode))
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot save over %s (not a regular file)",
                              path, cdvr_file_kind((unsigned)sb.st_mode));
    return CDVR_OK;
}

int cdvr_write_all(FILE *f, const void *p, size_t n)
{
    const uint8_t *b = p;
    while (n) {
        size_t k = n < ((size_t)1 << 30) ? n : (size_t)1 << 30;
        if (fwrite(b, 1, k, f) != k)
            return 0;
        b += k;
        n -= k;
    }
    return 1;
}

cdvr_status cdvr_write_deflate(const char *path, const void *src, size_t n, int gzip,
                               uint8_t **out, size_t *out_n, cdvr_error *err)
{
    *out = NULL;
    z_stream z;
    memset(&z, 0, sizeof z);
    if (deflateInit2(&z, Z_DEFAULT_COMPRESSION, Z_DEFLATED, gzip ? 15 + 16 : 15, 8,
                     Z_DEFAULT_STRATEGY) != Z_OK)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot start zlib", path);
    size_t cap = (size_t)deflateBound(&z, (uLong)n) + 64;
    uint8_t *buf = malloc(cap);
    if (!buf) {
        deflateEnd(&z);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot allocate %zu bytes to compress",
                              path, cap);
    }
    const uint8_t *in = src;
    size_t in_left = n, done = 0;
    int zs = Z_OK;
    while (zs == Z_OK) {
        if (z.avail_in == 0 && in_left) {
            uInt k = in_left < UINT_MAX / 2 ? (uInt)in_left : UINT_MAX / 2;
            z.next_in = (Bytef *)in;
            z.avail_in = k;
            in += k;
            in_left -= k;
        }
        size_t room = cap - done;
        z.next_out = buf + done;
        z.avail_out = room < UINT_MAX / 2 ? (uInt)room : UINT_MAX / 2;
        uInt before = z.avail_out;
        zs = deflate(&z, in_left || z.avail_in ? Z_NO_FLUSH : Z_FINISH);
        done += before - z.avail_out;
        if (zs == Z_OK && z.avail_out == before && z.avail_in == 0 && !in_left && done == cap)
            zs = Z_BUF_ERROR;
    }
    deflateEnd(&z);
    if (zs != Z_STREAM_END) {
        free(buf);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: zlib deflate failed (%d)", path, zs);
    }
    *out = buf;
    *out_n = done;
    return CDVR_OK;
}

cdvr_status cdvr_write_data_file(const char *path, const void *data, size_t n, int compress,
                                 cdvr_error *err)
{
    uint8_t *z = NULL;
    size_t zn = 0;
    cdvr_status st = CDVR_OK;
    if (compress && (st = cdvr_write_deflate(path, data, n, compress == 1, &z, &zn, err)) != CDVR_OK)
        return st;
    cdvr_atomic_file af;
    st = cdvr_atomic_open(&af, path, err);
    if (st == CDVR_OK)
        st = cdvr_atomic_commit(&af, !cdvr_write_all(af.f, z ? z : data, z ? zn : n), err);
    free(z);
    return st;
}

/* ---- MetaImage ------------------------------------------------------------------------------ */

static const char *met_type(cdvr_type t)
{
    switch (t) {
    case CDVR_TYPE_U8: return "MET_UCHAR";
    case CDVR_TYPE_U16: return "MET_USHORT";
    case CDVR_TYPE_I16: return "MET_SHORT";
    default: return "MET_FLOAT";
    }
}

/* The header text (ITK's key order) into f. data_file: "LOCAL" or the data file's name. */
static int mha_header(FILE *f, const cdvr_volume *vol, int compress, size_t csize,
                      const char *data_file)
{
    int n = vol->timesteps > 1 ? 4 : 3;
    double D[9];
    cdvr_volume_direction(vol, D);
    fprintf(f, "ObjectType = Image\nNDims = %d\nBinaryData = True\n", n);
    fprintf(f, "BinaryDataByteOrderMSB = %s\n", cdvr_host_is_little_endian() ? "False" : "True");
    fprintf(f, "CompressedData = %s\n", compress ? "True" : "False");
    if (compress)
        fprintf(f, "CompressedDataSize = %zu\n", csize);
    fprintf(f, "TransformMatrix =");
    for (int c = 0; c < n; c++) /* the direction of index axis c, then of c + 1, ... */
        for (int r = 0; r < n; r++)
            fprintf(f, " %.17g", c < 3 && r < 3 ? D[3 * r + c] : (double)(r == c));
    fprintf(f, "\nOffset =");
    for (int i = 0; i < n; i++)
        fprintf(f, " %.17g", i < 3 ? vol->origin[i] : 0.0);
    fprintf(f, "\nCenterOfRotation =");
    for (int i = 0; i < n; i++)
        fprintf(f, " 0");
    fprintf(f, "\nElementSpacing =");
    for (int i = 0; i < n; i++)
        fprintf(f, " %.17g", i < 3 ? vol->spacing[i] : 1.0);
    fprintf(f, "\nDimSize = %zu %zu %zu", vol->dims[0], vol->dims[1], vol->dims[2]);
    if (n == 4)
        fprintf(f, " %zu", vol->timesteps);
    double w[2];
    if (cdvr_u8_window_get(vol, w)) /* cdvr's key (ITK skips keys it does not know) */
        fprintf(f, "\nCdvrValueWindow = %.17g %.17g", w[0], w[1]);
    fprintf(f, "\nElementType = %s\nElementDataFile = %s\n", met_type(vol->type), data_file);
    return !ferror(f);
}

static cdvr_status write_mha(const cdvr_volume *vol, const char *path, int compress,
                             int detached, cdvr_error *err)
{
    size_t bytes;
    if (!cdvr_volume_bytes_for(vol->dims, vol->timesteps, vol->type, &bytes))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: volume size overflows", path);
    char *data_path = NULL;
    cdvr_status st = CDVR_OK;
    if (detached) {
        data_path = cdvr_write_sibling(path, 4, compress ? ".zraw" : ".raw");
        if (!data_path)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
        if ((st = cdvr_write_check_target(data_path, err)) != CDVR_OK) {
            free(data_path);
            return st;
        }
    }
    uint8_t *z = NULL;
    size_t zn = 0;
    if (compress)
        st = cdvr_write_deflate(path, vol->data, bytes, 0, &z, &zn, err);
    if (st == CDVR_OK && detached)
        st = cdvr_write_data_file(data_path, z ? z : vol->data, z ? zn : bytes, 0, err);
    if (st == CDVR_OK) {
        cdvr_atomic_file af;
        st = cdvr_atomic_open(&af, path, err);
        if (st == CDVR_OK) {
            int ok = mha_header(af.f, vol, compress, zn,
                                detached ? cdvr_write_basename(data_path) : "LOCAL");
            if (ok && !detached)
                ok = cdvr_write_all(af.f, z ? z : vol->data, z ? zn : bytes);
            st = cdvr_atomic_commit(&af, !ok, err);
        }
        if (st != CDVR_OK && detached)
            unlink(data_path); /* the header failed: its data file goes too */
    }
    free(z);
    free(data_path);
    return st;
}

static cdvr_status write_mha_local(const cdvr_volume *vol, const char *path, int compress,
                                   cdvr_error *err)
{
    return write_mha(vol, path, compress, 0, err);
}

static cdvr_status write_mhd(const cdvr_volume *vol, const char *path, int compress,
                             cdvr_error *err)
{
    return write_mha(vol, path, compress, 1, err);
}

/* ---- VTK XML ImageData ---------------------------------------------------------------------- */

#define VTI_BLOCK 32768 /* vtkZLibDataCompressor's default block size */

static const char *vtk_type(cdvr_type t)
{
    switch (t) {
    case CDVR_TYPE_U8: return "UInt8";
    case CDVR_TYPE_U16: return "UInt16";
    case CDVR_TYPE_I16: return "Int16";
    default: return "Float32";
    }
}

static void put_u64(uint8_t *p, uint64_t v)
{
    memcpy(p, &v, 8); /* host order: byte_order says which */
}

/* The compressed appended block: [UInt64 blocks][UInt64 block size][UInt64 last block size]
 * [UInt64 x blocks: compressed sizes][blocks] (uncompressed, write_vti writes [UInt64 bytes]
 * [data] straight from the volume). */
static cdvr_status vti_zblock(const char *path, const cdvr_volume *vol, size_t bytes,
                              uint8_t **out, size_t *out_n, cdvr_error *err)
{
    size_t nb = (bytes + VTI_BLOCK - 1) / VTI_BLOCK;
    size_t head = 8 * (3 + nb);
    size_t cap = head + nb * (size_t)compressBound(VTI_BLOCK);
    uint8_t *b = malloc(cap);
    if (!b)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot allocate %zu bytes", path, cap);
    put_u64(b, nb);
    put_u64(b + 8, VTI_BLOCK);
    put_u64(b + 16, bytes % VTI_BLOCK);
    size_t at = head;
    const uint8_t *src = vol->data;
    for (size_t i = 0; i < nb; i++) {
        size_t k = i + 1 < nb || bytes % VTI_BLOCK == 0 ? VTI_BLOCK : bytes % VTI_BLOCK;
        uLongf zn = (uLongf)(cap - at);
        if (compress2(b + at, &zn, src + i * VTI_BLOCK, (uLong)k, Z_DEFAULT_COMPRESSION) != Z_OK) {
            free(b);
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: zlib compress failed", path);
        }
        put_u64(b + 24 + 8 * i, zn);
        at += zn;
    }
    *out = b;
    *out_n = at;
    return CDVR_OK;
}

static cdvr_status write_vti(const cdvr_volume *vol, const char *path, int compress,
                             cdvr_error *err)
{
    if (vol->timesteps > 1) /* write_pvd gives it frames */
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: a .vti holds one volume", path);
    size_t bytes = cdvr_volume_frame_bytes(vol);
    uint8_t *block = NULL, size[8];
    size_t block_n = 0;
    cdvr_status st = compress ? vti_zblock(path, vol, bytes, &block, &block_n, err) : CDVR_OK;
    if (st != CDVR_OK)
        return st;
    put_u64(size, bytes);
    double D[9];
    cdvr_volume_direction(vol, D);
    cdvr_atomic_file af;
    st = cdvr_atomic_open(&af, path, err);
    if (st == CDVR_OK) {
        FILE *f = af.f;
        fprintf(f, "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" "
                   "byte_order=\"%s\" header_type=\"UInt64\"%s>\n",
                cdvr_host_is_little_endian() ? "LittleEndian" : "BigEndian",
                compress ? " compressor=\"vtkZLibDataCompressor\"" : "");
        char wattr[96] = "";
        double w[2];
        if (cdvr_u8_window_get(vol, w)) /* cdvr's attribute; VTK skips it */
            snprintf(wattr, sizeof wattr, " CdvrValueWindow=\"%.17g %.17g\"", w[0], w[1]);
        fprintf(f, "  <ImageData WholeExtent=\"0 %zu 0 %zu 0 %zu\" Origin=\"%.17g %.17g %.17g\" "
                   "Spacing=\"%.17g %.17g %.17g\" Direction=\"%.17g %.17g %.17g %.17g %.17g "
                   "%.17g %.17g %.17g %.17g\"%s>\n",
                vol->dims[0] - 1, vol->dims[1] - 1, vol->dims[2] - 1, vol->origin[0],
                vol->origin[1], vol->origin[2], vol->spacing[0], vol->spacing[1],
                vol->spacing[2], D[0], D[1], D[2], D[3], D[4], D[5], D[6], D[7], D[8], wattr);
        fprintf(f, "    <Piece Extent=\"0 %zu 0 %zu 0 %zu\">\n      <PointData "
                   "Scalars=\"scalars\">\n        <DataArray type=\"%s\" Name=\"scalars\" "
                   "NumberOfComponents=\"1\" format=\"appended\" offset=\"0\"/>\n      </PointData>\n      <CellData>\n"
                   "      </CellData>\n    </Piece>\n  </ImageData>\n"
                   "  <AppendedData encoding=\"raw\">\n   _",
                vol->dims[0] - 1, vol->dims[1] - 1, vol->dims[2] - 1, vtk_type(vol->type));
        int ok = block ? cdvr_write_all(f, block, block_n)
                       : cdvr_write_all(f, size, 8) && cdvr_write_all(f, vol->data, bytes);
        fprintf(f, "\n  </AppendedData>\n</VTKFile>\n");
        st = cdvr_atomic_commit(&af, !ok || ferror(f), err);
    }
    free(block);
    return st;
}

/* ---- a series as numbered .vti files and a .pvd collection ---------------------------------- */

/* base_0007.vti (width digits, 4..20) into out. */
static void frame_name(char *out, size_t n, const char *base, int width, size_t t)
{
    char num[24];
    snprintf(num, sizeof num, "%0*zu", width < 4 ? 4 : width > 20 ? 20 : width, t);
    snprintf(out, n, "%s_%s.vti", base, num);
}

/* NAME.pvd (or NAME.vti of a series) -> NAME_0000.vti ... (width: at least 4 digits, more when
 * the count needs them) beside it, each a one-timestep .vti, then NAME.pvd listing them with
 * their times (times[t], else t). A failure removes the files written so far. */
static cdvr_status write_pvd(const cdvr_volume *vol, const char *path, size_t suffix_len,
                             int compress, const double *times, cdvr_error *err)
{
    char *pvd = cdvr_write_sibling(path, suffix_len, ".pvd");
    char *base = cdvr_write_sibling(path, suffix_len, "");
    size_t nt = vol->timesteps, name_max = base ? strlen(base) + 32 : 0;
    char *name = base ? malloc(name_max) : NULL;
    int width = 4;
    for (size_t k = nt - 1; k >= 10000; k /= 10)
        width++;
    cdvr_status st = pvd && base && name ? cdvr_write_check_target(pvd, err)
                                         : cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    size_t written = 0;
    for (; st == CDVR_OK && written < nt; written++) {
        cdvr_volume frame = *vol;
        frame.timesteps = 1;
        frame.data = cdvr_volume_frame(vol, written);
        frame_name(name, name_max, base, width, written);
        st = cdvr_write_check_target(name, err);
        if (st == CDVR_OK)
            st = write_vti(&frame, name, compress, err);
    }
    cdvr_atomic_file af;
    if (st == CDVR_OK && (st = cdvr_atomic_open(&af, pvd, err)) == CDVR_OK) {
        FILE *f = af.f;
        fprintf(f, "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n"
                   "  <Collection>\n");
        for (size_t t = 0; t < nt; t++) {
            frame_name(name, name_max, cdvr_write_basename(base), width, t);
            fprintf(f, "    <DataSet timestep=\"%.17g\" group=\"\" part=\"0\" file=\"%s\"/>\n",
                    times ? times[t] : (double)t, name);
        }
        fprintf(f, "  </Collection>\n</VTKFile>\n");
        st = cdvr_atomic_commit(&af, ferror(f) != 0, err);
    }
    if (st != CDVR_OK && name) /* nothing half-written stays: the frames go again */
        for (size_t t = 0; t < written; t++) {
            frame_name(name, name_max, base, width, t);
            unlink(name);
        }
    free(name);
    free(base);
    free(pvd);
    return st;
}

/* ---- the table ------------------------------------------------------------------------------ */

typedef struct writer {
    const char *suffix;
    cdvr_writer_fn write;
    int compress_default; /* 1: always compressed (.nii.gz), 0: plain by default, -1: never */
} writer;

static const writer writers[] = {
    {".nrrd", cdvr_write_nrrd, 0},    {".nhdr", cdvr_write_nrrd, 0},
    {".nii.gz", cdvr_write_nifti, 1}, {".nii", cdvr_write_nifti, -1},
    {".vti", write_vti, 0},           {".mha", write_mha_local, 0},
    {".mhd", write_mhd, 0},           {".pvd", write_vti, 0}, /* write_pvd, see below */
};

const char *cdvr_save_suffixes(void)
{
    return ".nrrd .nhdr .nii .nii.gz .vti .pvd .mha .mhd";
}

static const writer *writer_for(const char *path)
{
    size_t n = strlen(path);
    for (size_t i = 0; i < sizeof writers / sizeof *writers; i++) {
        size_t k = strlen(writers[i].suffix);
        if (n > k && strcasecmp(path + n - k, writers[i].suffix) == 0)
            return &writers[i];
    }
    return NULL;
}

cdvr_status cdvr_volume_save(const cdvr_volume *vol, const char *path, const cdvr_save_opts *opts,
                             cdvr_error *err)
{
    if (!path || !*path)
        return cdvr_error_set(err, CDVR_ERR_ARG, "save: no file name");
    if (!vol || !vol->data)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: save: no volume", path);
    const writer *w = writer_for(path);
    if (!w)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: cannot save: the name does not end in a "
                              "suffix cdvr writes (%s)", path, cdvr_save_suffixes());
    if ((unsigned)vol->type > CDVR_TYPE_F32 || vol->timesteps < 1 || !vol->dims[0] ||
        !vol->dims[1] || !vol->dims[2])
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: save: not a volume (dims %zux%zux%zu, "
                              "%zu timesteps)", path, vol->dims[0], vol->dims[1], vol->dims[2],
                              vol->timesteps);
    char what[CDVR_ERRMSG_MAX / 2];
    snprintf(what, sizeof what, "%s: save", path);
    cdvr_status st = cdvr_volume_check_geometry(vol, what, err);
    if (st != CDVR_OK)
        return st;
    int compress = opts ? opts->compress : -1;
    if (compress < 0)
        compress = w->compress_default > 0;
    else if (compress && w->compress_default < 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: compress=true: a .nii file is plain; name "
                              "it .nii.gz for gzip", path);
    else if (!compress && w->compress_default > 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: compress=false: a .nii.gz file is gzip; "
                              "name it .nii for a plain one", path);
    size_t n = strlen(path);
    int pvd = strcasecmp(path + n - 4, ".pvd") == 0;
    if (pvd || (w->write == write_vti && vol->timesteps > 1)) /* a .vti series: NAME.pvd */
        return write_pvd(vol, path, 4, compress ? 1 : 0, opts ? opts->times : NULL, err);
    if ((st = cdvr_write_check_target(path, err)) != CDVR_OK)
        return st;
    return w->write(vol, path, compress ? 1 : 0, err);
}
