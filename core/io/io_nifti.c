/* core/io/io_nifti.c - NIfTI-1 (.nii, .nii.gz, .hdr/.img pairs) through niftilib. */
#include "cdvr/regular_file.h"
#include "cdvr/volume.h"
#include "volume_io.h"
#include "cdvr/format.h"

#include <math.h>
#include <errno.h>
#include <float.h>
#include <limits.h>
#include <sys/stat.h>
#include <stdint.h>
#include <nifti1_io.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static double read_u8(const void *p, size_t i) { return ((const uint8_t *)p)[i]; }
static double read_i8(const void *p, size_t i) { return ((const int8_t *)p)[i]; }
static double read_u16(const void *p, size_t i) { return ((const uint16_t *)p)[i]; }
static double read_i16(const void *p, size_t i) { return ((const int16_t *)p)[i]; }
static double read_u32(const void *p, size_t i) { return ((const uint32_t *)p)[i]; }
static double read_i32(const void *p, size_t i) { return ((const int32_t *)p)[i]; }
static double read_u64(const void *p, size_t i) { return (double)((const uint64_t *)p)[i]; }
static double read_i64(const void *p, size_t i) { return (double)((const int64_t *)p)[i]; }
static double read_f32(const void *p, size_t i) { return ((const float *)p)[i]; }
static double read_f64(const void *p, size_t i) { return ((const double *)p)[i]; }

/* Reader for a NIfTI datatype and the type it keeps when no conversion is needed
 * (*native = 0 for the types that become f32). NULL for unsupported datatypes. */
static cdvr_value_reader nifti_reader(int datatype, cdvr_type *type, int *native)
{
    *native = 1;
    switch (datatype) {
    case DT_UINT8: *type = CDVR_TYPE_U8; return read_u8;
    case DT_UINT16: *type = CDVR_TYPE_U16; return read_u16;
    case DT_INT16: *type = CDVR_TYPE_I16; return read_i16;
    case DT_FLOAT32: *type = CDVR_TYPE_F32; return read_f32;
    default: break;
    }
    *native = 0;
    *type = CDVR_TYPE_F32;
    switch (datatype) {
    case DT_INT8: return read_i8;
    case DT_UINT32: return read_u32;
    case DT_INT32: return read_i32;
    case DT_UINT64: return read_u64;
    case DT_INT64: return read_i64;
    case DT_FLOAT64: return read_f64;
    default: return NULL;
    }
}

/* slope/intercept to apply, or 0 when the header sets none (slope 0 or identity). */
static int nifti_scaling(const nifti_image *nim, double *slope, double *inter)
{
    *slope = nim->scl_slope;
    *inter = nim->scl_inter;
    if (!isfinite(*slope) || *slope == 0.0)
        return 0;
    if (!isfinite(*inter))
        *inter = 0.0;
    return !(*slope == 1.0 && *inter == 0.0);
}

static cdvr_status nifti_shape(const char *path, const nifti_image *nim, size_t dims[3],
                               size_t *timesteps, cdvr_error *err)
{
    if (nim->ndim > 4 || nim->nu > 1 || nim->nv > 1 || nim->nw > 1)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NIfTI has %d dimensions (dim[5..7] = %d %d %d): only 3D volumes "
                              "and 4D time series are supported",
                              path, nim->ndim, nim->nu, nim->nv, nim->nw);
    int n[4] = {nim->nx, nim->ny, nim->nz, nim->nt};
    for (int i = 0; i < 4; i++)
        if (n[i] < 1)
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI dim[%d] = %d is not positive",
                                  path, i + 1, n[i]);
    for (int i = 0; i < 3; i++)
        dims[i] = (size_t)n[i];
    *timesteps = (size_t)n[3];
    return CDVR_OK;
}

/* Splits the upper 3x3 of an index-to-world matrix into column lengths (spacing) and unit
 * columns (direction); returns 0 when a column is zero, the matrix singular or not finite. */
static int split_affine(const mat44 *m, double spacing[3], double direction[9])
{
    double M[9];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            M[3 * r + c] = m->m[r][c];
    double inv[9];
    if (!cdvr_mat3_inverse(M, inv))
        return 0;
    for (int c = 0; c < 3; c++) {
        spacing[c] = sqrt(M[c] * M[c] + M[3 + c] * M[3 + c] + M[6 + c] * M[6 + c]);
        for (int r = 0; r < 3; r++)
            direction[3 * r + c] = M[3 * r + c] / spacing[c];
    }
    for (int r = 0; r < 3; r++)
        if (!isfinite(m->m[r][3]))
            return 0;
    return 1;
}

/* Index-to-world matrix as nibabel's get_best_affine chooses it: the sform when sform_code >
 * 0, else the qform (quaternion, qoffset, pixdim and qfac = pixdim[0], niftilib's qto_xyz)
 * when qform_code > 0, else "method 1": spacing |pixdim|, origin 0, no rotation. A transform
 * that is singular or not finite is skipped for the next one. */
/* A u8 volume's value window as cdvr writes it in descrip ("cdvr value window LO HI"; NIfTI
 * has no field for it: cal_min/cal_max are a display range in data units); else [0, 255]. */
static void nifti_u8_window(const nifti_image *nim, cdvr_volume *vol)
{
    if (vol->type != CDVR_TYPE_U8)
        return;
    double lo, hi;
    vol->window[0] = 0;
    vol->window[1] = 255;
    char text[sizeof nim->descrip + 1];
    memcpy(text, nim->descrip, sizeof nim->descrip);
    text[sizeof nim->descrip] = '\0';
    if (sscanf(text, "cdvr value window %lf %lf", &lo, &hi) == 2)
        cdvr_u8_window_set(vol, lo, hi);
}

static void nifti_geometry(const nifti_image *nim, cdvr_volume *vol)
{
    nifti_u8_window(nim, vol);
    cdvr_volume_set_space(vol, nim->sform_code > 0 || nim->qform_code > 0 ? "RAS" : NULL);
    const mat44 *choices[2] = {nim->sform_code > 0 ? &nim->sto_xyz : NULL,
                               nim->qform_code > 0 ? &nim->qto_xyz : NULL};
    for (int i = 0; i < 2; i++) {
        double spacing[3], direction[9];
        if (!choices[i] || !split_affine(choices[i], spacing, direction))
            continue;
        memcpy(vol->spacing, spacing, sizeof spacing);
        memcpy(vol->direction, direction, sizeof direction);
        for (int r = 0; r < 3; r++)
            vol->origin[r] = choices[i]->m[r][3];
        return;
    }
    double pix[3] = {nim->dx, nim->dy, nim->dz};
    for (int i = 0; i < 3; i++)
        if (isfinite(pix[i]) && pix[i] != 0.0)
            vol->spacing[i] = fabs(pix[i]);
}

/* Reads the voxel bytes itself: niftilib pads a short data section with zeros and reports
 * success, and a truncated file must be an error here. */
static cdvr_status read_nifti_data(const char *path, const nifti_image *nim, void *buf, size_t bytes,
                                   cdvr_error *err)
{
    znzFile fp = znzopen(nim->iname, "rb", nifti_is_gzfile(nim->iname));
    if (znz_isnull(fp))
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open NIfTI data file %s", path, nim->iname);
    size_t got = 0;
    if (znzseek(fp, (long)nim->iname_offset, SEEK_SET) >= 0)
        got = znzread(buf, 1, bytes, fp);
    znzclose(fp);
    if (got != bytes)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NIfTI data truncated: %dx%dx%dx%d %s need %zu bytes from offset %d, got %zu",
                              path, nim->nx, nim->ny, nim->nz, nim->nt, nifti_datatype_string(nim->datatype),
                              bytes, nim->iname_offset, got);
    if (nim->swapsize > 1 && nim->byteorder != nifti_short_order())
        nifti_swap_Nbytes(bytes / (size_t)nim->swapsize, nim->swapsize, buf);
    return CDVR_OK;
}

/* Fills vol from the file: straight into vol->data when the type is kept, else through a
 * buffer of file values converted (and scaled) to f32. */
static cdvr_status load_voxels(const char *path, const nifti_image *nim, cdvr_volume *vol,
                               cdvr_value_reader reader, int native, int scaled, double slope,
                               double inter, const cdvr_raw_opts *opts, cdvr_error *err)
{
    size_t count = cdvr_volume_voxels(vol) * vol->timesteps, bytes;
    if (nim->nbyper <= 0 || !cdvr_size_mul(count, (size_t)nim->nbyper, &bytes))
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI data size overflows", path);
    if (native && !scaled)
        return read_nifti_data(path, nim, vol->data, bytes, err);
    void *buf = malloc(bytes ? bytes : 1);
    if (!buf)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot allocate %zu bytes", path, bytes);
    cdvr_status st = read_nifti_data(path, nim, buf, bytes, err);
    float *dst = vol->data;
    double lo = INFINITY, hi = -INFINITY;
    cdvr_f32_guard guard;
    cdvr_f32_guard_init(&guard, opts);
    for (size_t i = 0; st == CDVR_OK && i < count; i++) {
        double v = reader(buf, i), w = scaled ? v * slope + inter : v;
        if (isfinite(w)) {
            lo = w < lo ? w : lo;
            hi = w > hi ? w : hi;
        }
        dst[i] = cdvr_f32_guard_put(&guard, w, i);
    }
    free(buf);
    vol->window[0] = lo <= hi ? lo : 0; /* the window in double (cdvr/volume.h) */
    vol->window[1] = lo <= hi ? hi : 0;
    if (st == CDVR_OK)
        st = cdvr_f32_guard_finish(&guard, path, scaled ? "NIfTI (after scl_slope, scl_inter)" : "NIfTI",
                                   vol->source_type, vol, err);
    return st;
}

/* Refuses headers that claim more voxel data than the file can hold, before anything is
 * allocated: a plain file must hold offset + bytes; a gzip file of n bytes inflates to at most
 * 1032 n (deflate's maximum ratio). */
static cdvr_status check_data_size(const char *path, const nifti_image *nim, cdvr_error *err)
{
    size_t need;
    if (nim->nbyper <= 0 || nim->iname_offset < 0 || !cdvr_size_mul(nim->nvox, (size_t)nim->nbyper, &need) ||
        !cdvr_size_add(need, (size_t)nim->iname_offset, &need))
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI data size overflows", path);
    struct stat sb;
    cdvr_error why;
    if (cdvr_check_regular_file(nim->iname, &sb, &why) != CDVR_OK) /* a .img that is a FIFO or device */
        return cdvr_error_set(err, why.status, "%s: NIfTI data file %s", path, why.msg);
    size_t have = (size_t)sb.st_size;
    if (nifti_is_gzfile(nim->iname)) {
        if (have > SIZE_MAX / 1032 || need / 1032 <= have)
            return CDVR_OK;
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NIfTI header claims %zu bytes of voxel data (%dx%dx%dx%d %s), more than a %zu-byte gzip "
                              "file can hold",
                              path, need, nim->nx, nim->ny, nim->nz, nim->nt, nifti_datatype_string(nim->datatype), have);
    }
    if (need <= have)
        return CDVR_OK;
    return cdvr_error_set(err, CDVR_ERR_FORMAT,
                          "%s: NIfTI data truncated: header claims %dx%dx%dx%d %s = %zu bytes with the header, file has %zu",
                          path, nim->nx, nim->ny, nim->nz, nim->nt, nifti_datatype_string(nim->datatype), need, have);
}

#define NIFTI_EXTENSIONS_MAX 1024 /* niftilib reads extensions in quadratic time */

/* Counts the header extensions from the file's bytes (niftilib reads each with a realloc of the
 * list: 100000 of them take over a minute), up to one past the limit. */
static cdvr_status count_extensions(const char *path, const nifti_1_header *h, int swapped,
                                    cdvr_error *err)
{
    znzFile fp = znzopen(path, "rb", nifti_is_gzfile(path));
    if (znz_isnull(fp))
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open", path);
    unsigned char ext[4] = {0, 0, 0, 0};
    size_t count = 0;
    long pos = 352, end = h->magic[1] == '+' ? (long)h->vox_offset : LONG_MAX;
    if (znzseek(fp, 348, SEEK_SET) >= 0 && znzread(ext, 1, 4, fp) == 4 && ext[0] != 0) {
        while (count <= NIFTI_EXTENSIONS_MAX && pos + 8 <= end) {
            int32_t sz[2];
            if (znzread(sz, 1, 8, fp) != 8)
                break;
            if (swapped)
                nifti_swap_4bytes(2, sz);
            if (sz[0] < 16 || sz[0] % 16 != 0 || sz[0] > end - pos)
                break; /* niftilib stops at the first bad one too */
            count++;
            pos += sz[0];
            if (znzseek(fp, pos, SEEK_SET) < 0)
                break;
        }
    }
    znzclose(fp);
    if (count > NIFTI_EXTENSIONS_MAX)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI header has more than %d "
                              "extensions (the limit)", path, NIFTI_EXTENSIONS_MAX);
    return CDVR_OK;
}

static int nifti_is_hdr(const char *path)
{
    size_t n = strlen(path);
    return n >= 4 && strcasecmp(path + n - 4, ".hdr") == 0;
}

/* The geometry fields that niftilib replaces silently (a singular sform by the qform or the
 * identity, pixdim <= 0 or not finite by 1): refused when they are the ones used. */
static cdvr_status check_geometry_fields(const char *path, const nifti_1_header *h,
                                         cdvr_error *err)
{
    if (h->sform_code > 0) {
        double M[9], inv[9];
        const float *rows[3] = {h->srow_x, h->srow_y, h->srow_z};
        int finite = 1;
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++) {
                finite &= isfinite(rows[r][c]);
                if (c < 3)
                    M[3 * r + c] = rows[r][c];
            }
        if (!finite || !cdvr_mat3_inverse(M, inv))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI sform (sform_code %d) is %s: "
                                  "srow_x %g %g %g, srow_y %g %g %g, srow_z %g %g %g", path,
                                  h->sform_code, finite ? "singular" : "not finite",
                                  M[0], M[1], M[2], M[3], M[4], M[5], M[6], M[7], M[8]);
        return CDVR_OK;
    }
    int axes = h->dim[0] < 3 ? h->dim[0] : 3;
    for (int i = 1; i <= axes; i++) {
        double p = h->pixdim[i];
        if (!isfinite(p) || p == 0 || (h->qform_code > 0 && p < 0))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI pixdim[%d] = %g is not a "
                                  "voxel size (%s)", path, i, p,
                                  h->qform_code > 0 ? "the qform needs it > 0" : "finite, nonzero");
    }
    if (h->qform_code > 0) {
        double b = h->quatern_b, c = h->quatern_c, d = h->quatern_d;
        if (!isfinite(b) || !isfinite(c) || !isfinite(d) || b * b + c * c + d * d > 1.0 + 1e-6 ||
            !isfinite(h->qoffset_x) || !isfinite(h->qoffset_y) || !isfinite(h->qoffset_z))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI qform (qform_code %d) is not a "
                                  "rotation: quatern %g %g %g, qoffset %g %g %g", path,
                                  h->qform_code, b, c, d, (double)h->qoffset_x,
                                  (double)h->qoffset_y, (double)h->qoffset_z);
    }
    return CDVR_OK;
}

/* Refuses what niftilib lets through in the raw header (it reads dim[0] = 0 as a 1x1x1 volume,
 * clamps a negative, NaN or small vox_offset to 352 and truncates a fractional one, loads a file
 * with a bad magic, and takes any sizeof_hdr): sizeof_hdr must be 348 (540 is NIfTI-2, which
 * niftilib's NIfTI-1 reader misreads), the magic "n+1" or "ni1" (all zero only in a .hdr:
 * ANALYZE 7.5), dim[0] 1..7, vox_offset a whole number of bytes, >= 352 in a .nii, within the
 * file; at most NIFTI_EXTENSIONS_MAX extensions; the geometry fields as check_geometry_fields. */
static cdvr_status check_raw_header(const char *path, cdvr_error *err)
{
    int swapped = 0;
    nifti_1_header *h = nifti_read_header(path, &swapped, 0);
    if (!h)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: cannot read a NIfTI-1 header", path);
    cdvr_status st = CDVR_OK;
    int one_file = h->magic[1] == '+';
    int zero_magic = !h->magic[0] && !h->magic[1] && !h->magic[2] && !h->magic[3];
    struct stat sb;
    int sized = stat(path, &sb) == 0;
    if (h->sizeof_hdr != 348)
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI sizeof_hdr is %d, not 348%s", path, h->sizeof_hdr,
                            h->sizeof_hdr == 540 ? " (540 is NIfTI-2's; cdvr reads NIfTI-1)" : "");
    else if (!(memcmp(h->magic, "n+1", 4) == 0 || memcmp(h->magic, "ni1", 4) == 0 ||
               (zero_magic && nifti_is_hdr(path))))
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI magic is \"%.4s\" (bytes %02x %02x "
                            "%02x %02x), not \"n+1\" or \"ni1\"", path, h->magic,
                            (unsigned char)h->magic[0], (unsigned char)h->magic[1],
                            (unsigned char)h->magic[2], (unsigned char)h->magic[3]);
    else if (h->dim[0] < 1 || h->dim[0] > 7)
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI dim[0] = %d (the number of dimensions) is not 1..7",
                            path, h->dim[0]);
    else if (!isfinite(h->vox_offset) || h->vox_offset < 0 || h->vox_offset != floorf(h->vox_offset) ||
             (one_file && h->vox_offset < 352) || h->vox_offset > 2147483647.0f ||
             (one_file && sized && !nifti_is_gzfile(path) && h->vox_offset > (double)sb.st_size))
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI vox_offset %.7g is not a byte offset "
                            "(a whole number%s, within the file)", path, (double)h->vox_offset,
                            one_file ? " >= 352" : " >= 0");
    if (st == CDVR_OK)
        st = check_geometry_fields(path, h, err);
    if (st == CDVR_OK)
        st = count_extensions(path, h, swapped, err);
    free(h);
    return st;
}

/* niftilib finds a file by its name (it appends .nii, .hdr, ... to a name without them), so a
 * NIfTI file told by its first bytes (cdvr/format.h) must still have one of these. */
static cdvr_status check_suffix(const char *path, cdvr_error *err)
{
    static const char *const suffixes[] = {".nii", ".nii.gz", ".hdr"};
    size_t n = strlen(path);
    for (size_t i = 0; i < sizeof suffixes / sizeof *suffixes; i++) {
        size_t k = strlen(suffixes[i]);
        if (n >= k && strcasecmp(path + n - k, suffixes[i]) == 0)
            return CDVR_OK;
    }
    return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: a NIfTI file by its first bytes, but "
                          "niftilib opens NIfTI files only by a name ending in .nii, .nii.gz or "
                          ".hdr (rename or link it)", path);
}

/* Opens path's header after the checks niftilib does not make (header only, no voxels). */
static cdvr_status open_header(const char *path, nifti_image **nim, cdvr_error *err)
{
    *nim = NULL;
    cdvr_status st = check_suffix(path, err);
    if (st == CDVR_OK)
        st = cdvr_check_readable(path, err);
    if (st == CDVR_OK)
        st = check_raw_header(path, err);
    if (st != CDVR_OK)
        return st;
    *nim = nifti_image_read(path, 0);
    if (!*nim)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: cannot read NIfTI header: not a NIfTI-1 file or corrupt "
                              "(niftilib's reason is on stderr)",
                              path);
    return CDVR_OK;
}

/* The file type name of a NIfTI datatype (cdvr_volume.source_type), or NULL. */
static const char *nifti_file_type(int datatype)
{
    switch (datatype) {
    case DT_UINT8: return "uint8";
    case DT_INT8: return "int8";
    case DT_UINT16: return "uint16";
    case DT_INT16: return "int16";
    case DT_UINT32: return "uint32";
    case DT_INT32: return "int32";
    case DT_UINT64: return "uint64";
    case DT_INT64: return "int64";
    case DT_FLOAT32: return "float32";
    case DT_FLOAT64: return "float64";
    default: return NULL;
    }
}

/* How the header's values become ours: the datatype's reader and the scaling. */
typedef struct {
    cdvr_value_reader reader;
    int native, scaled;
    double slope, inter;
} nifti_values;

/* Fills head's dims, timesteps and type from the header, and vals; checks the data size
 * against the file. */
static cdvr_status describe(const char *path, const nifti_image *nim, cdvr_volume *head,
                            nifti_values *vals, uint64_t max_bytes, cdvr_error *err)
{
    vals->reader = nifti_reader(nim->datatype, &head->type, &vals->native);
    if (!vals->reader)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI datatype %s (%d) is not supported",
                              path, nifti_datatype_string(nim->datatype), nim->datatype);
    vals->scaled = nifti_scaling(nim, &vals->slope, &vals->inter);
    if (vals->scaled)
        head->type = CDVR_TYPE_F32;
    cdvr_volume_set_source_type(head, nifti_file_type(nim->datatype));
    cdvr_status st = nifti_shape(path, nim, head->dims, &head->timesteps, err);
    if (st == CDVR_OK)
        st = check_data_size(path, nim, err);
    size_t bytes;
    if (st == CDVR_OK && (!cdvr_volume_bytes_for(head->dims, head->timesteps, head->type, &bytes) ||
                          bytes > max_bytes || (uint64_t)nim->nvox * (uint64_t)nim->nbyper > max_bytes))
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI header claims %dx%dx%dx%d %s, more "
                            "than max_bytes %llu (a load option; the default is half the physical "
                            "memory)", path, nim->nx, nim->ny, nim->nz, nim->nt,
                            nifti_datatype_string(nim->datatype), (unsigned long long)max_bytes);
    return st;
}

static cdvr_status nifti_to_volume(const char *path, const nifti_image *nim,
                                   const cdvr_raw_opts *opts, cdvr_volume **out, cdvr_error *err)
{
    cdvr_volume head = {0};
    nifti_values vals;
    cdvr_status st = describe(path, nim, &head, &vals, cdvr_load_max_bytes(opts), err);
    if (st == CDVR_OK)
        st = cdvr_volume_create(head.dims, head.timesteps, head.type, out, err);
    if (st != CDVR_OK)
        return st;
    if (nim->nvox != cdvr_volume_voxels(*out) * head.timesteps) {
        cdvr_volume_free(*out);
        *out = NULL;
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NIfTI voxel count %zu does not match its dims",
                              path, nim->nvox);
    }
    memcpy((*out)->source_type, head.source_type, sizeof head.source_type); /* names the type */
    st = load_voxels(path, nim, *out, vals.reader, vals.native, vals.scaled, vals.slope, vals.inter,
                     opts, err);
    if (st != CDVR_OK) {
        cdvr_volume_free(*out);
        *out = NULL;
        return st;
    }
    nifti_geometry(nim, *out);
    memcpy((*out)->source_type, head.source_type, sizeof head.source_type);
    return CDVR_OK;
}

static cdvr_status load_nifti(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                              cdvr_error *err)
{
    *out = NULL;
    nifti_image *nim;
    cdvr_status st = open_header(path, &nim, err);
    if (st != CDVR_OK)
        return st;
    st = nifti_to_volume(path, nim, opts, out, err);
    nifti_image_free(nim);
    return st;
}

cdvr_status cdvr_volume_load_nifti(const char *path, cdvr_volume **out, cdvr_error *err)
{
    return load_nifti(path, NULL, out, err);
}

cdvr_status cdvr_volume_probe_nifti(const char *path, cdvr_volume *head, cdvr_error *err)
{
    nifti_image *nim;
    cdvr_status st = open_header(path, &nim, err);
    if (st != CDVR_OK)
        return st;
    nifti_values vals;
    st = describe(path, nim, head, &vals, UINT64_MAX, err); /* a probe allocates nothing */
    if (st == CDVR_OK)
        nifti_geometry(nim, head);
    nifti_image_free(nim);
    return st;
}

/* ---- format table (cdvr/format.h) ----------------------------------------------------------- */

static uint32_t u32_either(const uint8_t *p, int big)
{
    return big ? (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]
               : (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 | (uint32_t)p[1] << 8 | p[0];
}

/* An uncompressed NIfTI-1 header (sizeof_hdr 348, magic "n+1" or "ni1" at byte 344) or NIfTI-2
 * header (540, "n+2" or "ni2" at byte 4), in either byte order. .nii.gz is told by its name. */
static int nifti_magic(const uint8_t *head, size_t n)
{
    for (int big = 0; big < 2; big++) {
        uint32_t size = n >= 4 ? u32_either(head, big) : 0;
        if (size == 348 && n >= 348 &&
            (memcmp(head + 344, "n+1", 4) == 0 || memcmp(head + 344, "ni1", 4) == 0))
            return 1;
        if (size == 540 && n >= 8 &&
            (memcmp(head + 4, "n+2", 4) == 0 || memcmp(head + 4, "ni2", 4) == 0))
            return 1;
    }
    return 0;
}

static cdvr_status nifti_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                               cdvr_error *err)
{
    (void)opts;
    return cdvr_volume_probe_nifti(path, head, err);
}

static cdvr_status nifti_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                              cdvr_error *err)
{
    return load_nifti(path, opts, out, err);
}

static const char *const nifti_suffixes[] = {".nii", ".nii.gz", ".hdr", NULL};

const cdvr_format cdvr_format_nifti = {
    .name = "nifti",
    .description = "NIfTI-1 through niftilib (.nii, .nii.gz, .hdr/.img pairs); 3D, or 4D (time)",
    .suffixes = nifti_suffixes,
    .magic = nifti_magic,
    .probe = nifti_probe,
    .load = nifti_load,
};
