/* tests/spec.h - variant specs for the tests that encode stores through the codec table. */
#ifndef CDVR_TESTS_SPEC_H
#define CDVR_TESTS_SPEC_H

#include <string.h>

#include "cdvr/pvtc.h"
#include "cdvr/store.h"

static inline cdvr_variant_spec spec_pvtc(int S, int T, cdvr_pack pack, cdvr_pvtc_encoder enc,
                                          cdvr_stage2 stage2, double lzo_min_saving)
{
    cdvr_variant_spec v;
    memset(&v, 0, sizeof v);
    v.codec = cdvr_codec_find("pvtc");
    cdvr_pvtc_params p = {S, T, pack};
    cdvr_pvtc_params_to_blob(&p, enc, &v.params);
    v.stage2 = stage2;
    v.lzo_min_saving = lzo_min_saving;
    return v;
}

static inline cdvr_variant_spec spec_codec(const char *codec, cdvr_stage2 stage2,
                                           double lzo_min_saving)
{
    cdvr_variant_spec v;
    memset(&v, 0, sizeof v);
    v.codec = cdvr_codec_find(codec);
    if (v.codec)
        v.codec->params_default(&v.params);
    v.stage2 = stage2;
    v.lzo_min_saving = lzo_min_saving;
    return v;
}

#endif
