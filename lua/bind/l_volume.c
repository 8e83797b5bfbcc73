/* lua/bind/l_volume.c - cdvr.Volume: volumes and series in Lua (cdvr.load, v:dims(), ...). */
#include "lcdvr.h"
#include "cdvr/format.h"
#include "cdvr/plugin.h"
#include "cdvr/series.h"
#include "cdvr/write.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- lazy volumes -------------------------------------------------------------------------
 * cdvr.load_series gives a volume that reads its files as it needs them (cdvr/series.h): its
 * dims, type, geometry and timestep count come from the first file; a timestep is read when
 * something asks for it (v:get, v:frame, cdvr.render{t=}, cdvr.encode one timestep at a time),
 * and v:quantize of it is lazy too (codes made while reading). What needs every voxel at once
 * (v:set, v:save_raw, cdvr.compare, ...) reads all timesteps into memory first, once; from then
 * on the volume is an ordinary one. Its value window (volume.h) is that of a volume in memory:
 * [0, 255] for u8 files, the quantisation window of v:quantize, else the range of every
 * timestep, which one pass over the files computes the first time it is needed. */

/* The files, shared by a lazy series and the lazy volumes v:quantize makes of it. */
typedef struct lazy_source {
    cdvr_series *series;
    int refs;
} lazy_source;

typedef struct lazy_volume {
    lazy_source *src;
    cdvr_series_view view;       /* the series, or the u8 codes of its values over a window */
    cdvr_volume head;            /* dims, timesteps, type, geometry, window; no voxels */
    int range_known;             /* v:range of the codes (quantized) */
    double range_lo, range_hi;
    cdvr_series_source enc;      /* what the encode source reads (lcdvr_volume_source) */
} lazy_volume;

typedef struct lvolume {
    cdvr_volume *vol;            /* the voxels; NULL once closed, and for a lazy volume until
                                    something needs all of them */
    lazy_volume *lazy;           /* cdvr.load_series: read from the files as needed */
    int closed;
} lvolume;

static lvolume *tolvolume(lua_State *L, int idx)
{
    return (lvolume *)luaL_checkudata(L, idx, LCDVR_VOLUME);
}

static void lazy_free(lazy_volume *lv)
{
    if (!lv)
        return;
    if (--lv->src->refs == 0) {
        cdvr_series_close(lv->src->series);
        free(lv->src);
    }
    free(lv);
}

/* Range pass progress on stderr when it is a terminal. */
static void range_progress(void *ud, size_t done, size_t total)
{
    (void)ud;
    fprintf(stderr, "\rcdvr: value range of the series: %zu/%zu files", done, total);
    if (done == total)
        fputc('\n', stderr);
    fflush(stderr);
}

/* Range passes over the files show progress on stderr when it is a terminal. */
#define PROGRESS (isatty(2) ? range_progress : NULL)

/* The window of a lazy volume (see above), cached in its head. */
static cdvr_status lazy_window(lazy_volume *lv, double w[2], cdvr_error *err)
{
    cdvr_status st = cdvr_series_view_window(&lv->view, w, PROGRESS, NULL, err);
    if (st == CDVR_OK && !lv->view.quantized && lv->head.type != CDVR_TYPE_U8) {
        lv->head.window[0] = w[0];
        lv->head.window[1] = w[1];
    }
    return st;
}

/* Timesteps [t, t + count) as a new volume in memory, with the lazy volume's window. */
static cdvr_status lazy_read(lazy_volume *lv, size_t t, size_t count, cdvr_volume **out,
                             cdvr_error *err)
{
    double w[2];
    cdvr_status st = lazy_window(lv, w, err); /* caches the window in head */
    return st == CDVR_OK ? cdvr_series_view_read(&lv->view, t, count, out, NULL, NULL, err) : st;
}

/* Reads every timestep of a lazy volume into memory: from now on it is an ordinary volume. */
static void materialise(lua_State *L, lvolume *ud)
{
    cdvr_error err;
    cdvr_volume *all = NULL;
    if (lazy_read(ud->lazy, 0, ud->lazy->head.timesteps, &all, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    ud->vol = all;
}

/* The volume at idx, open; raises for a closed one. */
static lvolume *checkopen(lua_State *L, int idx)
{
    lvolume *ud = tolvolume(L, idx);
    if (ud->closed || lcdvr_closing(L, idx))
        luaL_error(L, "attempt to use a closed volume");
    return ud;
}

cdvr_volume *lcdvr_checkvolume(lua_State *L, int idx)
{
    lvolume *ud = checkopen(L, idx);
    if (!ud->vol)
        materialise(L, ud);
    return ud->vol;
}

/* The header of a volume; a lazy one's counts the values beyond f32 of the files read so far. */
static const cdvr_volume *header_of(lvolume *ud)
{
    if (ud->vol)
        return ud->vol;
    ud->lazy->head.beyond_f32 = cdvr_series_get_info(ud->lazy->src->series)->beyond_f32;
    return &ud->lazy->head;
}

const cdvr_volume *lcdvr_volume_header(lua_State *L, int idx)
{
    return header_of(checkopen(L, idx));
}

int lcdvr_volume_lazy(lua_State *L, int idx)
{
    lvolume *ud = checkopen(L, idx);
    return ud->vol == NULL;
}

cdvr_volume *lcdvr_volume_read(lua_State *L, int idx, size_t t, size_t count)
{
    lvolume *ud = checkopen(L, idx);
    cdvr_volume *out = NULL;
    cdvr_error err;
    cdvr_status st;
    if (ud->vol) {
        double w[2];
        cdvr_volume_window(ud->vol, w); /* cached: frames keep the series' window */
        st = cdvr_volume_slice_time(ud->vol, t, count, &out, &err);
    } else {
        st = lazy_read(ud->lazy, t, count, &out, &err);
    }
    if (st != CDVR_OK)
        lcdvr_raise(L, &err);
    lcdvr_pushvolume(L, out);
    return out;
}

void lcdvr_volume_source(lua_State *L, int idx, cdvr_encode_source *src, cdvr_encode_opts *o)
{
    lvolume *ud = checkopen(L, idx);
    lazy_volume *lv = ud->lazy;
    if (ud->vol || !lv)
        luaL_error(L, "internal error: lcdvr_volume_source on a volume in memory");
    double w[2];
    cdvr_error err;
    if (lazy_window(lv, w, &err) != CDVR_OK ||
        cdvr_series_encode_source(&lv->view, &lv->enc, src, o, NULL, NULL, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    memcpy(src->spacing, lv->head.spacing, sizeof src->spacing); /* the volume's geometry */
    memcpy(src->origin, lv->head.origin, sizeof src->origin);
    cdvr_volume_direction(&lv->head, src->direction);
}

void lcdvr_pushvolume(lua_State *L, cdvr_volume *vol)
{
    lvolume *ud = (lvolume *)lua_newuserdatauv(L, sizeof *ud, 0);
    ud->vol = vol;
    ud->lazy = NULL;
    ud->closed = 0;
    luaL_setmetatable(L, LCDVR_VOLUME);
}

/* Pushes a lazy volume over src (one more reference to it); it takes lv. */
static void push_lazy(lua_State *L, lazy_volume *lv)
{
    lvolume *ud = (lvolume *)lua_newuserdatauv(L, sizeof *ud, 0);
    ud->vol = NULL;
    ud->lazy = lv;
    ud->closed = 0;
    luaL_setmetatable(L, LCDVR_VOLUME);
}

static int volume_gc(lua_State *L)
{
    lvolume *ud = tolvolume(L, 1);
    if (lcdvr_defer_close(L, 1)) /* cdvr.encode still reads it: freed when it is done */
        return 0;
    lcdvr_render_ctx_release(L, ud->vol); /* a render context may hold it (l_render.c) */
    cdvr_volume_free(ud->vol);
    lazy_free(ud->lazy);
    ud->vol = NULL;
    ud->lazy = NULL;
    ud->closed = 1;
    return 0;
}

static int volume_tostring(lua_State *L)
{
    lvolume *ud = tolvolume(L, 1);
    if (ud->closed) {
        lua_pushliteral(L, "cdvr.Volume (closed)");
        return 1;
    }
    const cdvr_volume *v = header_of(ud);
    char conv[96] = "";
    if (cdvr_volume_converted(v))
        snprintf(conv, sizeof conv, ", converted from %s", v->source_type);
    if (v->beyond_f32)
        snprintf(conv + strlen(conv), sizeof conv - strlen(conv), ", %llu values beyond f32 as +-Inf",
                 (unsigned long long)v->beyond_f32);
    lua_pushfstring(L, "cdvr.Volume %dx%dx%d x %d %s%s%s (%p)", (int)v->dims[0], (int)v->dims[1],
                    (int)v->dims[2], (int)v->timesteps, cdvr_type_name(v->type), conv,
                    ud->vol ? "" : ", read from its files as needed", (void *)ud);
    return 1;
}

/* The time values of a series from ParaView collections (cdvr_series_times), or NULL. */
static const double *volume_time_values(lvolume *ud)
{
    return ud->lazy ? cdvr_series_times(ud->lazy->src->series) : NULL;
}

/* v:times(): {t1, t2, ...} of a series read from .pvd collections, else nil. */
static int volume_times(lua_State *L)
{
    lvolume *ud = checkopen(L, 1);
    const double *t = volume_time_values(ud);
    const cdvr_volume *v = lcdvr_volume_header(L, 1);
    if (!t) {
        lua_pushnil(L);
        return 1;
    }
    lua_createtable(L, (int)v->timesteps, 0);
    for (size_t i = 0; i < v->timesteps; i++) {
        lua_pushnumber(L, t[i]);
        lua_seti(L, -2, (lua_Integer)i + 1);
    }
    return 1;
}

/* v:info(): {type=, source_type=, converted=, lazy=, files=, times=} (see the help text). */
static int volume_info(lua_State *L)
{
    lvolume *ud = checkopen(L, 1);
    const cdvr_volume *v = lcdvr_volume_header(L, 1);
    lua_createtable(L, 0, 6);
    lua_pushstring(L, cdvr_type_name(v->type));
    lua_setfield(L, -2, "type");
    if (v->source_type[0]) {
        lua_pushstring(L, v->source_type);
        lua_setfield(L, -2, "source_type");
    }
    lua_pushboolean(L, cdvr_volume_converted(v));
    lua_setfield(L, -2, "converted");
    if (v->beyond_f32) {
        lua_pushinteger(L, (lua_Integer)v->beyond_f32);
        lua_setfield(L, -2, "beyond_f32");
    }
    if (v->space[0]) {
        lua_pushstring(L, v->space);
        lua_setfield(L, -2, "space");
    }
    lua_pushboolean(L, ud->vol == NULL);
    lua_setfield(L, -2, "lazy");
    if (ud->lazy) {
        lua_pushinteger(L, (lua_Integer)cdvr_series_get_info(ud->lazy->src->series)->files);
        lua_setfield(L, -2, "files");
    }
    if (volume_time_values(ud)) {
        volume_times(L);
        lua_setfield(L, -2, "times");
    }
    return 1;
}

static int volume_dims(lua_State *L)
{
    const cdvr_volume *v = lcdvr_volume_header(L, 1);
    for (int i = 0; i < 3; i++)
        lua_pushinteger(L, (lua_Integer)v->dims[i]);
    return 3;
}

static int volume_type(lua_State *L)
{
    lua_pushstring(L, cdvr_type_name(lcdvr_volume_header(L, 1)->type));
    return 1;
}

static int volume_timesteps(lua_State *L)
{
    lua_pushinteger(L, (lua_Integer)lcdvr_volume_header(L, 1)->timesteps);
    return 1;
}

/* Range of the codes of a lazy quantized volume: one pass over its files (cached). */
static cdvr_status lazy_code_range(lazy_volume *lv, double *lo, double *hi, cdvr_error *err)
{
    if (!lv->range_known) {
        cdvr_status st = cdvr_series_view_scan(&lv->view, NULL, &lv->range_lo, &lv->range_hi,
                                               err);
        if (st != CDVR_OK)
            return st;
        lv->range_known = 1;
    }
    *lo = lv->range_lo;
    *hi = lv->range_hi;
    return CDVR_OK;
}

static int volume_range(lua_State *L)
{
    lvolume *ud = checkopen(L, 1);
    double lo, hi;
    cdvr_error err;
    cdvr_status st = CDVR_OK;
    if (ud->vol)
        cdvr_volume_range(ud->vol, &lo, &hi);
    else if (ud->lazy->view.quantized)
        st = lazy_code_range(ud->lazy, &lo, &hi, &err);
    else
        st = cdvr_series_range(ud->lazy->src->series, &lo, &hi, PROGRESS, NULL, &err);
    if (st != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_pushnumber(L, lo);
    lua_pushnumber(L, hi);
    return 2;
}

static double value_of(const void *voxels, cdvr_type type, size_t i)
{
    switch (type) {
    case CDVR_TYPE_U8: return ((const uint8_t *)voxels)[i];
    case CDVR_TYPE_U16: return ((const uint16_t *)voxels)[i];
    case CDVR_TYPE_I16: return ((const int16_t *)voxels)[i];
    case CDVR_TYPE_F32: return ((const float *)voxels)[i];
    }
    return 0;
}

static int volume_get(lua_State *L)
{
    lvolume *ud = checkopen(L, 1);
    const cdvr_volume *v = lcdvr_volume_header(L, 1);
    lua_Integer c[4];
    for (int i = 0; i < 3; i++) {
        c[i] = luaL_checkinteger(L, i + 2);
        luaL_argcheck(L, c[i] >= 0 && (size_t)c[i] < v->dims[i], i + 2, "voxel coordinate out of range");
    }
    c[3] = luaL_optinteger(L, 5, 1);
    luaL_argcheck(L, c[3] >= 1 && (size_t)c[3] <= v->timesteps, 5, "timestep out of range");
    if (ud->vol) {
        lua_pushnumber(L, cdvr_volume_get(v, (size_t)c[0], (size_t)c[1], (size_t)c[2], (size_t)c[3] - 1));
        return 1;
    }
    const void *voxels;
    cdvr_error err;
    lazy_volume *lv = ud->lazy;
    if (cdvr_series_frame(lv->src->series, (size_t)c[3] - 1, &voxels, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    cdvr_type type = cdvr_series_get_info(lv->src->series)->type;
    size_t i = (size_t)c[0] + v->dims[0] * ((size_t)c[1] + v->dims[1] * (size_t)c[2]);
    if (!lv->view.quantized) {
        lua_pushnumber(L, value_of(voxels, type, i));
        return 1;
    }
    uint8_t code;
    const uint8_t *at = (const uint8_t *)voxels + i * cdvr_type_size(type);
    if (cdvr_quantize_values(at, type, 1, lv->view.lo, lv->view.hi, &code, NULL, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_pushnumber(L, code);
    return 1;
}

static int volume_len(lua_State *L)
{
    return volume_timesteps(L);
}

static int push_triple(lua_State *L, const double v[3])
{
    for (int i = 0; i < 3; i++)
        lua_pushnumber(L, v[i]);
    return 3;
}

static int volume_spacing(lua_State *L)
{
    return push_triple(L, lcdvr_volume_header(L, 1)->spacing);
}

static int volume_origin(lua_State *L)
{
    return push_triple(L, lcdvr_volume_header(L, 1)->origin);
}

static int volume_direction(lua_State *L)
{
    double D[9];
    cdvr_volume_direction(lcdvr_volume_header(L, 1), D);
    for (int i = 0; i < 9; i++)
        lua_pushnumber(L, D[i]);
    return 9;
}

/* xmin, xmax, ymin, ymax, zmin, zmax of the oriented box (VTK's GetBounds order). */
static int volume_bounds(lua_State *L)
{
    double lo[3], hi[3];
    cdvr_volume_bounds(lcdvr_volume_header(L, 1), lo, hi);
    for (int a = 0; a < 3; a++) {
        lua_pushnumber(L, lo[a]);
        lua_pushnumber(L, hi[a]);
    }
    return 6;
}

/* World position of voxel (i, j, k) (from 0, fractional allowed). */
static int volume_to_world(lua_State *L)
{
    const cdvr_volume *v = lcdvr_volume_header(L, 1);
    double ijk[3], xyz[3];
    for (int a = 0; a < 3; a++)
        ijk[a] = luaL_checknumber(L, a + 2);
    cdvr_volume_index_to_world(v, ijk, xyz);
    return push_triple(L, xyz);
}

static int volume_window(lua_State *L)
{
    lvolume *ud = checkopen(L, 1);
    double w[2];
    cdvr_error err;
    if (ud->vol)
        cdvr_volume_window(ud->vol, w);
    else if (lazy_window(ud->lazy, w, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_pushnumber(L, w[0]);
    lua_pushnumber(L, w[1]);
    return 2;
}

static int volume_bytes(lua_State *L)
{
    const cdvr_volume *v = lcdvr_volume_header(L, 1);
    lua_pushinteger(L, (lua_Integer)(cdvr_volume_frame_bytes(v) * v->timesteps));
    return 1;
}

static size_t check_timestep(lua_State *L, const cdvr_volume *v, int arg)
{
    lua_Integer t = luaL_checkinteger(L, arg);
    luaL_argcheck(L, t >= 1 && (lua_Unsigned)t <= v->timesteps, arg, "timestep out of range");
    return (size_t)t - 1;
}

static int volume_frame(lua_State *L)
{
    const cdvr_volume *v = lcdvr_volume_header(L, 1);
    size_t t = check_timestep(L, v, 2);
    lua_Integer count = luaL_optinteger(L, 3, 1);
    luaL_argcheck(L, count >= 1 && (lua_Unsigned)count <= v->timesteps - t, 3, "timestep count out of range");
    lcdvr_volume_read(L, 1, t, (size_t)count);
    return 1;
}

static void voxel_coords(lua_State *L, const cdvr_volume *v, size_t c[3])
{
    for (int i = 0; i < 3; i++) {
        lua_Integer x = luaL_checkinteger(L, i + 2);
        luaL_argcheck(L, x >= 0 && (lua_Unsigned)x < v->dims[i], i + 2, "voxel coordinate out of range");
        c[i] = (size_t)x;
    }
}

/* Stores value at element i; integer types take integers in their range, f32 any number. */
static void set_value(lua_State *L, cdvr_volume *v, size_t i, int arg)
{
    if (v->type == CDVR_TYPE_F32) {
        ((float *)v->data)[i] = (float)luaL_checknumber(L, arg);
        return;
    }
    static const lua_Integer lo[] = {0, 0, -32768}, hi[] = {255, 65535, 32767};
    lua_Integer x = luaL_checkinteger(L, arg);
    if (x < lo[v->type] || x > hi[v->type])
        luaL_argerror(L, arg, lua_pushfstring(L, "value %I out of range for %s", x, cdvr_type_name(v->type)));
    if (v->type == CDVR_TYPE_U8)
        ((uint8_t *)v->data)[i] = (uint8_t)x;
    else if (v->type == CDVR_TYPE_U16)
        ((uint16_t *)v->data)[i] = (uint16_t)x;
    else
        ((int16_t *)v->data)[i] = (int16_t)x;
}

static int volume_set(lua_State *L)
{
    cdvr_volume *v = lcdvr_checkvolume(L, 1);
    size_t c[3], t = 0;
    voxel_coords(L, v, c);
    int value_arg = 5;
    if (lua_gettop(L) >= 6) {
        t = check_timestep(L, v, 5);
        value_arg = 6;
    }
    size_t i = c[0] + v->dims[0] * (c[1] + v->dims[1] * (c[2] + v->dims[2] * t));
    set_value(L, v, i, value_arg);
    cdvr_volume_touch(v); /* a render context that holds v uploads it again */
    if (v->type != CDVR_TYPE_U8) /* the series range may have changed */
        v->window[0] = v->window[1] = NAN;
    return 0;
}

static void push_report(lua_State *L, const cdvr_quantize_report *r)
{
    lua_createtable(L, 0, 5);
    lua_pushinteger(L, (lua_Integer)(r->clipped_low + r->clipped_high));
    lua_setfield(L, -2, "clipped");
    lua_pushinteger(L, (lua_Integer)r->clipped_low);
    lua_setfield(L, -2, "clipped_low");
    lua_pushinteger(L, (lua_Integer)r->clipped_high);
    lua_setfield(L, -2, "clipped_high");
    lua_pushinteger(L, (lua_Integer)r->nan_count);
    lua_setfield(L, -2, "nan");
    lua_pushinteger(L, (lua_Integer)r->inf_count);
    lua_setfield(L, -2, "inf");
}

/* __index of a lazy quantize report: counts the clipped, NaN and Inf values of the source (one
 * pass over its files) the first time a field is read. Upvalue 1: the quantized volume. */
static int lazy_report_index(lua_State *L)
{
    lvolume *ud = tolvolume(L, lua_upvalueindex(1));
    if (ud->closed)
        return luaL_error(L, "quantize report: its volume is closed");
    cdvr_quantize_report r = {0};
    cdvr_error err;
    if (cdvr_series_view_scan(&ud->lazy->view, &r, NULL, NULL, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_pushnil(L);
    lua_setmetatable(L, 1); /* counted once: the fields are plain from now on */
    static const char *const names[] = {"clipped", "clipped_low", "clipped_high", "nan", "inf"};
    size_t values[] = {r.clipped_low + r.clipped_high, r.clipped_low, r.clipped_high,
                       r.nan_count, r.inf_count};
    for (int i = 0; i < 5; i++) {
        lua_pushinteger(L, (lua_Integer)values[i]);
        lua_setfield(L, 1, names[i]);
    }
    lua_rawget(L, 1); /* the field asked for (key at 2) */
    return 1;
}

/* v:quantize of a lazy series (not yet quantized): a lazy u8 volume over [lo, hi] and a report
 * table whose counts come from a pass over the files when first read. */
static int quantize_lazy(lua_State *L, lvolume *ud)
{
    lazy_volume *src = ud->lazy;
    double lo, hi;
    cdvr_error err;
    if (!lua_isnoneornil(L, 2))
        luaL_checktype(L, 2, LUA_TTABLE);
    int has_lo = !lua_isnoneornil(L, 2) && lua_getfield(L, 2, "lo") != LUA_TNIL;
    int has_hi = !lua_isnoneornil(L, 2) && lua_getfield(L, 2, "hi") != LUA_TNIL;
    lua_settop(L, 2);
    if ((!has_lo || !has_hi) &&
        cdvr_series_range(src->src->series, &lo, &hi, PROGRESS, NULL, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    if (!lua_isnoneornil(L, 2)) {
        lo = lcdvr_optnumberfield(L, 2, "lo", lo);
        hi = lcdvr_optnumberfield(L, 2, "hi", hi);
    }
    if (!isfinite(lo) || !isfinite(hi) || hi < lo)
        return luaL_error(L, "quantize: window [%f, %f] must be finite with lo <= hi", lo, hi);
    lazy_volume *lv = calloc(1, sizeof *lv);
    if (!lv)
        return luaL_error(L, "quantize: out of memory");
    lv->src = src->src;
    lv->src->refs++;
    lv->head = src->head;
    lv->head.type = CDVR_TYPE_U8;
    cdvr_volume_set_source_type(&lv->head, NULL); /* codes, as cdvr_volume_quantize gives */
    lv->view = (cdvr_series_view){lv->src->series, 1, lo, hi};
    lv->head.window[0] = lo;
    lv->head.window[1] = hi;
    push_lazy(L, lv);                                  /* q */
    lua_newtable(L);                                   /* q, report */
    lua_createtable(L, 0, 1);                          /* q, report, mt */
    lua_pushvalue(L, -3);
    lua_pushcclosure(L, lazy_report_index, 1);
    lua_setfield(L, -2, "__index");
    lua_setmetatable(L, -2);                           /* q, report */
    return 2;
}

static int volume_quantize(lua_State *L)
{
    static const char *const keys[] = {"lo", "hi", NULL};
    lcdvr_checkoptions(L, 2, "v:quantize", keys);
    lvolume *ud = checkopen(L, 1);
    if (!ud->vol && !ud->lazy->view.quantized)
        return quantize_lazy(L, ud);
    const cdvr_volume *v = lcdvr_checkvolume(L, 1);
    double lo, hi;
    cdvr_volume_range(v, &lo, &hi);
    if (!lua_isnoneornil(L, 2)) {
        luaL_checktype(L, 2, LUA_TTABLE);
        lo = lcdvr_optnumberfield(L, 2, "lo", lo);
        hi = lcdvr_optnumberfield(L, 2, "hi", hi);
    }
    cdvr_volume *q;
    cdvr_quantize_report report;
    cdvr_error err;
    if (cdvr_volume_quantize(v, lo, hi, &q, &report, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lcdvr_pushvolume(L, q);
    push_report(L, &report);
    return 2;
}

static int check_endian(lua_State *L, int idx)
{
    static const char *const names[] = {"little", "big", NULL};
    const char *e = lcdvr_optstringfield(L, idx, "endian", "little");
    for (int i = 0; names[i]; i++)
        if (strcmp(e, names[i]) == 0)
            return i;
    return lcdvr_error(L, "option 'endian': \"little\" or \"big\" expected, got \"%s\"", e);
}

static int volume_save_raw(lua_State *L)
{
    static const char *const keys[] = {"endian", NULL};
    lcdvr_checkoptions(L, 3, "v:save_raw", keys);
    const cdvr_volume *v = lcdvr_checkvolume(L, 1);
    const char *path = luaL_checkstring(L, 2);
    int big_endian = 0;
    if (!lua_isnoneornil(L, 3)) {
        luaL_checktype(L, 3, LUA_TTABLE);
        big_endian = check_endian(L, 3);
    }
    cdvr_error err;
    if (cdvr_volume_save_raw(v, path, big_endian, &err) != CDVR_OK)
        return lcdvr_fail(L, &err);
    lua_pushboolean(L, 1);
    return 1;
}

/* v:save(path [, {compress=}]): cdvr_volume_save (cdvr/write.h); a lazy series (cdvr.load_series)
 * is read into memory first (all its timesteps); a series from .pvd files passes its times (a
 * .pvd or .vti series target writes them). I/O failures return nil, msg; misuse (an unknown
 * suffix, compress= against the suffix) raises. */
static int volume_save(lua_State *L)
{
    static const char *const keys[] = {"compress", NULL};
    lcdvr_checkoptions(L, 3, "v:save", keys);
    const double *times = volume_time_values(checkopen(L, 1)); /* a .pvd series keeps them */
    const cdvr_volume *v = lcdvr_checkvolume(L, 1);
    const char *path = luaL_checkstring(L, 2);
    cdvr_save_opts o = {-1, times};
    if (!lua_isnoneornil(L, 3)) {
        luaL_checktype(L, 3, LUA_TTABLE);
        lua_getfield(L, 3, "compress");
        int given = !lua_isnil(L, -1);
        lua_pop(L, 1);
        if (given)
            o.compress = lcdvr_optbooleanfield(L, 3, "compress", 0);
    }
    cdvr_error err;
    cdvr_status st = cdvr_volume_save(v, path, &o, &err);
    if (st == CDVR_ERR_IO)
        return lcdvr_fail(L, &err);
    if (st != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_pushboolean(L, 1);
    return 1;
}

/* ---- constructors and loaders -------------------------------------------------------------- */

/* dims={x,y,z} as positive integers; returns 0 if absent. */
static int dims_field(lua_State *L, int idx, size_t dims[3])
{
    double d[3];
    if (!lcdvr_numberarrayfield(L, idx, "dims", d, 3))
        return 0;
    for (int i = 0; i < 3; i++) {
        if (!(d[i] >= 1 && d[i] <= 9007199254740992.0 && d[i] == floor(d[i])))
            lcdvr_error(L, "option 'dims'[%d]: positive integer expected, got %f", i + 1, d[i]);
        dims[i] = (size_t)d[i];
    }
    return 1;
}

static cdvr_type type_field(lua_State *L, int idx, const char *def)
{
    const char *name = lcdvr_optstringfield(L, idx, "type", def);
    cdvr_type type;
    if (!name)
        lcdvr_error(L, "option 'type' is required (u8, u16, i16, f32)");
    if (!cdvr_type_parse(name, &type))
        lcdvr_error(L, "option 'type': unknown voxel type '%s' (u8, u16, i16, f32)", name);
    return type;
}

static size_t count_field(lua_State *L, int idx, const char *key, lua_Integer def, lua_Integer min)
{
    lua_Integer n = lcdvr_optintegerfield(L, idx, key, def);
    if (n < min)
        lcdvr_error(L, "option '%s': must be >= %d, got %d", key, (int)min, (int)n);
    return (size_t)n;
}

/* spacing={sx,sy,sz} (positive) into out; leaves out as is when absent. */
static void spacing_field(lua_State *L, int idx, double out[3])
{
    double s[3];
    if (!lcdvr_numberarrayfield(L, idx, "spacing", s, 3))
        return;
    for (int i = 0; i < 3; i++) {
        if (!(s[i] > 0 && isfinite(s[i])))
            lcdvr_error(L, "option 'spacing'[%d]: positive number expected", i + 1);
        out[i] = s[i];
    }
}

/* The readers' limits (cdvr_raw_opts): allow_outside (boolean: a NRRD header may name data
 * files outside its directory), max_bytes (positive integer: the voxel bytes a file may
 * claim; default half the physical memory) and select (the object inside the file). */
static void limit_fields(lua_State *L, int idx, cdvr_raw_opts *raw)
{
    lua_getfield(L, idx, "allow_outside");
    if (!lua_isnil(L, -1) && !lua_isboolean(L, -1))
        lcdvr_error(L, "option 'allow_outside': boolean expected, got %s", luaL_typename(L, -1));
    raw->allow_outside = lua_toboolean(L, -1);
    lua_pop(L, 1);
    lua_getfield(L, idx, "max_bytes");
    if (!lua_isnil(L, -1)) {
        int isnum = 0;
        lua_Integer n = lua_tointegerx(L, -1, &isnum);
        if (!isnum || n < 1)
            lcdvr_error(L, "option 'max_bytes': positive integer expected, got %s",
                       luaL_tolstring(L, -1, NULL));
        raw->max_bytes = (uint64_t)n;
    }
    lua_pop(L, 1);
    lua_getfield(L, idx, "select");
    if (!lua_isnil(L, -1) && lua_type(L, -1) != LUA_TSTRING)
        lcdvr_error(L, "option 'select': string expected (an array, series, dataset or "
                       "variable name), got %s", luaL_typename(L, -1));
    raw->select = lua_tostring(L, -1); /* the string stays in the options table (arg idx) */
    lua_pop(L, 1);
    static const char *const overflow[] = {"refuse", "inf", NULL};
    lua_getfield(L, idx, "f32_overflow");
    if (!lua_isnil(L, -1)) {
        const char *o = lua_type(L, -1) == LUA_TSTRING ? lua_tostring(L, -1) : NULL;
        int k = 0;
        while (o && overflow[k] && strcmp(o, overflow[k]) != 0)
            k++;
        if (!o || !overflow[k])
            lcdvr_error(L, "option 'f32_overflow': \"refuse\" or \"inf\" expected, got %s",
                        luaL_tolstring(L, -1, NULL));
        raw->f32_overflow_inf = k == 1;
    }
    lua_pop(L, 1);
}

/* Reads the raw/loader options of table idx (may be none). Returns 1 when raw dims and type
 * were given (both are then required), 0 otherwise; spacing is filled either way. */
static int raw_opts(lua_State *L, int idx, cdvr_raw_opts *raw)
{
    memset(raw, 0, sizeof *raw);
    if (lua_isnoneornil(L, idx))
        return 0;
    luaL_checktype(L, idx, LUA_TTABLE);
    spacing_field(L, idx, raw->spacing);
    limit_fields(L, idx, raw);
    int has_dims = dims_field(L, idx, raw->dims);
    lua_getfield(L, idx, "type");
    int has_type = !lua_isnil(L, -1);
    lua_pop(L, 1);
    if (!has_dims && !has_type)
        return 0;
    if (!has_dims)
        lcdvr_error(L, "option 'dims' is required for a raw file");
    raw->type = type_field(L, idx, NULL);
    raw->big_endian = check_endian(L, idx);
    raw->header_bytes = count_field(L, idx, "header", 0, 0);
    raw->timesteps = count_field(L, idx, "timesteps", 1, 1);
    return 1;
}

/* Pushes the loaded volume, or raises with the loader's message (it names the file and the
 * reason): a script never goes on with a nil volume. */
static int push_load_result(lua_State *L, cdvr_status st, cdvr_volume *vol, const cdvr_error *err)
{
    if (st != CDVR_OK)
        return lcdvr_raise(L, err);
    lcdvr_pushvolume(L, vol);
    return 1;
}

static int l_load(lua_State *L)
{
    static const char *const keys[] = {"dims", "type", "endian", "header", "timesteps", "spacing",
                                       "allow_outside", "max_bytes", "select", "f32_overflow", NULL};
    lcdvr_checkoptions(L, 2, "cdvr.load", keys);
    const char *path = luaL_checkstring(L, 1);
    cdvr_raw_opts raw;
    int has_raw = raw_opts(L, 2, &raw);
    cdvr_volume *vol = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, &raw, &vol, &err); /* dims 0: limits + spacing only */
    if (st == CDVR_OK && !has_raw)
        for (int i = 0; i < 3; i++)
            if (raw.spacing[i] > 0)
                vol->spacing[i] = raw.spacing[i];
    return push_load_result(L, st, vol, &err);
}

/* Pushes a list of file names from a pattern (cdvr_series_pattern) and opts first/count/last
 * and returns 1. Without count or last, takes files from `first` while they exist; when there is
 * none, pushes a message instead and returns 0. */
static int series_names_from_pattern(lua_State *L, const char *pattern, int opts)
{
    int has_opts = lua_istable(L, opts);
    lua_Integer first = has_opts ? lcdvr_optintegerfield(L, opts, "first", 0) : 0;
    lua_Integer count = has_opts ? lcdvr_optintegerfield(L, opts, "count", -1) : -1;
    lua_Integer last = has_opts ? lcdvr_optintegerfield(L, opts, "last", first - 1) : first - 1;
    if (count < 0 && last >= first)
        count = last - first + 1;
    if (count == 0 || count > 1000000 || (has_opts && count < 0 && last < first - 1))
        luaL_error(L, "series '%s': count must be 1..1000000 (got first=%d count=%d last=%d)", pattern,
                   (int)first, (int)count, (int)last);
    char **names = NULL;
    size_t n = 0;
    cdvr_error err;
    cdvr_status st = cdvr_series_pattern(pattern, first, count > 0 ? (size_t)count : 0, &names, &n,
                                         &err);
    if (st == CDVR_ERR_IO) { /* no first file */
        lua_pushstring(L, err.msg);
        return 0;
    }
    if (st != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_createtable(L, (int)n, 0);
    for (size_t i = 0; i < n; i++) {
        lua_pushstring(L, names[i]); /* (a memory error here leaks names: never in practice) */
        lua_seti(L, -2, (lua_Integer)i + 1);
    }
    cdvr_format_free_paths(names, n);
    return 1;
}

/* Pushes the files of a directory, a glob pattern or one name (cdvr_series_names); the options
 * first/count/last belong to printf patterns only. */
static void series_names_from_path(lua_State *L, const char *where, int opts)
{
    static const char *const pattern_keys[] = {"first", "count", "last"};
    for (int i = 0; i < 3 && lua_istable(L, opts); i++) {
        if (lua_getfield(L, opts, pattern_keys[i]) != LUA_TNIL)
            luaL_error(L, "cdvr.load_series '%s': option '%s' is for a printf pattern "
                       "(\"t%%03d.nrrd\"), not a directory, glob pattern or file", where,
                       pattern_keys[i]);
        lua_pop(L, 1);
    }
    char **names = NULL;
    size_t n = 0;
    cdvr_error err;
    if (cdvr_series_names(where, 0, 0, &names, &n, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    lua_createtable(L, (int)(n < INT32_MAX ? n : 0), 0);
    for (size_t i = 0; i < n; i++) {
        lua_pushstring(L, names[i]); /* (a memory error here leaks names: never in practice) */
        lua_seti(L, -2, (lua_Integer)i + 1);
    }
    cdvr_format_free_paths(names, n);
}

static int l_load_series(lua_State *L)
{
    static const char *const keys[] = {"dims", "type", "endian", "header", "timesteps", "spacing",
                                       "first", "count", "last", "allow_outside", "max_bytes", "select", "f32_overflow",
                                       NULL};
    lcdvr_checkoptions(L, 2, "cdvr.load_series", keys);
    cdvr_raw_opts raw;
    int has_raw = raw_opts(L, 2, &raw);
    struct stat sb;
    int pattern_opts = lua_istable(L, 2) && (lcdvr_optintegerfield(L, 2, "first", -1) != -1 ||
                                             lcdvr_optintegerfield(L, 2, "count", -1) != -1 ||
                                             lcdvr_optintegerfield(L, 2, "last", -1) != -1);
    if (lua_type(L, 1) == LUA_TSTRING && stat(lua_tostring(L, 1), &sb) != 0 &&
        (strchr(lua_tostring(L, 1), '%') || pattern_opts)) {
        if (!series_names_from_pattern(L, lua_tostring(L, 1), 2))
            return lua_error(L); /* the message names the first missing file */
    } else if (lua_type(L, 1) == LUA_TSTRING) {
        series_names_from_path(L, lua_tostring(L, 1), 2);
    } else {
        luaL_checktype(L, 1, LUA_TTABLE);
        lua_pushvalue(L, 1);
    }
    int list = lua_gettop(L);
    lua_Integer n = luaL_len(L, list);
    luaL_argcheck(L, n >= 1, 1, "empty list of files");
    const char **paths = (const char **)lua_newuserdatauv(L, (size_t)n * sizeof *paths, 0);
    for (lua_Integer i = 0; i < n; i++) {
        lua_geti(L, list, i + 1);
        if (lua_type(L, -1) != LUA_TSTRING)
            luaL_error(L, "series file %d: string expected, got %s", (int)(i + 1), luaL_typename(L, -1));
        paths[i] = lua_tostring(L, -1); /* stays alive: the list holds it */
        lua_pop(L, 1);
    }
    cdvr_series *series = NULL;
    cdvr_error err;
    if (cdvr_series_open(paths, (size_t)n, &raw, &series, &err) != CDVR_OK) /* spacing= too */
        return lcdvr_raise(L, &err);
    lazy_source *src = calloc(1, sizeof *src);
    lazy_volume *lv = calloc(1, sizeof *lv);
    if (!src || !lv) {
        free(src);
        free(lv);
        cdvr_series_close(series);
        return luaL_error(L, "cdvr.load_series: out of memory");
    }
    src->series = series;
    src->refs = 1;
    lv->src = src;
    lv->view = (cdvr_series_view){series, 0, 0, 0};
    const cdvr_series_info *in = cdvr_series_get_info(series);
    cdvr_volume *h = &lv->head;
    memcpy(h->dims, in->dims, sizeof h->dims);
    memcpy(h->spacing, in->spacing, sizeof h->spacing);
    memcpy(h->origin, in->origin, sizeof h->origin);
    memcpy(h->direction, in->direction, sizeof h->direction);
    for (int i = 0; !has_raw && i < 3; i++)
        if (raw.spacing[i] > 0)
            h->spacing[i] = raw.spacing[i];
    h->timesteps = in->timesteps;
    h->type = in->type;
    memcpy(h->source_type, in->source_type, sizeof h->source_type);
    h->window[0] = in->window[0];
    h->window[1] = in->window[1];
    memcpy(h->space, in->space, sizeof h->space);
    push_lazy(L, lv);
    return 1;
}

static int l_volume_new(lua_State *L)
{
    static const char *const keys[] = {"dims", "type", "timesteps", "spacing", NULL};
    luaL_checktype(L, 1, LUA_TTABLE);
    lcdvr_checkoptions(L, 1, "cdvr.volume", keys);
    size_t dims[3];
    if (!dims_field(L, 1, dims))
        return lcdvr_error(L, "option 'dims' is required");
    cdvr_type type = type_field(L, 1, "u8");
    size_t timesteps = count_field(L, 1, "timesteps", 1, 1);
    cdvr_volume *vol;
    cdvr_error err;
    if (cdvr_volume_create(dims, timesteps, type, &vol, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    spacing_field(L, 1, vol->spacing);
    lcdvr_pushvolume(L, vol);
    return 1;
}

static int l_generate(lua_State *L)
{
    static const char *const names[] = {"box", "sphere", "ml", "ramp", NULL};
    const char *name = names[luaL_checkoption(L, 1, NULL, names)];
    cdvr_generate_opts o;
    memset(&o, 0, sizeof o);
    static const char *const keys[] = {"dims", "timesteps", "type", "value", "radius", "fM", "alpha", NULL};
    lcdvr_checkoptions(L, 2, "cdvr.generate", keys);
    if (!lua_isnoneornil(L, 2)) {
        luaL_checktype(L, 2, LUA_TTABLE);
        dims_field(L, 2, o.dims);
        o.timesteps = count_field(L, 2, "timesteps", 1, 1);
        o.type = type_field(L, 2, "u8");
        o.value = lcdvr_optnumberfield(L, 2, "value", 0.0);
        o.radius = lcdvr_optnumberfield(L, 2, "radius", 0.0);
        o.fM = lcdvr_optnumberfield(L, 2, "fM", 0.0);
        o.alpha = lcdvr_optnumberfield(L, 2, "alpha", 0.0);
        const char *const num_keys[] = {"value", "radius", "fM", "alpha"};
        const double nums[] = {o.value, o.radius, o.fM, o.alpha};
        for (int i = 0; i < 4; i++)
            if (!isfinite(nums[i]))
                luaL_error(L, "cdvr.generate: option '%s' must be finite, got %f", num_keys[i], nums[i]);
    }
    cdvr_volume *vol;
    cdvr_error err;
    if (cdvr_volume_generate(name, &o, &vol, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lcdvr_pushvolume(L, vol);
    return 1;
}

/* cdvr.formats(): {{name=, description=, suffixes={...}, magic=, series=, described= (reads
 * only what opts describe: raw), plugin=file or nil}, ...} in registration order
 * (cdvr/format.h). */
static int l_formats(lua_State *L)
{
    size_t n = cdvr_format_count();
    lua_createtable(L, (int)n, 0);
    for (size_t i = 0; i < n; i++) {
        const cdvr_format *f = cdvr_format_at(i);
        lua_createtable(L, 0, 7);
        lua_pushstring(L, f->name);
        lua_setfield(L, -2, "name");
        lua_pushstring(L, f->description);
        lua_setfield(L, -2, "description");
        lua_newtable(L);
        for (int k = 0; f->suffixes[k]; k++) {
            lua_pushstring(L, f->suffixes[k]);
            lua_seti(L, -2, k + 1);
        }
        lua_setfield(L, -2, "suffixes");
        lua_pushboolean(L, f->magic != NULL);
        lua_setfield(L, -2, "magic");
        lua_pushboolean(L, f->expand != NULL || f->expand_opts != NULL);
        lua_setfield(L, -2, "series");
        lua_pushboolean(L, (f->flags & CDVR_FORMAT_DESCRIBED) != 0);
        lua_setfield(L, -2, "described");
        const char *file = cdvr_plugin_format_file(f);
        if (file) {
            lua_pushstring(L, file);
            lua_setfield(L, -2, "plugin");
        }
        lua_seti(L, -2, (lua_Integer)i + 1);
    }
    return 1;
}

static const luaL_Reg volume_funcs[] = {
    {"load", l_load},         {"load_series", l_load_series}, {"volume", l_volume_new},
    {"generate", l_generate}, {"formats", l_formats}, {NULL, NULL}};

static const luaL_Reg volume_methods[] = {
    {"dims", volume_dims},   {"type", volume_type}, {"timesteps", volume_timesteps},
    {"range", volume_range}, {"get", volume_get},   {"set", volume_set},
    {"spacing", volume_spacing}, {"origin", volume_origin}, {"frame", volume_frame},
    {"direction", volume_direction}, {"bounds", volume_bounds}, {"to_world", volume_to_world},
    {"window", volume_window},
    {"info", volume_info}, {"times", volume_times},
    {"bytes", volume_bytes}, {"quantize", volume_quantize}, {"save_raw", volume_save_raw},
    {"save", volume_save},
    {NULL, NULL}};

static const luaL_Reg volume_meta[] = {
    {"__gc", volume_gc}, {"__close", volume_gc}, {"__tostring", volume_tostring},
    {"__len", volume_len}, {NULL, NULL}};

int lcdvr_open_volume(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_VOLUME, volume_methods, volume_meta);
    lcdvr_setfuncs(L, volume_funcs);
    lcdvr_help_add(L, "cdvr.load(path [, opts])",
                   "load .nrrd .nhdr .nii .nii.gz (or any format of cdvr.formats(), by suffix, else by its first bytes), "
                   "or raw with opts {dims=, type=, endian=, header=, timesteps=, spacing=}; "
                   "allow_outside=true lets a NRRD header name data files outside its directory, max_bytes= caps the "
                   "voxel bytes a file may claim (default half the physical memory); select= names the object inside "
                   "the file (array, DICOM series, HDF5 dataset, NetCDF variable); f32_overflow=\"inf\" loads a value beyond "
                   "f32 (of a float64 file) as +-Inf instead of refusing it (v:info().beyond_f32 counts them); "
                   "a file that cannot be read raises an error naming it and the reason");
    lcdvr_help_add(L, "cdvr.formats()",
                   "list of file formats: {name, description, suffixes, magic, series, described, plugin}");
    lcdvr_help_add(L, "cdvr.load_series(pattern_or_list [, opts])",
                   "load files as one series: printf pattern (\"vf_t%03d.nrrd\", opts first=, count= or last=), a "
                   "directory (its files of one format in natural order: t2 before t10; or its TIFF-stack "
                   "subdirectories, one per timestep), a glob pattern (\"run/*.vti\", ?, [...]: natural order), a "
                   ".pvd collection (times kept: v:times()) or a list of names; raises naming a file that cannot be read");
    lcdvr_help_add(L, "v:info()",
                   "{type=, source_type= (the file's element type, e.g. \"float64\"), converted= (true when the "
                   "values became f32), beyond_f32= (values loaded as +-Inf, f32_overflow=\"inf\"), space= (\"RAS\", \"LAS\" or "
                   "\"LPS\" when the file names its world), lazy=, files= (a series), "
                   "times= (a .pvd series)}");
    lcdvr_help_add(L, "v:times()", "time values of a series read from .pvd collections (one per timestep), else nil");
    lcdvr_help_add(L, "cdvr.volume{dims=, type=, timesteps=}", "new zero-filled volume");
    lcdvr_help_add(L, "cdvr.generate(name [, opts])",
                   "test field \"box\", \"sphere\", \"ml\" (Marschner-Lobb) or \"ramp\"; opts dims=, timesteps=, type=, value=, radius=, fM=, alpha=");
    lcdvr_help_add(L, "v:set(x, y, z [, t], value)", "set a voxel (x, y, z from 0; t from 1)");
    lcdvr_help_add(L, "v:spacing()", "voxel spacing sx, sy, sz");
    lcdvr_help_add(L, "v:origin()", "world position of voxel (0,0,0)");
    lcdvr_help_add(L, "v:direction()",
                   "the 9 entries (row-major) of the direction matrix D: world = origin + D * (i*sx, j*sy, k*sz), "
                   "column c = world direction of index axis c (from NIfTI sform/qform, NRRD space directions)");
    lcdvr_help_add(L, "v:bounds()", "xmin, xmax, ymin, ymax, zmin, zmax of the oriented box in world coordinates");
    lcdvr_help_add(L, "v:to_world(i, j, k)", "world position of voxel (i, j, k) (from 0; fractional allowed)");
    lcdvr_help_add(L, "v:window()",
                   "value window lo, hi (data units) that TFs are classified over: u8 codes 0..255 stand for lo..hi "
                   "(quantize window, store window); other types: the range of the whole series");
    lcdvr_help_add(L, "v:frame(t [, count])", "new volume holding timesteps t .. t+count-1 (t from 1, count default 1)");
    lcdvr_help_add(L, "v:bytes()", "size of the voxel data in bytes (all timesteps)");
    lcdvr_help_add(L, "v:quantize{lo=, hi=}",
                   "u8 volume over window [lo, hi] (default: range) and report {clipped=, clipped_low=, clipped_high=, nan=, inf=}");
    lcdvr_help_add(L, "v:save(path [, {compress=}])",
                   "write .nrrd .nhdr .nii .nii.gz .vti .pvd .mha .mhd (by suffix; geometry kept, 4D; a series as .vti or "
                   ".pvd: NAME_0000.vti ... and NAME.pvd with its times); the value window of a u8 volume is kept "
                   "(NRRD old min/max, MetaImage/VTI/NIfTI a cdvr key); "
                   "compress=true: gzip/zlib; true or nil, msg");
    lcdvr_help_add(L, "v:save_raw(path [, {endian=}])", "write the voxels as raw (little endian by default); true or nil, msg");
    lcdvr_help_add(L, "#v", "number of timesteps");
    lcdvr_help_add(L, "v:dims()", "x, y, z dimensions of a volume");
    lcdvr_help_add(L, "v:type()", "voxel type: u8, u16, i16 or f32");
    lcdvr_help_add(L, "v:timesteps()", "number of timesteps");
    lcdvr_help_add(L, "v:range()", "min, max over finite values");
    lcdvr_help_add(L, "v:get(x, y, z [, t])", "voxel value (x, y, z from 0; t from 1)");
    return 0;
}
