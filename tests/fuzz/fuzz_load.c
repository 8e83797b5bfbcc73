/* tests/fuzz/fuzz_load.c - libFuzzer target for the volume loaders (core/io/io_raw.c, io_nrrd.c
 * through teem, io_nifti.c through niftilib): bytes -> temporary file -> cdvr_volume_load by
 * extension; errors are tolerated, crashes are not. How to run: README.
 *
 * Input: 1 selector byte, then (raw only) 8 option bytes, then the file.
 *   selector % 6: 0 .nrrd, 1 .nhdr, 2 .nii, 3 .nii.gz (the rest gzipped by the target, so
 *   mutations reach the NIfTI parser), 4 .nii.gz (the rest as it is: bad gzip), 5 .raw
 *   raw option bytes: X, Y, Z (1 + byte % 32), type (% 4), big endian (bit 0 of byte 4),
 *   header bytes (byte 5 % 64), timesteps (byte 6 % 4), spacing (byte 7 / 16)
 * A loaded volume is read through once (range, frame pointers). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#include "cdvr/volume.h"
#include "fuzz_common.h"

static const char *const LOAD_SUFFIX[6] = {".nrrd", ".nhdr", ".nii", ".nii.gz", ".nii.gz", ".raw"};

static void load_raw_opts(const uint8_t *b, cdvr_raw_opts *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 0; i < 3; i++) {
        o->dims[i] = 1 + b[i] % 32u;
        o->spacing[i] = b[7] / 16.0;
    }
    o->type = (cdvr_type)(b[3] % 4);
    o->big_endian = b[4] & 1;
    o->header_bytes = b[5] % 64u;
    o->timesteps = b[6] % 4u;
}

/* data gzipped into a temporary .nii.gz file. */
static int load_write_gzip(const uint8_t *data, size_t size, char path[256])
{
    if (!fuzz_write_temp(NULL, 0, ".nii.gz", path))
        return 0;
    gzFile gz = gzopen(path, "wb");
    int ok = gz && (size == 0 || gzwrite(gz, data, (unsigned)size) == (int)size);
    if (gz && gzclose(gz) != Z_OK)
        ok = 0;
    if (!ok)
        unlink(path);
    return ok;
}

static void load_touch(const cdvr_volume *vol)
{
    double lo, hi;
    cdvr_volume_range(vol, &lo, &hi);
    FUZZ_ASSERT(cdvr_volume_frame(vol, vol->timesteps - 1) != NULL);
    FUZZ_ASSERT(cdvr_volume_frame(vol, vol->timesteps) == NULL);
    FUZZ_ASSERT(lo <= hi || (lo == 0 && hi == 0));
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    int kind = data[0] % 6;
    cdvr_raw_opts opts;
    size_t skip = 1;
    if (kind == 5) {
        if (size < 9)
            return 0;
        load_raw_opts(data + 1, &opts);
        skip = 9;
    }
    char path[256];
    int written = kind == 3 ? load_write_gzip(data + skip, size - skip, path)
                            : fuzz_write_temp(data + skip, size - skip, LOAD_SUFFIX[kind], path);
    if (!written)
        return 0;
    cdvr_volume *vol = NULL;
    cdvr_error err;
    int loaded = cdvr_volume_load(path, kind == 5 ? &opts : NULL, &vol, &err) == CDVR_OK;
    FUZZ_OUTCOME(loaded);
    if (loaded) {
        load_touch(vol);
        cdvr_volume_free(vol);
    }
    unlink(path);
    return 0;
}
