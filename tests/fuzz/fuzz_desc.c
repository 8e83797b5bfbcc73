/* tests/fuzz/fuzz_desc.c - libFuzzer target for the description parsers that are cdvr's own:
 * ParaView collections (cdvr_pvd_parse, core/io/io_pvd.c) and TIFF ImageDescriptions
 * (cdvr_tiff_ome_parse, cdvr_tiff_imagej_parse, core/io/tiff_desc.c), from memory; errors are
 * tolerated, crashes and results outside their documented ranges are not. How to run: README.
 *
 * Input: 1 selector byte, then the text. selector % 3: 0 .pvd, 1 OME-XML (3 pages), 2 ImageJ. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/pvd.h"
#include "cdvr/tiff.h"
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const char *text = (const char *)data + 1;
    size_t len = size - 1;
    cdvr_error err;
    switch (data[0] % 3) {
    case 0: {
        cdvr_pvd_entry *e = NULL;
        size_t n = 0;
        int ok = cdvr_pvd_parse("fuzz.pvd", text, len, &e, &n, &err) == CDVR_OK;
        FUZZ_OUTCOME(ok);
        if (ok) {
            FUZZ_ASSERT(n > 0 && e != NULL);
            for (size_t i = 0; i < n; i++)
                FUZZ_ASSERT(e[i].file != NULL && e[i].time == e[i].time);
            cdvr_pvd_free(e, n);
        }
        break;
    }
    case 1: {
        cdvr_tiff_desc d;
        memset(&d, 0, sizeof d);
        int ok = cdvr_tiff_ome_parse("fuzz.ome.tif", text, len, 3, &d, &err) == CDVR_OK;
        FUZZ_OUTCOME(ok);
        if (ok)
            for (int a = 0; a < 3; a++)
                FUZZ_ASSERT(d.spacing[a] >= 0 && d.spacing[a] == d.spacing[a]);
        break;
    }
    default: {
        cdvr_tiff_desc d;
        memset(&d, 0, sizeof d);
        int ok = cdvr_tiff_imagej_parse(text, len, &d) != 0;
        FUZZ_OUTCOME(ok);
        if (ok)
            FUZZ_ASSERT(d.spacing[2] >= 0 && memchr(d.unit, 0, sizeof d.unit) != NULL);
        break;
    }
    }
    return 0;
}
