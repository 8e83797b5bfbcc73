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
    if (!ud->st)
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

static const char *const codec_names[] = {"raw", "pvtc", NULL};
static const char *const pack_names[] = {"time", "space", NULL};
static const char *const encoder_names[] = {"lsq", "bbox", NULL};
static const char *const stage2_names[] = {"none", "lzo", NULL};

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
    return luaL_error(L, "option '%s': invalid value '%s' (expected %s)", key, s,
                      lua_tostring(L, -1));
}

static int paramfield(lua_State *L, int idx, const char *key, int def, int a, int b)
{
    lua_Integer v = lcdvr_optintegerfield(L, idx, key, def);
    if (v != a && v != b)
        luaL_error(L, "option '%s': invalid value %d (expected %d or %d)", key, (int)v, a, b);
    return (int)v;
}

/* Fills *out from the table at idx, with base as defaults (the name is never inherited). */
static void parse_spec(lua_State *L, int idx, const cdvr_variant_spec *base, cdvr_variant_spec *out)
{
    *out = *base;
    out->codec = (cdvr_codec_id)optionfield(L, idx, "codec", codec_names, (int)base->codec);
    out->pvtc.S = paramfield(L, idx, "S", base->pvtc.S, 1, 4);
    out->pvtc.T = paramfield(L, idx, "T", base->pvtc.T, 2, 3);
    out->pvtc.pack = (cdvr_pack)optionfield(L, idx, "pack", pack_names, (int)base->pvtc.pack);
    out->encoder = (cdvr_pvtc_encoder)optionfield(L, idx, "encoder", encoder_names,
                                                  (int)base->encoder);
    out->stage2 = (cdvr_stage2)optionfield(L, idx, "stage2", stage2_names, (int)base->stage2);
    out->lzo_min_saving = lcdvr_optnumberfield(L, idx, "lzo_min_saving", base->lzo_min_saving);
    if (!(out->lzo_min_saving >= 0 && out->lzo_min_saving <= 1))
        luaL_error(L, "option 'lzo_min_saving': %f is not in [0, 1]", out->lzo_min_saving);
    const char *name = lcdvr_optstringfield(L, idx, "name", "");
    if (strlen(name) >= CDVR_NAME_MAX)
        luaL_error(L, "option 'name': '%s' is longer than %d bytes", name, CDVR_NAME_MAX - 1);
    memset(out->name, 0, sizeof out->name);
    memcpy(out->name, name, strlen(name));
}

/* Parses opts (at idx) into a userdata array of specs left on the stack; returns it. */
static cdvr_variant_spec *parse_variants(lua_State *L, int idx, size_t *n)
{
    cdvr_variant_spec base = {.codec = CDVR_CODEC_PVTC, .pvtc = {4, 3, CDVR_PACK_TIME},
                              .encoder = CDVR_ENCODER_LSQ, .stage2 = CDVR_STAGE2_LZO,
                              .lzo_min_saving = CDVR_LZO_MIN_SAVING};
    cdvr_variant_spec top;
    parse_spec(L, idx, &base, &top);
    int t = lua_getfield(L, idx, "variants");
    if (t != LUA_TNIL && t != LUA_TTABLE)
        luaL_error(L, "option 'variants': table expected, got %s", luaL_typename(L, -1));
    *n = t == LUA_TTABLE ? (size_t)luaL_len(L, -1) : 1;
    if (*n < 1 || *n > 256)
        luaL_error(L, "option 'variants': %d entries (expected 1..256)", (int)*n);
    cdvr_variant_spec *specs = lua_newuserdatauv(L, *n * sizeof *specs, 0);
    if (t != LUA_TTABLE)
        specs[0] = top;
    for (size_t i = 0; t == LUA_TTABLE && i < *n; i++) {
        if (lua_geti(L, -2, (lua_Integer)i + 1) != LUA_TTABLE)
            luaL_error(L, "option 'variants': entry %d is not a table", (int)i + 1);
        parse_spec(L, lua_gettop(L), &top, &specs[i]);
        lua_pop(L, 1);
    }
    for (size_t i = 0; i < *n; i++) /* the core's default names, known here for progress */
        if (specs[i].name[0] == '\0' && specs[i].codec == CDVR_CODEC_PVTC)
            snprintf(specs[i].name, sizeof specs[i].name, "S%dT%d%s", specs[i].pvtc.S,
                     specs[i].pvtc.T, specs[i].pvtc.pack == CDVR_PACK_SPACE ? "s" : "");
        else if (specs[i].name[0] == '\0')
            snprintf(specs[i].name, sizeof specs[i].name, "raw");
    lua_remove(L, -2); /* the variants table (or nil); the specs stay */
    return specs;
}

/* ---- schedule and progress callbacks ---------------------------------------------------- */

typedef struct encode_ctx {
    lua_State *L;
    int schedule_idx;            /* stack index of the Lua schedule, 0 if none */
    const cdvr_variant_spec *specs;
    size_t nvariants;
    size_t *chunks;              /* chunks per variant, counted during planning */
    int show_progress;
    int lua_failed;              /* the schedule raised or returned something invalid */
} encode_ctx;

static cdvr_status schedule_fail(encode_ctx *ctx, cdvr_error *err, const char *fmt, const char *a)
{
    ctx->lua_failed = 1;
    return cdvr_error_set(err, CDVR_ERR_ARG, fmt, a);
}

/* Reads {S=, T=, pack=} from the schedule's result without raising (we are inside the core). */
static cdvr_status schedule_result(encode_ctx *ctx, cdvr_pvtc_params *p, cdvr_error *err)
{
    lua_State *L = ctx->L;
    const char *keys[] = {"S", "T"};
    int *slots[] = {&p->S, &p->T};
    for (int k = 0; k < 2; k++) {
        int t = lua_getfield(L, -1, keys[k]);
        if (t != LUA_TNIL && !lua_isinteger(L, -1)) {
            lua_pop(L, 1);
            return schedule_fail(ctx, err, "schedule: field '%s' must be an integer", keys[k]);
        }
        if (t != LUA_TNIL)
            *slots[k] = (int)lua_tointeger(L, -1);
        lua_pop(L, 1);
    }
    int t = lua_getfield(L, -1, "pack");
    const char *pack = t == LUA_TSTRING ? lua_tostring(L, -1) : "";
    if (t != LUA_TNIL && strcmp(pack, "time") && strcmp(pack, "space")) {
        lua_pop(L, 1);
        return schedule_fail(ctx, err, "schedule: field 'pack' must be %s", "\"time\" or \"space\"");
    }
    if (t != LUA_TNIL)
        p->pack = strcmp(pack, "space") == 0 ? CDVR_PACK_SPACE : CDVR_PACK_TIME;
    lua_pop(L, 1);
    if ((p->S != 1 && p->S != 4) || (p->T != 2 && p->T != 3))
        return schedule_fail(ctx, err, "schedule: %s", "S must be 1 or 4 and T 2 or 3");
    return CDVR_OK;
}

static cdvr_status lua_schedule(void *ud, size_t variant, size_t t0, cdvr_pvtc_params *p,
                                cdvr_error *err)
{
    encode_ctx *ctx = ud;
    ctx->chunks[variant]++;
    if (!ctx->schedule_idx || ctx->specs[variant].codec != CDVR_CODEC_PVTC)
        return CDVR_OK;
    lua_State *L = ctx->L;
    lua_pushvalue(L, ctx->schedule_idx);
    lua_pushinteger(L, (lua_Integer)t0 + 1);
    lua_pushinteger(L, (lua_Integer)variant + 1);
    if (lua_pcall(L, 2, 1, 0) != LUA_OK) {
        cdvr_status s = schedule_fail(ctx, err, "schedule: %s",
                                      lua_isstring(L, -1) ? lua_tostring(L, -1) : "error");
        lua_pop(L, 1);
        return s;
    }
    cdvr_status s = CDVR_OK;
    if (lua_istable(L, -1))
        s = schedule_result(ctx, p, err);
    else if (!lua_isnil(L, -1))
        s = schedule_fail(ctx, err, "schedule: returned a %s (expected a table or nil)",
                          luaL_typename(L, -1));
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
    if (vol->type == CDVR_TYPE_U8) {
        o->qlo = 0;
        o->qhi = 255;
        return vol;
    }
    cdvr_volume_range(vol, &o->qlo, &o->qhi);
    cdvr_volume *q = NULL;
    cdvr_error err;
    if (cdvr_volume_quantize(vol, o->qlo, o->qhi, &q, NULL, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    lcdvr_pushvolume(L, q);
    return q;
}

static int l_encode(lua_State *L)
{
    const cdvr_volume *vol = lcdvr_checkvolume(L, 1);
    luaL_checktype(L, 2, LUA_TTABLE);
    const char *path = lcdvr_optstringfield(L, 2, "path", NULL);
    if (!path)
        return luaL_error(L, "cdvr.encode: option 'path' is required");
    lua_pushstring(L, path); /* keep it alive */
    path = lua_tostring(L, -1);
    int sched_type = lua_getfield(L, 2, "schedule");
    if (sched_type != LUA_TNIL && sched_type != LUA_TFUNCTION)
        return luaL_error(L, "option 'schedule': function expected, got %s", luaL_typename(L, -1));
    int schedule_idx = sched_type == LUA_TFUNCTION ? lua_gettop(L) : 0;
    encode_ctx ctx = {.L = L, .schedule_idx = schedule_idx};
    ctx.show_progress = lcdvr_optbooleanfield(L, 2, "progress", 1) && isatty(2);
    ctx.specs = parse_variants(L, 2, &ctx.nvariants);
    ctx.chunks = lua_newuserdatauv(L, ctx.nvariants * sizeof *ctx.chunks, 0);
    memset(ctx.chunks, 0, ctx.nvariants * sizeof *ctx.chunks);
    cdvr_encode_opts o = {.variants = ctx.specs, .nvariants = ctx.nvariants,
                          .schedule = lua_schedule, .schedule_ud = &ctx,
                          .progress = lua_progress, .progress_ud = &ctx};
    const cdvr_volume *u8 = encode_input(L, vol, &o);
    cdvr_error err;
    cdvr_status s = cdvr_store_encode(u8, &o, path, &err);
    if (s == CDVR_ERR_IO)
        return lcdvr_fail(L, &err);
    if (s != CDVR_OK)
        return lcdvr_raise(L, &err);
    cdvr_store *st = NULL;
    if (cdvr_store_open(path, &st, &err) != CDVR_OK)
        return lcdvr_fail(L, &err);
    pushstore(L, st);
    return 1;
}

static int l_open(lua_State *L)
{
    const char *path = luaL_checkstring(L, 1);
    cdvr_store *st = NULL;
    cdvr_error err;
    if (cdvr_store_open(path, &st, &err) != CDVR_OK)
        return lcdvr_fail(L, &err);
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
        int v = cdvr_store_find_variant(st, lua_tostring(L, idx));
        if (v < 0)
            luaL_argerror(L, idx, lua_pushfstring(L, "no variant '%s' in %s", lua_tostring(L, idx),
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

static void push_variant_info(lua_State *L, const cdvr_store_info *in, const cdvr_variant_info *vi)
{
    lua_createtable(L, 0, 14);
    setstr(L, "name", vi->name);
    setstr(L, "codec", vi->codec_name);
    if (vi->codec == CDVR_CODEC_PVTC) {
        setint(L, "S", vi->pvtc.S);
        setint(L, "T", vi->pvtc.T);
        setstr(L, "pack", pack_names[vi->pvtc.pack]);
        setstr(L, "encoder", encoder_names[vi->encoder]);
    }
    setstr(L, "stage2", stage2_names[vi->stage2]);
    setint(L, "bytes", (lua_Integer)vi->bytes);
    setint(L, "payload_bytes", (lua_Integer)vi->payload_bytes);
    setnum(L, "ratio", (double)vi->bytes / (double)in->raw_bytes);
    setnum(L, "bpv", 8.0 * (double)vi->bytes / (double)in->raw_bytes);
    setnum(L, "psnr", vi->psnr);
    setnum(L, "maxerr", vi->maxerr);
    setint(L, "chunks", (lua_Integer)vi->nchunks);
}

static int store_info(lua_State *L)
{
    const cdvr_store *st = lcdvr_checkstore(L, 1);
    const cdvr_store_info *in = cdvr_store_get_info(st);
    lua_createtable(L, 0, 10);
    setstr(L, "path", cdvr_store_path(st));
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
    lua_createtable(L, 2, 0);
    lua_pushnumber(L, in->qlo);
    lua_rawseti(L, -2, 1);
    lua_pushnumber(L, in->qhi);
    lua_rawseti(L, -2, 2);
    lua_setfield(L, -2, "window");
    setstr(L, "source_type", cdvr_type_name(in->source_type));
    uint64_t bytes = 0;
    lua_createtable(L, (int)in->nvariants, 0);
    for (size_t v = 0; v < in->nvariants; v++) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, v);
        bytes += vi->bytes;
        push_variant_info(L, in, vi);
        lua_rawseti(L, -2, (lua_Integer)v + 1);
    }
    lua_setfield(L, -2, "variants");
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
    int device = opts ? optionfield(L, opts, "device", devices, 0) : 0;
    if (device == 1)
        return lcdvr_decode_cl(L, st, v, (size_t)t - 1);
    cdvr_volume *vol = NULL;
    cdvr_error err;
    if (cdvr_store_decode(st, v, (size_t)t - 1, &vol, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lcdvr_pushvolume(L, vol);
    return 1;
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
    lua_createtable(L, 0, 8);
    setint(L, "t0", (lua_Integer)ci->t0 + 1);
    setint(L, "timesteps", (lua_Integer)ci->count);
    if (vi->codec == CDVR_CODEC_PVTC) {
        setint(L, "S", ci->pvtc.S);
        setint(L, "T", ci->pvtc.T);
        setstr(L, "pack", pack_names[ci->pvtc.pack]);
    }
    setint(L, "stored_bytes", (lua_Integer)ci->stored_bytes);
    setint(L, "payload_bytes", (lua_Integer)ci->payload_bytes);
    lua_pushboolean(L, ci->stage2);
    lua_setfield(L, -2, "stage2");
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
    cdvr_store_close(ud->st);
    ud->st = NULL;
    return 0;
}

static int store_tostring(lua_State *L)
{
    lstore *ud = tolstore(L, 1);
    if (!ud->st) {
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
            if (cdvr_store_unpack_chunk(st, v, c, stored[c], out, &err) != CDVR_OK)
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
    {"close", store_gc},          {"bench_decode", store_bench_decode},
    {"bench_unpack", store_bench_unpack}, {NULL, NULL}};

static const luaL_Reg store_meta[] = {
    {"__gc", store_gc}, {"__close", store_gc}, {"__tostring", store_tostring}, {NULL, NULL}};

static const luaL_Reg store_funcs[] = {{"encode", l_encode},
                                       {"open", l_open},
                                       {"clock", l_clock},
                                       {"bench_memcpy", l_bench_memcpy},
                                       {NULL, NULL}};

int lcdvr_open_store(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_STORE, store_methods, store_meta);
    lcdvr_setfuncs(L, store_funcs);
    lcdvr_help_add(L, "cdvr.encode(volume, {path=, codec=, S=, T=, pack=, encoder=, stage2=, "
                      "lzo_min_saving=, name=, variants=, schedule=, progress=})",
                   "encode a series into a .cdv store (written atomically; defaults codec=pvtc "
                   "S=4 T=3 pack=time encoder=lsq stage2=lzo lzo_min_saving=0.1); the opened "
                   "store, or nil, msg on write failure");
    lcdvr_help_add(L, "cdvr.open(path)", "open a .cdv store (lazy); store or nil, msg");
    lcdvr_help_add(L, "st:info()", "dims, timesteps, window, bytes, ratio and per-variant "
                                   "codec, bpv, psnr, maxerr, chunks");
    lcdvr_help_add(L, "st:decode(t [, variant] [, {device=\"cpu\"|\"cl\"}])",
                   "u8 volume of timestep t (from 1) of a variant (name or index, default 1)");
    lcdvr_help_add(L, "st:chunk(i [, variant])", "payload bytes of chunk i after stage 2, and "
                                                 "{t0=, timesteps=, S=, T=, pack=, stored_bytes=, stage2=}");
    lcdvr_help_add(L, "st:variants()", "list of variant names");
    lcdvr_help_add(L, "st:close()", "close the store file");
    lcdvr_help_add(L, "st:bench_decode([variant] [, repeats])",
                   "median MB/s (output bytes) of the C decoder over all chunks, single thread");
    lcdvr_help_add(L, "st:bench_unpack([variant] [, repeats])",
                   "median MB/s (payload bytes) of undoing stage 2 (LZO) over all chunks");
    lcdvr_help_add(L, "cdvr.bench_memcpy(bytes [, repeats [, piece]])", "median memcpy MB/s for a buffer size (piece: copy into one reused buffer of that size)");
    lcdvr_help_add(L, "cdvr.clock()", "monotonic time in seconds");
    return 0;
}
