/* core/io/write_nifti.c - NIfTI-1 writer through niftilib (cdvr/write.h): the header is
 * niftilib's (nifti_make_new_nim, nifti_convert_nim2nhdr), written with the voxels through
 * zlib's gzip stream for .nii.gz) into the atomic file. One file ("n+1", vox_offset 352, no
 * extensions).
 *
 * Geometry, the inverse of io_nifti.c's nifti_geometry (which takes the sform first): sform
 * rows = D * diag(spacing) | origin, sform_code 1 (NIFTI_XFORM_SCANNER_ANAT); the qform (code 1)
 * from the same matrix by nifti_mat44_to_quatern (qfac -1 for a left-handed D; for a D that is
 * not orthonormal it is the nearest rotation, and the sform is what readers that honour it use);
 * pixdim[1..3] = spacing, pixdim[4] = 1 for a series. No scaling (scl_slope 0). */
#include "cdvr/atomicfile.h"
#include "volume_io.h"
#include "write_io.h"

#include <nifti1_io.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

static int nifti_type_of(cdvr_type t)
{
    switch (t) {
    case CDVR_TYPE_U8: return DT_UINT8;
    case CDVR_TYPE_U16: return DT_UINT16;
    case CDVR_TYPE_I16: return DT_INT16;
    default: return DT_FLOAT32;
    }
}

/* The header niftilib makes of vol's shape and geometry. */
static cdvr_status make_header(const cdvr_volume *vol, const char *path, nifti_1_header *out,
                               cdvr_error *err)
{
    const size_t n[4] = {vol->dims[0], vol->dims[1], vol->dims[2], vol->timesteps};
    for (int i = 0; i < 4; i++)
        if (n[i] > 32767)
            return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: NIfTI-1 dims are 16-bit: %s "
                                  "%zu is more than 32767", path, i < 3 ? "a dim of" : "timesteps",
                                  n[i]);
    int dims[8] = {vol->timesteps > 1 ? 4 : 3, (int)n[0], (int)n[1], (int)n[2], (int)n[3], 1, 1, 1};
    nifti_image *nim = nifti_make_new_nim(dims, nifti_type_of(vol->type), 0);
    if (!nim)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: niftilib cannot make a header", path);
    /* niftilib leaves the unused dims 0; readers (ours, niftilib's nt) want 1 */
    for (int i = dims[0] + 1; i < 8; i++)
        nim->dim[i] = 1;
    nim->nt = nim->nu = nim->nv = nim->nw = 1;
    nim->nt = (int)n[3];
    double M[9];
    cdvr_write_matrix(vol, M);
    /* NIfTI's world is RAS+: a volume known to be LPS (DICOM) or LAS turns its x (and for LPS
     * y) around; one of unknown world is written as it is */
    double flip[3] = {1, 1, 1};
    if (!strcmp(vol->space, "LPS") || !strcmp(vol->space, "LAS"))
        flip[0] = -1;
    if (!strcmp(vol->space, "LPS"))
        flip[1] = -1;
    mat44 s;
    memset(&s, 0, sizeof s);
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++)
            s.m[r][c] = (float)(flip[r] * M[3 * r + c]);
        s.m[r][3] = (float)(flip[r] * vol->origin[r]);
    }
    s.m[3][3] = 1.0f;
    nim->sform_code = NIFTI_XFORM_SCANNER_ANAT;
    nim->sto_xyz = s;
    nim->sto_ijk = nifti_mat44_inverse(s);
    float qb, qc, qd, qx, qy, qz, dx, dy, dz, qfac;
    nifti_mat44_to_quatern(s, &qb, &qc, &qd, &qx, &qy, &qz, &dx, &dy, &dz, &qfac);
    nim->qform_code = NIFTI_XFORM_SCANNER_ANAT;
    nim->quatern_b = qb;
    nim->quatern_c = qc;
    nim->quatern_d = qd;
    nim->qoffset_x = qx;
    nim->qoffset_y = qy;
    nim->qoffset_z = qz;
    nim->qfac = qfac;
    nim->dx = nim->pixdim[1] = (float)vol->spacing[0];
    nim->dy = nim->pixdim[2] = (float)vol->spacing[1];
    nim->dz = nim->pixdim[3] = (float)vol->spacing[2];
    nim->dt = nim->pixdim[4] = 1.0f;
    nim->qto_xyz = nifti_quatern_to_mat44(qb, qc, qd, qx, qy, qz, nim->dx, nim->dy, nim->dz, qfac);
    nim->qto_ijk = nifti_mat44_inverse(nim->qto_xyz);
    nim->xyz_units = NIFTI_UNITS_MM;
    nim->time_units = vol->timesteps > 1 ? NIFTI_UNITS_SEC : NIFTI_UNITS_UNKNOWN;
    nim->scl_slope = 0.0f;
    nim->scl_inter = 0.0f;
    nim->nifti_type = NIFTI_FTYPE_NIFTI1_1;
    nim->iname_offset = 352;
    double w[2];
    if (cdvr_u8_window_get(vol, w)) /* read back by io_nifti.c (NIfTI has no such field) */
        snprintf(nim->descrip, sizeof nim->descrip, "cdvr value window %.17g %.17g", w[0], w[1]);
    else
        snprintf(nim->descrip, sizeof nim->descrip, "cdvr");
    *out = nifti_convert_nim2nhdr(nim);
    nifti_image_free(nim);
    return CDVR_OK;
}

cdvr_status cdvr_write_nifti(const cdvr_volume *vol, const char *path, int compress,
                             cdvr_error *err)
{
    size_t bytes = cdvr_volume_frame_bytes(vol) * vol->timesteps;
    nifti_1_header h;
    cdvr_status st = make_header(vol, path, &h, err);
    if (st != CDVR_OK)
        return st;
    cdvr_atomic_file af;
    if ((st = cdvr_atomic_open(&af, path, err)) != CDVR_OK)
        return st;
    static const char ext[4] = {0, 0, 0, 0}; /* no extensions */
    int ok = 0;
    if (!compress) {
        ok = cdvr_write_all(af.f, &h, sizeof h) && cdvr_write_all(af.f, ext, 4) &&
             cdvr_write_all(af.f, vol->data, bytes);
    } else {
        int fd = dup(fileno(af.f)); /* gzclose closes it; af keeps its own */
        gzFile z = fd >= 0 ? gzdopen(fd, "wb") : NULL;
        if (!z && fd >= 0)
            close(fd);
        if (z) {
            ok = gzwrite(z, &h, sizeof h) == (int)sizeof h && gzwrite(z, ext, 4) == 4;
            const char *p = vol->data;
            for (size_t done = 0; ok && done < bytes;) {
                size_t k = bytes - done < ((size_t)1 << 28) ? bytes - done : (size_t)1 << 28;
                ok = gzwrite(z, p + done, (unsigned)k) == (int)k;
                done += k;
            }
            ok = gzclose(z) == Z_OK && ok;
        }
    }
    return cdvr_atomic_commit(&af, !ok, err);
}
