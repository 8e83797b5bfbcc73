/* core/io/write_nrrd.c - NRRD writer through teem (cdvr/write.h): .nrrd with the voxels after
 * the header, .nhdr with them in NAME.raw (NAME.raw.gz) beside it. The header is teem's
 * (nrrdWrite into the atomic file); for .nhdr teem writes the header only (skipData, with
 * "data file:" naming the data file) and the data file is written here, raw or as a gzip
 * stream, which is what teem's gzip encoding reads. */
#include "cdvr/atomicfile.h"
#include "volume_io.h"
#include "write_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <teem/nrrd.h>
#include <unistd.h>

static int nrrd_type(cdvr_type t)
{
    switch (t) {
    case CDVR_TYPE_U8: return nrrdTypeUChar;
    case CDVR_TYPE_U16: return nrrdTypeUShort;
    case CDVR_TYPE_I16: return nrrdTypeShort;
    default: return nrrdTypeFloat;
    }
}

/* The NRRD space of a volume's known world (cdvr_volume.space: RAS, LAS or LPS). */
static int nrrd_space(const char *space)
{
    if (!strcmp(space, "RAS"))
        return nrrdSpaceRightAnteriorSuperior;
    if (!strcmp(space, "LAS"))
        return nrrdSpaceLeftAnteriorSuperior;
    return nrrdSpaceLeftPosteriorSuperior;
}

static cdvr_status teem_fail(const char *path, const char *what, cdvr_error *err)
{
    char *msg = biffGetDone(NRRD);
    if (msg)
        cdvr_teem_reason(msg);
    cdvr_status st = cdvr_error_set(err, CDVR_ERR_IO, "%s: teem cannot %s: %s", path, what,
                                    msg && *msg ? msg : "(no reason given)");
    free(msg);
    return st;
}

/* The nrrd header of vol (wrapping its voxels, not copying them). */
static cdvr_status make_nrrd(const cdvr_volume *vol, const char *path, Nrrd **out,
                             cdvr_error *err)
{
    Nrrd *n = nrrdNew();
    if (!n)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    size_t sizes[4] = {vol->dims[0], vol->dims[1], vol->dims[2], vol->timesteps};
    unsigned dim = vol->timesteps > 1 ? 4 : 3;
    if (nrrdWrap_nva(n, vol->data, nrrd_type(vol->type), dim, sizes) ||
        (vol->space[0] ? nrrdSpaceSet(n, nrrd_space(vol->space)) : nrrdSpaceDimensionSet(n, 3))) {
        nrrdNix(n);
        return teem_fail(path, "describe the volume", err);
    }
    double M[9];
    cdvr_write_matrix(vol, M);
    for (unsigned ax = 0; ax < 3; ax++) {
        n->axis[ax].kind = nrrdKindSpace;
        for (int r = 0; r < 3; r++)
            n->axis[ax].spaceDirection[r] = M[3 * r + ax];
    }
    if (dim == 4) {
        n->axis[3].kind = nrrdKindTime;
        nrrdSpaceVecSetNaN(n->axis[3].spaceDirection);
    }
    for (int r = 0; r < 3; r++)
        n->spaceOrigin[r] = vol->origin[r];
    double w[2];
    if (cdvr_u8_window_get(vol, w)) { /* "old min"/"old max": the values the codes came from */
        n->oldMin = w[0];
        n->oldMax = w[1];
    }
    *out = n;
    return CDVR_OK;
}

cdvr_status cdvr_write_nrrd(const cdvr_volume *vol, const char *path, int compress, cdvr_error *err)
{
    size_t len = strlen(path);
    int detached = len >= 5 && strcasecmp(path + len - 5, ".nhdr") == 0;
    char *data_path = NULL;
    cdvr_status st = CDVR_OK;
    if (compress && !nrrdEncodingGzip->available())
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: this teem has no gzip encoding",
                              path);
    if (detached) {
        data_path = cdvr_write_sibling(path, 5, compress ? ".raw.gz" : ".raw");
        if (!data_path)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
        if ((st = cdvr_write_check_target(data_path, err)) != CDVR_OK) {
            free(data_path);
            return st;
        }
    }
    Nrrd *n = NULL;
    NrrdIoState *nio = nrrdIoStateNew();
    if (!nio)
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (st == CDVR_OK)
        st = make_nrrd(vol, path, &n, err);
    if (st == CDVR_OK) {
        nio->format = nrrdFormatNRRD;
        nio->encoding = compress ? nrrdEncodingGzip : nrrdEncodingRaw;
        nio->endian = airMyEndian();
        if (detached) {
            nio->detachedHeader = AIR_TRUE;
            nio->skipData = AIR_TRUE;
            unsigned idx = airArrayLenIncr(nio->dataFNArr, 1);
            nio->dataFN[idx] = airStrdup(cdvr_write_basename(data_path));
            size_t bytes;
            if (!cdvr_volume_bytes_for(vol->dims, vol->timesteps, vol->type, &bytes))
                st = cdvr_error_set(err, CDVR_ERR_ARG, "%s: volume size overflows", path);
            else
                st = cdvr_write_data_file(data_path, vol->data, bytes, compress ? 1 : 0, err);
        }
    }
    if (st == CDVR_OK) {
        cdvr_atomic_file af;
        st = cdvr_atomic_open(&af, path, err);
        if (st == CDVR_OK) {
            cdvr_error why;
            int failed = nrrdWrite(af.f, n, nio) != 0;
            if (failed)
                teem_fail(path, "write the NRRD", &why);
            st = cdvr_atomic_commit(&af, failed, err);
            if (failed) {
                st = why.status;
                if (err)
                    *err = why;
            }
        }
        if (st != CDVR_OK && detached)
            unlink(data_path); /* the header failed: its data file goes too */
    }
    if (n)
        nrrdNix(n); /* the voxels stay the volume's */
    if (nio)
        nrrdIoStateNix(nio);
    free(data_path);
    return st;
}
