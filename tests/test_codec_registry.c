/* tests/test_codec_registry.c - core/codec/registry.c: built-ins present, lookups by name
 * and id, refusals of bad tables and clashes, parameter parsing through the table. */
#include "cdvr/codec.h"
#include "check.h"

#include <string.h>

static cdvr_codec fake(const char *name, uint32_t id)
{
    cdvr_codec c = *cdvr_codec_find("raw");
    c.name = name;
    c.id = id;
    return c;
}

int main(void)
{
    CHECK(cdvr_codec_count() >= 2, "%zu codecs", cdvr_codec_count());
    const cdvr_codec *raw = cdvr_codec_find("raw"), *pvtc = cdvr_codec_find("pvtc");
    CHECK(raw && raw->id == CDVR_CODEC_ID_RAW, "raw");
    CHECK(pvtc && pvtc->id == CDVR_CODEC_ID_PVTC, "pvtc");
    CHECK(cdvr_codec_by_id(CDVR_CODEC_ID_PVTC) == pvtc, "by id");
    CHECK(cdvr_codec_find("nope") == NULL && cdvr_codec_by_id(999) == NULL, "absent");
    CHECK(cdvr_codec_at(0) == raw && cdvr_codec_at(1) == pvtc, "order");

    cdvr_error err;
    static cdvr_codec clash_name, clash_id, bad_name, ok;
    clash_name = fake("pvtc", 77);
    CHECK(cdvr_codec_register(&clash_name, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "already registered"), "%s", err.msg);
    clash_id = fake("other", CDVR_CODEC_ID_PVTC);
    CHECK(cdvr_codec_register(&clash_id, &err) == CDVR_ERR_ARG && strstr(err.msg, "'pvtc'"),
          "%s", err.msg);
    bad_name = fake("Bad-Name", 78);
    CHECK(cdvr_codec_register(&bad_name, &err) == CDVR_ERR_ARG, "%s", err.msg);
    ok = fake("fake_ok", 79);
    ok.decode = NULL;
    CHECK(cdvr_codec_register(&ok, &err) == CDVR_ERR_ARG && strstr(err.msg, "decode"), "%s",
          err.msg);
    ok = fake("fake_ok", 79);
    CHECK_OK(cdvr_codec_register(&ok, &err), err);
    CHECK(cdvr_codec_find("fake_ok") == &ok, "registered");

    const char *keys[] = {"S", "T", "pack"}, *vals[] = {"1", "2", "space"};
    cdvr_codec_params p;
    CHECK_OK(cdvr_codec_params_parse(pvtc, keys, vals, 3, &p, &err), err);
    char name[CDVR_VARIANT_NAME_MAX], v[32];
    pvtc->variant_name(&p, name, sizeof name);
    CHECK(strcmp(name, "S1T2s") == 0, "%s", name);
    CHECK(pvtc->params_get(&p, "pack", v, sizeof v) == 0 && strcmp(v, "space") == 0, "%s", v);
    const char *bk[] = {"S"}, *bv[] = {"3"};
    CHECK(cdvr_codec_params_parse(pvtc, bk, bv, 1, &p, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "1 or 4"), "%s", err.msg);
    const char *uk[] = {"Q"}, *uv[] = {"1"};
    CHECK(cdvr_codec_params_parse(pvtc, uk, uv, 1, &p, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "unknown parameter 'Q'"), "%s", err.msg);
    size_t dims[3] = {5, 3, 7};
    cdvr_codec_shape sh;
    pvtc->params_default(&p);
    CHECK_OK(cdvr_codec_shape_of(pvtc, &p, dims, &sh, &err), err);
    CHECK(sh.timesteps == 3 && sh.payload_bytes == 2 * 1 * 2 * 20, "%zu %zu", sh.timesteps,
          sh.payload_bytes);
    return check_finish();
}
