/* lua/bind/l_store.c - cdvr.Store: cdvr.encode, cdvr.open, st:info(), st:decode(), st:chunk(), and
 * the timing helpers the codec benchmark needs (st:bench_decode, st:bench_unpack,
 * cdvr.bench_memcpy, cdvr.clock). */
#include "cdvr/timing.h"
#include "lcdvr.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

typedef struct lstore {
    cdvr_store *st; /* NULL once closed */
} lstore;

static lstore *tolstore(lua_State *L, int idx)
{
    return (lstore *)luaL_checkudata(L, idx, LCDVR_STORE);
}

cdvr_store *lcdvr_checkstore(lua_State *L, int idx)
{
    lstore *ud = tolstore(L, idx);
    if (!ud->st || lcdvr_closing(L, idx))
        luaL_error(L, "attempt to use a closed store");
    return ud->st;
}

static void pushstore(lua_State *L, cdvr_store *st)
{
    lstore *ud = (lstore *)lua_newuserdatauv(L, sizeof *ud, 0);
    ud->st = st;
    luaL_setmetatable(L, LCDVR_STORE);
}

/* ---- option parsing (cdvr.encode) ------------------------------------------------------- */

static const char *const stage2_names[] = {"none", "lzo", "lz4", "zstd", "auto", NULL};

/* Keys of a variant table that are not codec parameters. */
static const char *const variant_keys[] = {"codec", "name", "stage2", "lzo_min_saving",
                                           "stage2_read_mbps", "stage2_segment", NULL};
/* Keys only the top-level options table takes. */
static const char *const top_keys[] = {"path", "schedule", "progress", "variants", "bricks",
                                        "threads", "ranges", "range_brick", "levels",
                                        "level_variants", "callback_limit", "callback_memory",
                                        NULL};

static int in_list(const char *const list[], const char *key)
{
    for (int i = 0; list[i]; i++)
        if (strcmp(list[i], key) == 0)
            return 1;
    return 0;
}

/* Like luaL_checkoption for a table field: index into names, def when absent; raises listing
 * the valid values. */
static int optionfield(lua_State *L, int idx, const char *key, const char *const names[], int def)
{
    const char *s = lcdvr_optstringfield(L, idx, key, NULL);
    if (!s)
        return def;
    for (int i = 0; names[i]; i++)
        if (strcmp(names[i], s) == 0)
            return i;
    luaL_Buffer b;
    luaL_buffinit(L, &b);
    for (int i = 0; names[i]; i++) {
        luaL_addstring(&b, i ? ", " : "");
        luaL_addstring(&b, names[i]);
    }
    luaL_pushresult(&b);
    return lcdvr_error(L, "option '%s': invalid value '%s' (expected %s)", key, s,
                      lua_tostring(L, -1));
}

/* The codec named by field "codec" of the table at idx (def when absent); raises listing the
 * registered codecs when unknown. */
static const cdvr_codec *codecfield(lua_State *L, int idx, const cdvr_codec *def)
{
    const char *name = lcdvr_optstringfield(L, idx, "codec", NULL);
    if (!name)
        return def;
    const cdvr_codec *c = cdvr_codec_find(name);
    if (c)
        return c;
    luaL_Buffer b;
    luaL_buffinit(L, &b);
    for (size_t i = 0; i < cdvr_codec_count(); i++) {
        luaL_addstring(&b, i ? ", " : "");
        luaL_addstring(&b, cdvr_codec_at(i)->name);
    }
    luaL_pushresult(&b);
    return (const cdvr_codec *)(intptr_t)lcdvr_error(
        L, "option 'codec': unknown codec '%s' (loaded: %s; plugins load with "
           "cdvr.plugin.load)", name, lua_tostring(L, -1));
}

/* The value at the top of the stack as text for a codec's params_set (pushed, kept on the
 * stack until the caller pops it). Integers print without a decimal point, other numbers
 * with 17 significant digits. */
static const char *param_text(lua_State *L, const char *key)
{
    switch (lua_type(L, -1)) {
    case LUA_TNUMBER:
        if (lua_isinteger(L, -1))
            return lua_pushfstring(L, "%I", (LUAI_UACINT)lua_tointeger(L, -1));
        {
            char buf[64];
            snprintf(buf, sizeof buf, "%.17g", (double)lua_tonumber(L, -1));
            return lua_pushstring(L, buf);
        }
    case LUA_TSTRING:
        return lua_pushstring(L, lua_tostring(L, -1));
    case LUA_TBOOLEAN:
        return lua_pushstring(L, lua_toboolean(L, -1) ? "true" : "false");
    default:
        return (const char *)(intptr_t)lcdvr_error(L, "option '%s': a number, string or boolean "
                                                     "expected, got %s", key,
                                                  luaL_typename(L, -1));
    }
}

/* Applies every key of the table at idx that `codec` takes as a parameter to *params. With
 * `strict`, any other key that is not in `allowed` is an error naming it (with a suggestion). */
static void apply_params(lua_State *L, int idx, const cdvr_codec *codec, cdvr_codec_params *params,
                         const char *const allowed[], const char *what)
{
    idx = lua_absindex(L, idx);
    lua_pushnil(L); /* key */
    while (lua_next(L, idx)) { /* key, value */
        const char *key = lua_type(L, -2) == LUA_TSTRING ? lua_tostring(L, -2) : NULL;
        if (key && cdvr_codec_has_param(codec, key)) {
            const char *text = param_text(L, key); /* key, value, text */
            cdvr_error err;
            if (codec->params_set(params, key, text, &err) != CDVR_OK)
                lcdvr_raise(L, &err);
            lua_pop(L, 1);
        } else if (allowed && (!key || !in_list(allowed, key))) {
            /* an unknown key: let lcdvr_checkoptions word the error with a suggestion */
            const char *keys[64];
            int n = 0;
            for (int i = 0; allowed[i] && n < 48; i++)
                keys[n++] = allowed[i];
            for (const cdvr_codec_param_doc *d = codec->params; d && d->key && n < 63; d++)
                keys[n++] = d->key;
            keys[n] = NULL;
            lcdvr_checkoptions(L, idx, what, keys);
        }
        lua_pop(L, 1); /* key */
    }
}

void lcdvr_parse_params(lua_State *L, int idx, const cdvr_codec *codec, cdvr_codec_params *out,
                        const char *what)
{
    static const char *const none[] = {NULL};
    memset(out, 0, sizeof *out);
    codec->params_default(out);
    if (!lua_isnoneornil(L, idx)) {
        luaL_checktype(L, idx, LUA_TTABLE);
        apply_params(L, idx, codec, out, none, what);
    }
    cdvr_error err;
    if (codec->params_check(out, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
}

typedef struct top_defaults {
    int idx;                    /* the options table */
    const cdvr_codec *codec;    /* codec= at the top, or the default */
    cdvr_stage2 stage2;
    double lzo_min_saving;
    double stage2_read_mbps;
    lua_Integer stage2_segment;
} top_defaults;

/* stage2_read_mbps= of the table at idx: a read rate > 0 in MB/s, or def when absent (0: the
 * store's filesystem's, measured by the encoder). */
static double read_rate_field(lua_State *L, int idx, double def)
{
    if (lua_getfield(L, idx, "stage2_read_mbps") == LUA_TNIL) {
        lua_pop(L, 1);
        return def;
    }
    lua_pop(L, 1);
    double mbps = lcdvr_optnumberfield(L, idx, "stage2_read_mbps", def);
    if (!(mbps > 0 && mbps < 1e12))
        lcdvr_error(L, "option 'stage2_read_mbps': %f must be a read rate > 0 in MB/s", mbps);
    return mbps;
}

/* Fills *out from the variant table at idx (0: the top-level table is the only variant):
 * codec defaults, then the top-level keys the codec takes, then the variant's own keys. */
static void parse_spec(lua_State *L, int idx, const top_defaults *top, cdvr_variant_spec *out)
{
    int from = idx ? idx : top->idx;
    memset(out, 0, sizeof *out);
    out->codec = idx ? codecfield(L, idx, top->codec) : top->codec;
    out->codec->params_default(&out->params);
    apply_params(L, top->idx, out->codec, &out->params, NULL, NULL);
    if (idx) {
        const char *const *allowed = variant_keys;
        apply_params(L, idx, out->codec, &out->params, allowed, "cdvr.encode: variant");
    }
    cdvr_error err;
    if (out->codec->params_check(&out->params, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    out->stage2 = (cdvr_stage2)optionfield(L, from, "stage2", stage2_names, (int)top->stage2);
    out->lzo_min_saving = lcdvr_optnumberfield(L, from, "lzo_min_saving", top->lzo_min_saving);
    if (!(out->lzo_min_saving >= 0 && out->lzo_min_saving <= 1))
        lcdvr_error(L, "option 'lzo_min_saving': %f is not in [0, 1]", out->lzo_min_saving);
    out->stage2_read_mbps = read_rate_field(L, from, top->stage2_read_mbps);
    lua_Integer seg = lcdvr_optintegerfield(L, from, "stage2_segment", top->stage2_segment);
    if (seg < CDVR_STAGE2_SEGMENT_MIN || seg > CDVR_STAGE2_SEGMENT_MAX)
        lcdvr_error(L, "option 'stage2_segment': %I bytes is not in %d..%d", seg,
                    (int)CDVR_STAGE2_SEGMENT_MIN, (int)CDVR_STAGE2_SEGMENT_MAX);
    out->stage2_segment = (size_t)seg;
    const char *name = idx ? lcdvr_optstringfield(L, idx, "name", "") : "";
    if (!idx)
        name = lcdvr_optstringfield(L, top->idx, "name", "");
    if (strlen(name) >= CDVR_NAME_MAX)
        lcdvr_error(L, "option 'name': '%s' is longer than %d bytes", name, CDVR_NAME_MAX - 1);
    memcpy(out->name, name, strlen(name));
    if (!out->name[0]) /* the core's default name, known here for progress */
        out->codec->variant_name(&out->params, out->name, sizeof out->name);
}

/* Raises for a top-level key that is neither an option nor a parameter of any codec in use. */
static void check_top_keys(lua_State *L, int idx, const cdvr_variant_spec *specs, size_t n,
                           const cdvr_codec *top_codec)
{
    const char *keys[128];
    int k = 0;
    for (int i = 0; top_keys[i]; i++)
        keys[k++] = top_keys[i];
    for (int i = 0; variant_keys[i]; i++)
        keys[k++] = variant_keys[i];
    const cdvr_codec *used[257];
    size_t nused = 0;
    used[nused++] = top_codec;
    for (size_t i = 0; i < n; i++)
        used[nused++] = specs[i].codec;
    for (size_t u = 0; u < nused; u++) {
        int seen = 0;
        for (size_t w = 0; w < u; w++)
            seen |= used[w] == used[u];
        for (const cdvr_codec_param_doc *d = used[u]->params; !seen && d && d->key && k < 127; d++)
            keys[k++] = d->key;
    }
    keys[k] = NULL;
    lcdvr_checkoptions(L, idx, "cdvr.encode", keys);
}

/* Parses opts (at idx) into a userdata array of specs left on the stack; returns it. */
static cdvr_variant_spec *parse_variants(lua_State *L, int idx, size_t *n)
{
    top_defaults top = {.idx = idx, .stage2 = CDVR_STAGE2_AUTO,
                        .lzo_min_saving = CDVR_LZO_MIN_SAVING,
                        .stage2_read_mbps = 0,
                        .stage2_segment = CDVR_STAGE2_SEGMENT};
    top.codec = codecfield(L, idx, cdvr_codec_find(CDVR_CODEC_DEFAULT));
    top.stage2 = (cdvr_stage2)optionfield(L, idx, "stage2", stage2_names, (int)top.stage2);
    top.lzo_min_saving = lcdvr_optnumberfield(L, idx, "lzo_min_saving", top.lzo_min_saving);
    top.stage2_read_mbps = read_rate_field(L, idx, top.stage2_read_mbps);
    top.stage2_segment = lcdvr_optintegerfield(L, idx, "stage2_segment", top.stage2_segment);
    int t = lua_getfield(L, idx, "variants");
    if (t != LUA_TNIL && t != LUA_TTABLE)
        lcdvr_error(L, "option 'variants': table expected, got %s", luaL_typename(L, -1));
    *n = t == LUA_TTABLE ? (size_t)luaL_len(L, -1) : 1;
    if (*n < 1 || *n > 256)
        lcdvr_error(L, "option 'variants': %d entries (expected 1..256)", (int)*n);
    cdvr_variant_spec *specs = lua_newuserdatauv(L, *n * sizeof *specs, 0);
    if (t != LUA_TTABLE)
        parse_spec(L, 0, &top, &specs[0]);
    for (size_t i = 0; t == LUA_TTABLE && i < *n; i++) {
        if (lua_geti(L, -2, (lua_Integer)i + 1) != LUA_TTABLE)
            lcdvr_error(L, "option 'variants': entry %d is not a table", (int)i + 1);
        parse_spec(L, lua_gettop(L), &top, &specs[i]);
        lua_pop(L, 1);
    }
    check_top_keys(L, idx, specs, *n, top.codec);
    lua_remove(L, -2); /* the variants table (or nil); the specs stay */
    return specs;
}

/* ---- schedule and progress callbacks ---------------------------------------------------- */

typedef struct encode_ctx {
    lua_State *L;
    int schedule_idx;            /* stack index of the Lua schedule, 0 if none */
    lcdvr_limits limits;         /* the schedule's budget (callback_limit, callback_memory) */
    const cdvr_variant_spec *specs;
    size_t nvariants;
    size_t *chunks;              /* chunks per variant, counted during planning */
    size_t nbricks;
    int show_progress;
    int lua_failed;              /* the schedule raised or returned something invalid */
} encode_ctx;

/* Applies the schedule's result table (top of the stack) to *p without raising (we are inside
 * the core): every key must be a parameter of the variant's codec. */
static cdvr_status schedule_result(encode_ctx *ctx, const cdvr_codec *codec, cdvr_codec_params *p,
                                   cdvr_error *err)
{
    lua_State *L = ctx->L;
    int tbl = lua_gettop(L);
    lua_pushnil(L);
    while (lua_next(L, tbl)) { /* key, value */
        const char *key = lua_type(L, -2) == LUA_TSTRING ? lua_tostring(L, -2) : NULL;
        char text[64];
        int ok = key && cdvr_codec_has_param(codec, key);
        if (ok && lua_isinteger(L, -1))
            snprintf(text, sizeof text, "%lld", (long long)lua_tointeger(L, -1));
        else if (ok && lua_type(L, -1) == LUA_TNUMBER)
            snprintf(text, sizeof text, "%.17g", (double)lua_tonumber(L, -1));
        else if (ok && lua_type(L, -1) == LUA_TSTRING)
            snprintf(text, sizeof text, "%s", lua_tostring(L, -1));
        else
            ok = 0;
        cdvr_error perr;
        cdvr_status s = ok ? codec->params_set(p, key, text, &perr)
                           : cdvr_error_set(&perr, CDVR_ERR_ARG, "'%s' is not a parameter of "
                                            "codec %s (a number or string)",
                                            key ? key : "(non-string key)", codec->name);
        if (s != CDVR_OK) {
            lua_pop(L, 2);
            ctx->lua_failed = 1;
            return cdvr_error_set(err, s, "schedule: %s", perr.msg);
        }
        lua_pop(L, 1);
    }
    return CDVR_OK;
}

static cdvr_status lua_schedule(void *ud, size_t variant, size_t t0, cdvr_codec_params *p,
                                cdvr_error *err)
{
    encode_ctx *ctx = ud;
    ctx->chunks[variant] += ctx->nbricks;
    if (!ctx->schedule_idx)
        return CDVR_OK;
    lua_State *L = ctx->L;
    lua_pushvalue(L, ctx->schedule_idx);
    lua_pushinteger(L, (lua_Integer)t0 + 1);
    lua_pushinteger(L, (lua_Integer)variant + 1);
    if (lcdvr_pcall_limits(L, 2, 1, &ctx->limits) != LUA_OK) {
        ctx->lua_failed = 1;
        cdvr_status s = cdvr_error_set(err, CDVR_ERR_ARG, "schedule: %s",
                                       lua_isstring(L, -1) ? lua_tostring(L, -1) : "error");
        lua_pop(L, 1);
        return s;
    }
    cdvr_status s = CDVR_OK;
    if (lua_istable(L, -1))
        s = schedule_result(ctx, ctx->specs[variant].codec, p, err);
    else if (!lua_isnil(L, -1)) {
        ctx->lua_failed = 1;
        s = cdvr_error_set(err, CDVR_ERR_ARG, "schedule: returned a %s (expected a table of "
                           "%s parameters, or nil)", luaL_typename(L, -1),
                           ctx->specs[variant].codec->name);
    }
    lua_pop(L, 1);
    return s;
}

static void lua_progress(void *ud, size_t done, size_t total)
{
    encode_ctx *ctx = ud;
    (void)total;
    if (!ctx->show_progress)
        return;
    size_t v = 0, before = 0;
    while (v + 1 < ctx->nvariants && done > before + ctx->chunks[v])
        before += ctx->chunks[v++];
    fprintf(stderr, "\rencode %s: %zu/%zu chunks", ctx->specs[v].name, done - before,
            ctx->chunks[v]);
    if (done - before == ctx->chunks[v])
        fputc('\n', stderr);
    fflush(stderr);
}

/* ---- cdvr.encode / cdvr.open ------------------------------------------------------------ */

/* Returns the u8 volume to encode: vol itself, or a quantised copy (pushed, owned by Lua). */
static const cdvr_volume *encode_input(lua_State *L, const cdvr_volume *vol,
                                       cdvr_encode_opts *o)
{
    o->source_type = vol->type;
    double window[2];
    cdvr_volume_window_peek(vol, window); /* u8: what its codes stand for (quantize window) */
    o->qlo = window[0];
    o->qhi = window[1];
    if (vol->type == CDVR_TYPE_U8)
        return vol;
    cdvr_volume *q = NULL;
    cdvr_error err;
    if (cdvr_volume_quantize(vol, o->qlo, o->qhi, &q, NULL, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    lcdvr_pushvolume(L, q);
    return q;
}

/* levels= (1..CDVR_STORE_MAX_LEVELS) and level_variants= {{variants of level 1}, ...} (each a
 * list of as many variant tables as variants=, parsed as variants=): the level count, and the
 * per-level specs in *out (NULL when none), left on the stack. */
static size_t level_options(lua_State *L, size_t nvariants, const cdvr_variant_spec *const **out)
{
    lua_Integer levels = lcdvr_optintegerfield(L, 2, "levels", 1);
    if (levels < 1 || levels > CDVR_STORE_MAX_LEVELS)
        luaL_error(L, "cdvr.encode: option 'levels': 1..%d expected, got %I",
                   CDVR_STORE_MAX_LEVELS, (LUAI_UACINT)levels);
    *out = NULL;
    int t = lua_getfield(L, 2, "level_variants");
    if (t == LUA_TNIL) {
        lua_pop(L, 1);
        return (size_t)levels;
    }
    if (t != LUA_TTABLE || luaL_len(L, -1) != levels - 1)
        luaL_error(L, "cdvr.encode: option 'level_variants': a list of %I lists of variants "
                      "(levels 1 .. %I) expected", (LUAI_UACINT)(levels - 1),
                   (LUAI_UACINT)(levels - 1));
    int list = lua_gettop(L);
    const cdvr_variant_spec **specs = lua_newuserdatauv(L, (size_t)levels * sizeof *specs, 0);
    for (lua_Integer l = 1; l < levels; l++) {
        lua_createtable(L, 0, 1); /* {variants = level_variants[l]}, parsed as cdvr.encode's */
        int tmp = lua_gettop(L);
        lua_geti(L, list, l);
        lua_setfield(L, tmp, "variants");
        size_t n;
        specs[l - 1] = parse_variants(L, tmp, &n); /* left on the stack: kept alive */
        if (n != nvariants)
            luaL_error(L, "cdvr.encode: option 'level_variants': level %I has %d variants, "
                          "variants= has %d", (LUAI_UACINT)l, (int)n, (int)nvariants);
    }
    *out = specs;
    return (size_t)levels;
}

static int l_encode(lua_State *L)
{
    int lazy = lcdvr_volume_lazy(L, 1); /* read one timestep at a time while encoding */
    const cdvr_volume *vol = lazy ? NULL : lcdvr_checkvolume(L, 1);
    luaL_checktype(L, 2, LUA_TTABLE);
    const char *path = lcdvr_optstringfield(L, 2, "path", NULL);
    if (!path)
        return luaL_error(L, "cdvr.encode: option 'path' is required");
    lua_pushstring(L, path); /* keep it alive */
    path = lua_tostring(L, -1);
    int sched_type = lua_getfield(L, 2, "schedule");
    if (sched_type != LUA_TNIL && sched_type != LUA_TFUNCTION)
        return lcdvr_error(L, "option 'schedule': function expected, got %s", luaL_typename(L, -1));
    int schedule_idx = sched_type == LUA_TFUNCTION ? lua_gettop(L) : 0;
    encode_ctx ctx = {.L = L, .schedule_idx = schedule_idx};
    lcdvr_limits_options(L, 2, "cdvr.encode", &ctx.limits);
    ctx.show_progress = lcdvr_optbooleanfield(L, 2, "progress", 1) && isatty(2);
    ctx.specs = parse_variants(L, 2, &ctx.nvariants);
    ctx.chunks = lua_newuserdatauv(L, ctx.nvariants * sizeof *ctx.chunks, 0);
    memset(ctx.chunks, 0, ctx.nvariants * sizeof *ctx.chunks);
    cdvr_encode_opts o = {.variants = ctx.specs, .nvariants = ctx.nvariants,
                          .schedule = lua_schedule, .schedule_ud = &ctx,
                          .progress = lua_progress, .progress_ud = &ctx};
    double bricks[3] = {1, 1, 1};
    lcdvr_numberarrayfield(L, 2, "bricks", bricks, 3);
    for (int i = 0; i < 3; i++) {
        if (!(bricks[i] >= 1 && bricks[i] <= CDVR_STORE_MAX_BRICKS) || bricks[i] != floor(bricks[i]))
            return luaL_error(L, "cdvr.encode: option 'bricks': {bx, by, bz} of integers 1..%d "
                              "expected", CDVR_STORE_MAX_BRICKS);
        o.bricks[i] = (size_t)bricks[i];
    }
    ctx.nbricks = o.bricks[0] * o.bricks[1] * o.bricks[2];
    lua_Integer threads = lcdvr_optintegerfield(L, 2, "threads", 0);
    if (threads < 0 || threads > CDVR_ENCODE_MAX_THREADS)
        return luaL_error(L, "cdvr.encode: option 'threads': 0 (one per core) .. %d expected, "
                          "got %d", CDVR_ENCODE_MAX_THREADS, (int)threads);
    o.threads = (int)threads;
    o.no_range_tables = !lcdvr_optbooleanfield(L, 2, "ranges", 1);
    lua_Integer range_brick = lcdvr_optintegerfield(L, 2, "range_brick",
                                                    1 << CDVR_RANGE_SHIFT_DEFAULT);
    o.range_shift = 0;
    while (o.range_shift <= CDVR_RANGE_SHIFT_MAX &&
           ((lua_Integer)1 << o.range_shift) != range_brick)
        o.range_shift++;
    if (o.range_shift < CDVR_RANGE_SHIFT || o.range_shift > CDVR_RANGE_SHIFT_MAX)
        return luaL_error(L, "cdvr.encode: option 'range_brick': 4, 8, 16, 32 or 64 expected, "
                          "got %d", (int)range_brick);
    o.levels = level_options(L, ctx.nvariants, &o.level_variants);
    cdvr_encode_source src;
    const cdvr_volume *u8 = NULL;
    if (lazy)
        lcdvr_volume_source(L, 1, &src, &o);
    else
        u8 = encode_input(L, vol, &o);
    cdvr_error err;
    lcdvr_use(L, 1); /* the schedule may close the volume: deferred until the encoder is done */
    cdvr_status s = lazy ? cdvr_store_encode_source(&src, &o, path, &err)
                         : cdvr_store_encode(u8, &o, path, &err);
    lcdvr_unuse(L, 1);
    if (s != CDVR_OK) /* an encoder opens what it wrote: it raises, as cdvr.open (lcdvr.h) */
        return lcdvr_raise(L, &err);
    cdvr_store *st = NULL;
    if (cdvr_store_open(path, &st, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    pushstore(L, st);
    return 1;
}

static int l_open(lua_State *L)
{
    const char *path = luaL_checkstring(L, 1);
    cdvr_store *st = NULL;
    cdvr_error err;
    if (cdvr_store_open(path, &st, &err) != CDVR_OK) /* refuses FIFOs without blocking */
        return lcdvr_raise(L, &err);
    pushstore(L, st);
    return 1;
}

/* ---- methods ---------------------------------------------------------------------------- */

/* Variant argument at idx: nil/none -> 0, 1-based index, or name. */
static size_t checkvariant(lua_State *L, const cdvr_store *st, int idx)
{
    size_t n = cdvr_store_get_info(st)->nvariants;
    if (lua_isnoneornil(L, idx))
        return 0;
    if (lua_type(L, idx) == LUA_TSTRING) {
        int v = lcdvr_find_variant(L, idx, st);
        if (v < 0)
            luaL_argerror(L, idx, lua_pushfstring(L, "no variant %s in %s", lcdvr_push_quoted(L, idx),
                                                  cdvr_store_path(st)));
        return (size_t)v;
    }
    lua_Integer v = luaL_checkinteger(L, idx);
    luaL_argcheck(L, v >= 1 && (size_t)v <= n, idx, "variant index out of range");
    return (size_t)v - 1;
}

static void setnum(lua_State *L, const char *k, double v)
{
    lua_pushnumber(L, v);
    lua_setfield(L, -2, k);
}

static void setint(lua_State *L, const char *k, lua_Integer v)
{
    lua_pushinteger(L, v);
    lua_setfield(L, -2, k);
}

static void setstr(lua_State *L, const char *k, const char *v)
{
    lua_pushstring(L, v);
    lua_setfield(L, -2, k);
}

static void push_triple(lua_State *L, const char *k, double a, double b, double c)
{
    lua_createtable(L, 3, 0);
    lua_pushnumber(L, a);
    lua_rawseti(L, -2, 1);
    lua_pushnumber(L, b);
    lua_rawseti(L, -2, 2);
    lua_pushnumber(L, c);
    lua_rawseti(L, -2, 3);
    lua_setfield(L, -2, k);
}

/* The codec parameters of p as fields of the table on top (numbers as numbers), and the same
 * in a `params` subtable. */
void lcdvr_push_params(lua_State *L, const cdvr_codec *codec, const cdvr_codec_params *p)
{
    lua_newtable(L); /* info, params */
    for (const cdvr_codec_param_doc *d = codec->params; d && d->key; d++) {
        char text[64];
        if (codec->params_get(p, d->key, text, sizeof text) != 0)
            continue;
        if (!lua_stringtonumber(L, text))
            lua_pushstring(L, text);
        lua_pushvalue(L, -1);
        lua_setfield(L, -3, d->key);  /* params[key] */
        lua_setfield(L, -3, d->key);  /* info[key] */
    }
    lua_setfield(L, -2, "params");
}

size_t lcdvr_chunk_timesteps(const cdvr_store *st, size_t v)
{
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, v, 0);
    size_t lo[3], dims[3];
    cdvr_codec_shape shape;
    cdvr_store_brick_box(cdvr_store_get_info(st), 0, lo, dims);
    if (ch && ch->codec && cdvr_codec_shape_of(ch->codec, &ch->params, dims, &shape, NULL) == CDVR_OK)
        return shape.timesteps;
    return ch && ch->count ? ch->count : 1;
}

/* Adds emitted figures into the table on top (sums over chunks). */
static void add_figure(void *ud, const char *key, double value)
{
    lua_State *L = ud;
    lua_getfield(L, -1, key);
    double sum = lua_tonumber(L, -1) + value;
    lua_pop(L, 1);
    lua_pushnumber(L, sum);
    lua_setfield(L, -2, key);
}

/* The codec's describe figures summed over the variant's chunks, in table `details` of the
 * table on top (reads every chunk: only for codecs that describe their payloads). */
static void push_details(lua_State *L, const cdvr_store *st, size_t v)
{
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    if (!vi->codec || !vi->codec->describe)
        return;
    lua_newtable(L); /* info, details */
    for (size_t c = 0; c < vi->nchunks; c++) {
        const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
        uint8_t *payload;
        cdvr_error err;
        if (!ci->codec || !ci->codec->describe ||
            cdvr_store_load_payload(st, v, c, &payload, &err) != CDVR_OK)
            continue;
        size_t lo[3], dims[3];
        cdvr_store_brick_box(cdvr_store_get_info(st), ci->brick, lo, dims);
        ci->codec->describe(&ci->params, dims, payload, (size_t)ci->payload_bytes, add_figure,
                            L, &err);
        free(payload);
    }
    /* the figures also as fields of the row, for reports */
    lua_pushnil(L);
    while (lua_next(L, -2)) { /* info, details, key, value */
        lua_pushvalue(L, -2);
        lua_insert(L, -2);    /* info, details, key, key, value */
        lua_settable(L, -5);  /* info[key] = value */
    }
    lua_setfield(L, -2, "details");
}

/* Device memory the volume data of one frame of variant v takes on the cl device: a
 * fetch-mode codec keeps its largest chunk payload and the parameter blob there (rendering in
 * the compressed domain); the others hold one chunk's dense frames. */
static uint64_t device_bytes(const cdvr_store *st, size_t v)
{
    const cdvr_store_info *in = cdvr_store_get_info(st);
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    uint64_t payload = 0;
    for (size_t c = 0; c < vi->nchunks; c++) {
        const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
        payload = ci->payload_bytes > payload ? ci->payload_bytes : payload;
    }
    if (vi->codec && vi->codec->cl_mode == CDVR_CODEC_CL_FETCH && in->nbricks == 1)
        return payload + CDVR_CODEC_PARAMS_MAX;
    return (uint64_t)in->dims[0] * in->dims[1] * in->dims[2] * lcdvr_chunk_timesteps(st, v);
}

static void push_variant_info(lua_State *L, const cdvr_store *st, size_t v)
{
    const cdvr_store_info *in = cdvr_store_get_info(st);
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    lua_createtable(L, 0, 16);
    setstr(L, "name", vi->name);
    setstr(L, "codec", vi->codec_name);
    lua_pushboolean(L, vi->codec != NULL);
    lua_setfield(L, -2, "codec_loaded");
    if (vi->codec)
        lcdvr_push_params(L, vi->codec, &vi->params);
    setstr(L, "stage2", stage2_names[vi->stage2]);
    lua_createtable(L, 0, 4); /* chunks per stage 2 actually stored (what auto chose) */
    for (int c = 0; c < 4; c++)
        setint(L, stage2_names[c], (lua_Integer)vi->stage2_chunks[c]);
    lua_setfield(L, -2, "stage2_chunks");
    if (vi->stage2_read_mbps > 0)
        setnum(L, "stage2_read_mbps", vi->stage2_read_mbps);
    if (vi->stage2_segment)
        setint(L, "stage2_segment", (lua_Integer)vi->stage2_segment);
    setint(L, "bytes", (lua_Integer)vi->bytes);
    setint(L, "payload_bytes", (lua_Integer)vi->payload_bytes);
    setint(L, "ranges_bytes", (lua_Integer)vi->ranges_bytes);
    const cdvr_chunk_info *c0 = cdvr_store_chunk(st, v, 0);
    if (c0 && c0->ranges_shift) /* the encoder writes one size for every chunk */
        setint(L, "range_brick", (lua_Integer)1 << c0->ranges_shift);
    setint(L, "shared_bytes", (lua_Integer)vi->shared_bytes); /* in bytes too */
    setnum(L, "ratio", (double)vi->bytes / (double)in->raw_bytes);
    setnum(L, "bpv", 8.0 * (double)vi->bytes / (double)in->raw_bytes);
    setnum(L, "psnr", vi->psnr);
    setnum(L, "maxerr", vi->maxerr);
    setint(L, "chunks", (lua_Integer)vi->nchunks);
    setint(L, "groups", (lua_Integer)vi->ngroups);
    setint(L, "device_bytes", (lua_Integer)device_bytes(st, v));
    push_details(L, st, v);
}

static void push_bricks(lua_State *L, const cdvr_store_info *in)
{
    lua_createtable(L, 3, 0);
    for (int i = 0; i < 3; i++) {
        lua_pushinteger(L, (lua_Integer)in->bricks[i]);
        lua_rawseti(L, -2, i + 1);
    }
    lua_setfield(L, -2, "brick_grid");
    lua_createtable(L, (int)in->nbricks, 0);
    for (size_t b = 0; b < in->nbricks; b++) {
        size_t lo[3], dims[3];
        cdvr_store_brick_box(in, b, lo, dims);
        lua_createtable(L, 0, 2);
        push_triple(L, "lo", (double)lo[0], (double)lo[1], (double)lo[2]);
        push_triple(L, "dims", (double)dims[0], (double)dims[1], (double)dims[2]);
        lua_rawseti(L, -2, (lua_Integer)b + 1);
    }
    lua_setfield(L, -2, "bricks");
}

/* info.levels: per level (from 0) its dims, spacing, brick grid, bytes (all variants) and per
 * variant name, bytes, psnr and maxerr against level 0 (store.h). */
static void push_levels(lua_State *L, const cdvr_store *st)
{
    const cdvr_store_info *in = cdvr_store_get_info(st);
    lua_createtable(L, (int)in->nlevels, 0);
    for (size_t l = 0; l < in->nlevels; l++) {
        const cdvr_store *lv = cdvr_store_level(st, l);
        const cdvr_store_info *li = cdvr_store_get_info(lv);
        lua_createtable(L, 0, 6);
        setint(L, "level", (lua_Integer)l);
        push_triple(L, "dims", (double)li->dims[0], (double)li->dims[1], (double)li->dims[2]);
        push_triple(L, "spacing", li->spacing[0], li->spacing[1], li->spacing[2]);
        push_triple(L, "brick_grid", (double)li->bricks[0], (double)li->bricks[1],
                    (double)li->bricks[2]);
        uint64_t bytes = 0;
        lua_createtable(L, (int)li->nvariants, 0);
        for (size_t v = 0; v < li->nvariants; v++) {
            const cdvr_variant_info *vi = cdvr_store_variant(lv, v);
            double psnr, maxerr;
            cdvr_store_level_error(st, l, v, &psnr, &maxerr);
            bytes += vi->bytes;
            lua_createtable(L, 0, 5);
            setstr(L, "name", vi->name);
            setstr(L, "codec", vi->codec_name);
            setint(L, "bytes", (lua_Integer)vi->bytes);
            setnum(L, "psnr", psnr);
            setnum(L, "maxerr", maxerr);
            lua_rawseti(L, -2, (lua_Integer)v + 1);
        }
        lua_setfield(L, -2, "variants");
        setint(L, "bytes", (lua_Integer)bytes);
        lua_rawseti(L, -2, (lua_Integer)l + 1);
    }
    lua_setfield(L, -2, "levels");
}

/* st:level(l): level l (0 .. #st:info().levels - 1) as a store of its own. */
static int store_level(lua_State *L)
{
    const cdvr_store *st = lcdvr_checkstore(L, 1);
    lua_Integer l = luaL_checkinteger(L, 2);
    size_t n = cdvr_store_get_info(st)->nlevels;
    if (l < 0 || (size_t)l >= n)
        return luaL_error(L, "st:level: level %I of %s: the store has levels 0..%d",
                          (LUAI_UACINT)l, cdvr_store_path(st), (int)n - 1);
    cdvr_store *out;
    cdvr_error err;
    if (cdvr_store_open_level(st, (size_t)l, &out, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    pushstore(L, out);
    return 1;
}

static int store_info(lua_State *L)
{
    const cdvr_store *st = lcdvr_checkstore(L, 1);
    const cdvr_store_info *in = cdvr_store_get_info(st);
    lua_createtable(L, 0, 16);
    setstr(L, "path", cdvr_store_path(st));
    setint(L, "version", (lua_Integer)in->version);
    lua_createtable(L, 3, 0);
    for (int i = 0; i < 3; i++) {
        lua_pushinteger(L, (lua_Integer)in->dims[i]);
        lua_rawseti(L, -2, i + 1);
    }
    lua_setfield(L, -2, "dims");
    setint(L, "timesteps", (lua_Integer)in->timesteps);
    setint(L, "raw_bytes", (lua_Integer)in->raw_bytes);
    setint(L, "file_bytes", (lua_Integer)in->file_bytes);
    push_triple(L, "spacing", in->spacing[0], in->spacing[1], in->spacing[2]);
    push_triple(L, "origin", in->origin[0], in->origin[1], in->origin[2]);
    lua_createtable(L, 9, 0);
    for (int i = 0; i < 9; i++) {
        lua_pushnumber(L, in->direction[i]);
        lua_rawseti(L, -2, i + 1);
    }
    lua_setfield(L, -2, "direction");
    lua_createtable(L, 2, 0);
    lua_pushnumber(L, in->qlo);
    lua_rawseti(L, -2, 1);
    lua_pushnumber(L, in->qhi);
    lua_rawseti(L, -2, 2);
    lua_setfield(L, -2, "window");
    setstr(L, "source_type", cdvr_type_name(in->source_type));
    push_bricks(L, in);
    uint64_t bytes = 0;
    lua_createtable(L, (int)in->nvariants, 0);
    for (size_t v = 0; v < in->nvariants; v++) {
        bytes += cdvr_store_variant(st, v)->bytes;
        push_variant_info(L, st, v);
        lua_rawseti(L, -2, (lua_Integer)v + 1);
    }
    lua_setfield(L, -2, "variants");
    push_levels(L, st);
    setint(L, "bytes", (lua_Integer)bytes);
    setnum(L, "ratio", (double)cdvr_store_variant(st, 0)->bytes / (double)in->raw_bytes);
    return 1;
}

static int store_decode(lua_State *L)
{
    const cdvr_store *st = lcdvr_checkstore(L, 1);
    lua_Integer t = luaL_checkinteger(L, 2);
    luaL_argcheck(L, t >= 1 && (size_t)t <= cdvr_store_get_info(st)->timesteps, 2,
                  "timestep out of range");
    int opts = lua_istable(L, 3) ? 3 : (lua_istable(L, 4) ? 4 : 0);
    size_t v = opts == 3 ? 0 : checkvariant(L, st, 3);
    static const char *const devices[] = {"cpu", "cl", NULL};
    static const char *const keys[] = {"device", "brick", NULL};
    if (opts)
        lcdvr_checkoptions(L, opts, "st:decode", keys);
    int device = opts ? optionfield(L, opts, "device", devices, 0) : 0;
    lua_Integer brick = opts ? lcdvr_optintegerfield(L, opts, "brick", 0) : 0;
    size_t nbricks = cdvr_store_get_info(st)->nbricks;
    if (brick != 0 && (brick < 1 || (size_t)brick > nbricks))
        return luaL_error(L, "st:decode: brick %d out of range 1..%d (%s)", (int)brick,
                          (int)nbricks, cdvr_store_path(st));
    if (device == 1 && brick)
        return luaL_error(L, "st:decode: brick= decodes on the cpu device only");
    if (device == 1) {
        lcdvr_decode_cl(L, st, v, (size_t)t - 1);
    } else {
        cdvr_volume *vol = NULL;
        cdvr_error err;
        cdvr_status s = brick ? cdvr_store_decode_brick(st, v, (size_t)t - 1, (size_t)brick - 1,
                                                        &vol, &err)
                              : cdvr_store_decode(st, v, (size_t)t - 1, &vol, &err);
        if (s != CDVR_OK)
            return lcdvr_raise(L, &err);
        lcdvr_pushvolume(L, vol);
    }
    return 1; /* the decoded volume carries the store's value window either way */
}

/* Reads and unpacks chunk c into a Lua string (pushed), or raises. */
static void push_payload(lua_State *L, const cdvr_store *st, size_t v, size_t c)
{
    uint8_t *payload;
    cdvr_error err;
    if (cdvr_store_load_payload(st, v, c, &payload, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    lua_pushlstring(L, (const char *)payload, (size_t)cdvr_store_chunk(st, v, c)->payload_bytes);
    free(payload);
}

static int store_chunk(lua_State *L)
{
    const cdvr_store *st = lcdvr_checkstore(L, 1);
    size_t v = checkvariant(L, st, 3);
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    lua_Integer i = luaL_checkinteger(L, 2);
    luaL_argcheck(L, i >= 1 && (size_t)i <= vi->nchunks, 2, "chunk index out of range");
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, (size_t)i - 1);
    push_payload(L, st, v, (size_t)i - 1);
    lua_createtable(L, 0, 12);
    setint(L, "t0", (lua_Integer)ci->t0 + 1);
    setint(L, "timesteps", (lua_Integer)ci->count);
    setint(L, "brick", (lua_Integer)ci->brick + 1);
    setstr(L, "codec", ci->codec ? ci->codec->name : vi->codec_name);
    if (ci->codec)
        lcdvr_push_params(L, ci->codec, &ci->params);
    setint(L, "value_min", ci->value_min);
    setint(L, "value_max", ci->value_max);
    setint(L, "stored_bytes", (lua_Integer)ci->stored_bytes);
    setint(L, "payload_bytes", (lua_Integer)ci->payload_bytes);
    lua_pushboolean(L, ci->stage2);
    lua_setfield(L, -2, "stage2");
    setstr(L, "stage2_codec", stage2_names[ci->stage2 & 3]);
    lua_pushboolean(L, ci->stage2_segmented);
    lua_setfield(L, -2, "stage2_segmented");
    return 2;
}

static int store_variants(lua_State *L)
{
    const cdvr_store *st = lcdvr_checkstore(L, 1);
    size_t n = cdvr_store_get_info(st)->nvariants;
    lua_createtable(L, (int)n, 0);
    for (size_t v = 0; v < n; v++) {
        lua_pushstring(L, cdvr_store_variant(st, v)->name);
        lua_rawseti(L, -2, (lua_Integer)v + 1);
    }
    return 1;
}

static int store_gc(lua_State *L)
{
    lstore *ud = tolstore(L, 1);
    if (lcdvr_defer_close(L, 1)) /* a player still uses it: closed when the player lets go */
        return 0;
    cdvr_store_close(ud->st);
    ud->st = NULL;
    return 0;
}

static int store_tostring(lua_State *L)
{
    lstore *ud = tolstore(L, 1);
    if (!ud->st || lcdvr_closing(L, 1)) {
        lua_pushliteral(L, "cdvr.Store (closed)");
        return 1;
    }
    const cdvr_store_info *in = cdvr_store_get_info(ud->st);
    lua_pushfstring(L, "cdvr.Store %s %dx%dx%d x %d, %d variants (%p)", cdvr_store_path(ud->st),
                    (int)in->dims[0], (int)in->dims[1], (int)in->dims[2], (int)in->timesteps,
                    (int)in->nvariants, (void *)ud);
    return 1;
}

/* ---- timing helpers --------------------------------------------------------------------- */

static int l_clock(lua_State *L)
{
    lua_pushnumber(L, cdvr_now_ms() / 1e3);
    return 1;
}

static size_t checkrepeats(lua_State *L, int idx)
{
    lua_Integer r = luaL_optinteger(L, idx, 5);
    luaL_argcheck(L, r >= 1 && r <= 1000, idx, "repeats must be 1..1000");
    return (size_t)r;
}

/* cdvr.bench_memcpy(bytes [, repeats [, piece]]): median MB/s of copying `bytes` from one
 * buffer into another; with `piece`, the source is copied piece by piece into one reused
 * destination of `piece` bytes - the same write working set as st:bench_decode, which
 * decodes every chunk into one reused buffer of a chunk's frames. */
static int l_bench_memcpy(lua_State *L)
{
    lua_Integer bytes = luaL_checkinteger(L, 1);
    luaL_argcheck(L, bytes >= 1 && bytes <= ((lua_Integer)1 << 34), 1, "bytes must be 1..2^34");
    size_t n = (size_t)bytes, repeats = checkrepeats(L, 2);
    lua_Integer piece_arg = luaL_optinteger(L, 3, bytes);
    luaL_argcheck(L, piece_arg >= 1 && piece_arg <= bytes, 3, "piece must be 1..bytes");
    size_t piece = (size_t)piece_arg;
    uint8_t *src = lua_newuserdatauv(L, n, 0), *dst = lua_newuserdatauv(L, piece, 0);
    double *mbps = lua_newuserdatauv(L, repeats * sizeof *mbps, 0);
    memset(src, 1, n);
    memset(dst, 0, piece); /* fault the pages in before timing, as the decoders' outputs are */
    for (size_t r = 0; r < repeats; r++) {
        src[r % n] = (uint8_t)r;
        double t0 = cdvr_now_ms();
        for (size_t off = 0; off < n; off += piece)
            memcpy(dst, src + off, n - off < piece ? n - off : piece);
        double dt = (cdvr_now_ms() - t0) / 1e3;
        mbps[r] = dt > 0 ? (double)n / dt / 1e6 : HUGE_VAL;
    }
    volatile uint8_t sink = dst[(repeats - 1) % piece]; /* the copies are observable */
    (void)sink;
    lua_pushnumber(L, cdvr_median(mbps, repeats));
    return 1;
}

/* Stored bytes of every chunk of variant v, read once (CRC checked), in a Lua userdata. */
static uint8_t **load_all_stored(lua_State *L, const cdvr_store *st, size_t v, int unpack)
{
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    uint8_t **bufs = lua_newuserdatauv(L, vi->nchunks * sizeof *bufs, 1);
    lua_createtable(L, (int)vi->nchunks, 0); /* keeps the chunk buffers alive */
    for (size_t c = 0; c < vi->nchunks; c++) {
        const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
        uint8_t *stored = lua_newuserdatauv(L, (size_t)ci->stored_bytes, 0);
        cdvr_error err;
        if (cdvr_store_read_chunk(st, v, c, stored, &err) != CDVR_OK)
            lcdvr_raise(L, &err);
        bufs[c] = stored;
        if (unpack) {
            bufs[c] = lua_newuserdatauv(L, (size_t)ci->payload_bytes, 0);
            if (cdvr_store_unpack_chunk(st, v, c, stored, bufs[c], &err) != CDVR_OK)
                lcdvr_raise(L, &err);
            lua_rawseti(L, -3, (lua_Integer)(2 * c + 2));
        }
        lua_rawseti(L, -2, (lua_Integer)(2 * c + 1));
    }
    lua_setiuservalue(L, -2, 1);
    return bufs;
}

static int store_bench_decode(lua_State *L)
{
    const cdvr_store *st = lcdvr_checkstore(L, 1);
    size_t v = checkvariant(L, st, 2), repeats = checkrepeats(L, 3);
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    size_t voxels = (size_t)(cdvr_store_get_info(st)->raw_bytes / cdvr_store_get_info(st)->timesteps);
    uint8_t **payloads = load_all_stored(L, st, v, 1);
    uint8_t *out = lua_newuserdatauv(L, 3 * voxels, 0);
    memset(out, 0, 3 * voxels);
    double *mbps = lua_newuserdatauv(L, repeats * sizeof *mbps, 0);
    uint8_t *frames[3] = {out, out + voxels, out + 2 * voxels};
    for (size_t r = 0; r < repeats; r++) {
        double t0 = cdvr_now_ms();
        for (size_t c = 0; c < vi->nchunks; c++) {
            cdvr_error err;
            if (cdvr_store_decode_chunk(st, v, c, payloads[c], frames, &err) != CDVR_OK)
                return lcdvr_raise(L, &err);
        }
        double dt = (cdvr_now_ms() - t0) / 1e3;
        mbps[r] = dt > 0 ? (double)cdvr_store_get_info(st)->raw_bytes / dt / 1e6 : HUGE_VAL;
    }
    lua_pushnumber(L, cdvr_median(mbps, repeats));
    return 1;
}

static int store_bench_unpack(lua_State *L)
{
    const cdvr_store *st = lcdvr_checkstore(L, 1);
    size_t v = checkvariant(L, st, 2), repeats = checkrepeats(L, 3);
    lua_Integer threads = luaL_optinteger(L, 4, 0);
    luaL_argcheck(L, threads >= 0 && threads <= 256, 4, "threads: 0 (one per core) .. 256");
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    uint8_t **stored = load_all_stored(L, st, v, 0);
    size_t max_payload = 1;
    for (size_t c = 0; c < vi->nchunks; c++)
        if (cdvr_store_chunk(st, v, c)->payload_bytes > max_payload)
            max_payload = (size_t)cdvr_store_chunk(st, v, c)->payload_bytes;
    uint8_t *out = lua_newuserdatauv(L, max_payload, 0);
    memset(out, 0, max_payload);
    double *mbps = lua_newuserdatauv(L, repeats * sizeof *mbps, 0);
    for (size_t r = 0; r < repeats; r++) {
        double t0 = cdvr_now_ms();
        for (size_t c = 0; c < vi->nchunks; c++) {
            cdvr_error err;
            if (cdvr_store_unpack_chunk_threads(st, v, c, stored[c], out, (int)threads,
                                                &err) != CDVR_OK)
                return lcdvr_raise(L, &err);
        }
        double dt = (cdvr_now_ms() - t0) / 1e3;
        mbps[r] = dt > 0 ? (double)vi->payload_bytes / dt / 1e6 : HUGE_VAL;
    }
    lua_pushnumber(L, cdvr_median(mbps, repeats));
    return 1;
}

static const luaL_Reg store_methods[] = {
    {"info", store_info},         {"decode", store_decode},
    {"chunk", store_chunk},       {"variants", store_variants},
    {"level", store_level},
    {"close", store_gc},          {"bench_decode", store_bench_decode},
    {"bench_unpack", store_bench_unpack}, {NULL, NULL}};

static const luaL_Reg store_meta[] = {
    {"__gc", store_gc}, {"__close", store_gc}, {"__tostring", store_tostring}, {NULL, NULL}};

/* cdvr.stage2_rates([path]) -> {lzo=, lz4=, zstd= (MB/s), from_cache=[, read_disk=,
 * read_cache=, read_from_cache=]} */
static int l_stage2_rates(lua_State *L)
{
    const char *path = luaL_optstring(L, 1, NULL);
    double mbps[5];
    int from_cache = 0;
    cdvr_read_rates read;
    cdvr_error err;
    if (cdvr_stage2_unpack_rates(mbps, &from_cache, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    if (path && cdvr_store_read_rates(path, &read, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_createtable(L, 0, 7);
    for (int c = CDVR_STAGE2_LZO; c <= CDVR_STAGE2_ZSTD; c++)
        setnum(L, stage2_names[c], mbps[c]);
    lua_pushboolean(L, from_cache);
    lua_setfield(L, -2, "from_cache");
    if (path) {
        setnum(L, "read_disk", read.disk_mbps);
        setnum(L, "read_cache", read.cache_mbps);
        lua_pushboolean(L, read.from_cache);
        lua_setfield(L, -2, "read_from_cache");
    }
    return 1;
}

static const luaL_Reg store_funcs[] = {{"encode", l_encode},
                                       {"stage2_rates", l_stage2_rates},
                                       {"open", l_open},
                                       {"clock", l_clock},
                                       {"bench_memcpy", l_bench_memcpy},
                                       {NULL, NULL}};

int lcdvr_open_store(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_STORE, store_methods, store_meta);
    lcdvr_setfuncs(L, store_funcs);
    lcdvr_help_add(L, "cdvr.encode(volume, {path=, codec=, S=, T=, pack=, encoder=, stage2=, "
                      "lzo_min_saving=, stage2_read_mbps=, stage2_segment=, name=, variants=, schedule=, progress=, bricks=, threads=, ranges=, range_brick=, levels=, level_variants=})",
                   "encode a series into a .cdv store (written atomically; defaults codec=pvtc "
                   "S=4 T=3 pack=time encoder=lsq stage2=auto lzo_min_saving=0.1; stage2=none|lzo|lz4|"
                   "zstd|auto (auto: per chunk the shortest modelled time in the pipelined "
                   "player, the read at stage2_read_mbps= MB/s or twice the unpack on all "
                   "cores at this machine's rates, whichever is longer; the read rate by "
                   "default that of the store's filesystem, from the page cache where the "
                   "series fits in half the memory, else from the disk; rates measured once "
                   "and remembered, cdvr.stage2_rates(path); stage2_segment=1048576 payload bytes per "
                   "independently packed segment); bricks={bx,by,bz} "
                   "splits each timestep into bricks; threads=0: one per core, the same bytes for "
                   "any count; ranges=true: per-brick value range tables for empty-space "
                   "skipping, range_brick=8 (4..64) voxels per brick edge; levels=N adds N-1 coarser levels, each halving resolution "
                   "(tent filter, store.h), with level_variants={{...}, ...} per level "
                   "(default: variants=); schedule(t, variant) runs under callback_limit= instructions, "
                   "default 5e7, and callback_memory= MB, default 256); the opened store; raises "
                   "when it cannot write the file (the message names it)");
    lcdvr_help_add(L, "cdvr.stage2_rates([path])",
                   "the rates stage2=auto models: this machine's single-thread stage-2 unpack "
                   "rates (payload MB/s, measured once on a fixed calibration payload) and, "
                   "given a store's path, the rates its filesystem reads at from the disk and "
                   "from the page cache (MB/s; a 32 MiB test file written, synced and read "
                   "there, dropped from the page cache and cached), each remembered in the "
                   "cache: {lzo=, lz4=, zstd=, from_cache=, read_disk=, read_cache=, "
                   "read_from_cache=}");
    lcdvr_help_add(L, "cdvr.open(path)", "open a .cdv store (lazy); the store, or raises naming "
                                         "the file and the reason");
    lcdvr_help_add(L, "st:info()", "dims, timesteps, window, bytes, ratio and per-variant "
                                   "codec, bpv, psnr, maxerr, chunks, ranges_bytes (the value "
                                   "range tables for empty-space skipping), range_brick");
    lcdvr_help_add(L, "st:decode(t [, variant] [, {device=\"cpu\"|\"cl\", brick=b}])",
                   "u8 volume of timestep t (from 1) of a variant (name or index, default 1); "
                   "brick=b reads and decodes only brick b (st:info().bricks[b]), placed where it lies");
    lcdvr_help_add(L, "st:chunk(i [, variant])", "payload bytes of chunk i after stage 2, and "
                                                 "{t0=, timesteps=, S=, T=, pack=, stored_bytes=, stage2=, "
                                                 "stage2_codec=, stage2_segmented=}");
    lcdvr_help_add(L, "st:variants()", "list of variant names");
    lcdvr_help_add(L, "st:level(l)", "level l (0 = full resolution) of a multi-resolution "
                                     "store (cdvr.encode levels=) as a store of its own");
    lcdvr_help_add(L, "st:close()", "close the store file");
    lcdvr_help_add(L, "st:bench_decode([variant] [, repeats])",
                   "median MB/s (output bytes) of the C decoder over all chunks, single thread");
    lcdvr_help_add(L, "st:bench_unpack([variant] [, repeats] [, threads])",
                   "median MB/s (payload bytes) of undoing stage 2 (LZO, LZ4, zstd) over all "
                   "chunks, each chunk's segments on `threads` threads (0, the default: one per "
                   "core, as the player)");
    lcdvr_help_add(L, "cdvr.bench_memcpy(bytes [, repeats [, piece]])", "median memcpy MB/s for a buffer size (piece: copy into one reused buffer of that size)");
    lcdvr_help_add(L, "cdvr.clock()", "monotonic time in seconds");
    return 0;
}
