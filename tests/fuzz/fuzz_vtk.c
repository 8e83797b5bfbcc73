/* tests/fuzz/fuzz_vtk.c - libFuzzer target for the header and XML parsing that is cdvr's own:
 * VTK XML ImageData (core/io/io_vti.c, expat underneath) and legacy VTK (io_vtk.c): bytes ->
 * temporary file -> cdvr_volume_probe and cdvr_volume_load by extension; errors are tolerated,
 * crashes and disagreements between the probe and the load are not. How to run: README.
 *
 * Input: 1 selector byte, then the file. selector % 3: 0 .vti, 1 .vtk, 2 .mha. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/volume.h"
#include "fuzz_common.h"

static const char *const VTK_SUFFIX[3] = {".vti", ".vtk", ".mha"};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    char path[256];
    if (!fuzz_write_temp(data + 1, size - 1, VTK_SUFFIX[data[0] % 3], path))
        return 0;
    cdvr_volume head, *vol = NULL;
    cdvr_error err;
    int probed = cdvr_volume_probe(path, NULL, &head, &err) == CDVR_OK;
    int loaded = cdvr_volume_load(path, NULL, &vol, &err) == CDVR_OK;
    FUZZ_OUTCOME(loaded);
    if (loaded) {
        double lo, hi;
        FUZZ_ASSERT(probed && head.dims[0] == vol->dims[0] && head.dims[1] == vol->dims[1] &&
                    head.dims[2] == vol->dims[2] && head.type == vol->type &&
                    head.timesteps == vol->timesteps);
        cdvr_volume_range(vol, &lo, &hi);
        FUZZ_ASSERT(lo <= hi || (lo == 0 && hi == 0));
        cdvr_volume_free(vol);
    }
    unlink(path);
    return 0;
}
