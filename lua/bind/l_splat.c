/* lua/bind/l_splat.c - splatting in Lua: cdvr.splat_order (the cdvr.SplatOrder object: #o,
 * o[i]) and cdvr.splat_order_quality; the splat render method is core/render/cpu/splat_method.c. */
#include "cdvr/render.h"
#include "cdvr/splat.h"
#include "cdvr/timing.h"
#include "lcdvr.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LCDVR_SPLAT_ORDER "cdvr.SplatOrder"

static const char *const how_names[] = {"dda", "axis", "sort", "quicksort", NULL};

typedef struct lorder {
    cdvr_splat_order *order; /* NULL once closed */
} lorder;

static lorder *tolorder(lua_State *L, int idx)
{
    return (lorder *)luaL_checkudata(L, idx, LCDVR_SPLAT_ORDER);
}

static cdvr_splat_order *checkorder(lua_State *L, int idx)
{
    lorder *ud = tolorder(L, idx);
    if (!ud->order)
        luaL_error(L, "attempt to use a closed splat order");
    return ud->order;
}

static int order_gc(lua_State *L)
{
    lorder *ud = tolorder(L, 1);
    cdvr_splat_order_free(ud->order);
    ud->order = NULL;
    return 0;
}

static int order_tostring(lua_State *L)
{
    lorder *ud = tolorder(L, 1);
    if (!ud->order) {
        lua_pushliteral(L, "cdvr.SplatOrder (closed)");
        return 1;
    }
    const cdvr_splat_order *o = ud->order;
    lua_pushfstring(L, "cdvr.SplatOrder %I voxels of %Ix%Ix%I (%p)", (LUAI_UACINT)o->count,
                    (LUAI_UACINT)o->dims[0], (LUAI_UACINT)o->dims[1], (LUAI_UACINT)o->dims[2],
                    (void *)ud);
    return 1;
}

static int order_len(lua_State *L)
{
    lua_pushinteger(L, (lua_Integer)checkorder(L, 1)->count);
    return 1;
}

/* o[i] (i from 1): the linear voxel index drawn i-th, nil outside 1..#o; other keys are
 * methods. */
static int order_index(lua_State *L)
{
    const cdvr_splat_order *o = checkorder(L, 1);
    int isint = 0;
    lua_Integer i = lua_tointegerx(L, 2, &isint);
    if (isint && lua_type(L, 2) == LUA_TNUMBER) {
        if (i >= 1 && (lua_Unsigned)i <= (lua_Unsigned)o->count)
            lua_pushinteger(L, (lua_Integer)o->index[i - 1]);
        else
            lua_pushnil(L);
        return 1;
    }
    lua_pushvalue(L, 2);
    lua_rawget(L, lua_upvalueindex(1)); /* methods[key] */
    return 1;
}

static int order_dims(lua_State *L)
{
    const cdvr_splat_order *o = checkorder(L, 1);
    for (int a = 0; a < 3; a++)
        lua_pushinteger(L, (lua_Integer)o->dims[a]);
    return 3;
}

/* ---- arguments ------------------------------------------------------------------------- */

static void check_dims(lua_State *L, int idx, size_t dims[3])
{
    luaL_argcheck(L, lua_istable(L, idx) && luaL_len(L, idx) == 3, idx,
                  "dims must be {X, Y, Z}");
    for (int a = 0; a < 3; a++) {
        lua_geti(L, idx, a + 1);
        int isint = 0;
        lua_Integer n = lua_tointegerx(L, -1, &isint);
        luaL_argcheck(L, isint && n >= 1 && (lua_Unsigned)n <= UINT32_MAX, idx,
                      "dims must be integers >= 1");
        dims[a] = (size_t)n;
        lua_pop(L, 1);
    }
}

static void check_vec3(lua_State *L, int idx, const char *what, double out[3])
{
    int ok = lua_istable(L, idx) && luaL_len(L, idx) == 3;
    for (int a = 0; a < 3 && ok; a++) {
        lua_geti(L, idx, a + 1);
        int isnum = 0;
        out[a] = (double)lua_tonumberx(L, -1, &isnum);
        ok = isnum && isfinite(out[a]);
        lua_pop(L, 1);
    }
    if (!ok)
        lcdvr_error(L, "%s must be 3 finite numbers", what);
}

/* dir: {x, y, z} (orthographic view direction) or {eye = {x, y, z}} (perspective). */
static void check_view(lua_State *L, int idx, cdvr_splat_view *view, int allow_eye)
{
    memset(view, 0, sizeof *view);
    luaL_argcheck(L, lua_istable(L, idx), idx, "view must be a direction {x, y, z} or {eye = {x, y, z}}");
    if (lua_getfield(L, idx, "eye") != LUA_TNIL) { /* eye */
        if (!allow_eye)
            luaL_argerror(L, idx, "a direction {x, y, z} is needed here (no perspective)");
        lua_Integer extra = luaL_len(L, idx);
        luaL_argcheck(L, extra == 0, idx, "give either a direction or {eye = ...}, not both");
        check_vec3(L, lua_gettop(L), "view eye", view->eye);
        view->perspective = 1;
    } else {
        check_vec3(L, idx, "view direction", view->dir);
        luaL_argcheck(L, view->dir[0] != 0.0 || view->dir[1] != 0.0 || view->dir[2] != 0.0, idx,
                      "view direction must not be zero");
    }
    lua_pop(L, 1);
}

/* A byte per voxel, 1 where frame t of vol is above threshold, and the keep table {0, 1}. */
static uint8_t *threshold_mask(lua_State *L, const cdvr_volume *vol, size_t t, double threshold,
                               uint8_t keep[256])
{
    size_t n = cdvr_volume_voxels(vol);
    uint8_t *mask = lua_newuserdatauv(L, n ? n : 1, 0); /* freed by the collector */
    const void *frame = cdvr_volume_frame(vol, t);
    for (size_t i = 0; i < n; i++) {
        double v;
        switch (vol->type) {
        case CDVR_TYPE_U8: v = ((const uint8_t *)frame)[i]; break;
        case CDVR_TYPE_U16: v = ((const uint16_t *)frame)[i]; break;
        case CDVR_TYPE_I16: v = ((const int16_t *)frame)[i]; break;
        default: v = ((const float *)frame)[i]; break;
        }
        mask[i] = v > threshold; /* NaN: not listed */
    }
    memset(keep, 0, 256);
    keep[1] = 1;
    return mask;
}

static int l_splat_order(lua_State *L)
{
    static const char *const keys[] = {"threshold", "volume", "t", NULL};
    size_t dims[3];
    cdvr_splat_view view;
    check_dims(L, 1, dims);
    check_view(L, 2, &view, 1);
    cdvr_splat_how how = (cdvr_splat_how)luaL_checkoption(L, 3, NULL, how_names);
    lua_settop(L, 4);
    if (!lua_isnil(L, 4))
        luaL_checktype(L, 4, LUA_TTABLE);
    lcdvr_checkoptions(L, 4, "cdvr.splat_order", keys);
    cdvr_splat_filter filter = {NULL, NULL}, *use = NULL;
    uint8_t keep[256];
    if (lua_istable(L, 4)) {
        int has_thr = lua_getfield(L, 4, "threshold") != LUA_TNIL;
        int has_vol = lua_getfield(L, 4, "volume") != LUA_TNIL;
        int has_t = lua_getfield(L, 4, "t") != LUA_TNIL;
        lua_pop(L, 3);
        if (has_thr != has_vol || (has_t && !has_vol))
            return luaL_error(L, "cdvr.splat_order: options 'threshold' and 'volume' go together "
                                 "('t' picks the volume's frame)");
        if (has_vol) {
            double threshold = lcdvr_optnumberfield(L, 4, "threshold", 0.0);
            if (isnan(threshold))
                return luaL_error(L, "cdvr.splat_order: threshold is NaN");
            lua_getfield(L, 4, "volume");
            lcdvr_checkoption(L, -1, "cdvr.splat_order", "volume", LCDVR_VOLUME);
            const cdvr_volume *vol = lcdvr_checkvolume(L, -1);
            lua_pop(L, 1); /* the options table keeps the volume alive */
            for (int a = 0; a < 3; a++)
                if (vol->dims[a] != dims[a])
                    return luaL_error(L, "cdvr.splat_order: volume is %dx%dx%d, dims are %dx%dx%d",
                                      (int)vol->dims[0], (int)vol->dims[1], (int)vol->dims[2],
                                      (int)dims[0], (int)dims[1], (int)dims[2]);
            lua_Integer t = lcdvr_optintegerfield(L, 4, "t", 1);
            if (t < 1 || (size_t)t > vol->timesteps)
                return luaL_error(L, "cdvr.splat_order: t = %I outside 1..%I", (LUAI_UACINT)t,
                                  (LUAI_UACINT)vol->timesteps);
            filter.voxels = threshold_mask(L, vol, (size_t)t - 1, threshold, keep); /* mask */
            filter.keep = keep;
            use = &filter;
        }
    }
    lorder *ud = (lorder *)lua_newuserdatauv(L, sizeof *ud, 0); /* [mask,] order */
    ud->order = NULL;
    luaL_setmetatable(L, LCDVR_SPLAT_ORDER);
    cdvr_error err;
    if (cdvr_splat_order_build(dims, &view, how, use, &ud->order, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    return 1;
}

static int l_splat_order_quality(lua_State *L)
{
    static const char *const keys[] = {"radius", "budget", NULL};
    size_t dims[3];
    cdvr_splat_view view;
    check_dims(L, 1, dims);
    check_view(L, 2, &view, 0);
    lua_settop(L, 4);
    if (!lua_isnil(L, 4))
        luaL_checktype(L, 4, LUA_TTABLE);
    lcdvr_checkoptions(L, 4, "cdvr.splat_order_quality", keys);
    double radius = lua_istable(L, 4) ? lcdvr_optnumberfield(L, 4, "radius", CDVR_SPLAT_DEFAULT_RADIUS)
                                      : CDVR_SPLAT_DEFAULT_RADIUS;
    lua_Integer budget = lua_istable(L, 4) ? lcdvr_optintegerfield(L, 4, "budget", 0) : 0;
    if (budget < 0)
        return luaL_error(L, "cdvr.splat_order_quality: budget must be >= 0 (0 = default)");
    cdvr_splat_order *order = NULL;
    cdvr_error err;
    if (lua_type(L, 3) == LUA_TUSERDATA) {
        order = checkorder(L, 3);
        if (memcmp(order->dims, dims, sizeof dims) != 0)
            return luaL_error(L, "cdvr.splat_order_quality: the order is for %dx%dx%d, dims are %dx%dx%d",
                              (int)order->dims[0], (int)order->dims[1], (int)order->dims[2],
                              (int)dims[0], (int)dims[1], (int)dims[2]);
    } else {
        cdvr_splat_how how = (cdvr_splat_how)luaL_checkoption(L, 3, NULL, how_names);
        lorder *ud = (lorder *)lua_newuserdatauv(L, sizeof *ud, 0); /* owns the order */
        ud->order = NULL;
        luaL_setmetatable(L, LCDVR_SPLAT_ORDER);
        if (cdvr_splat_order_build(dims, &view, how, NULL, &ud->order, &err) != CDVR_OK)
            return lcdvr_raise(L, &err);
        order = ud->order;
    }
    cdvr_splat_quality q;
    if (cdvr_splat_order_quality(order, view.dir, radius, (uint64_t)budget, &q, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_pushnumber(L, q.fraction);
    lua_createtable(L, 0, 5);
    lua_pushinteger(L, (lua_Integer)q.pairs);
    lua_setfield(L, -2, "pairs");
    lua_pushinteger(L, (lua_Integer)q.wrong);
    lua_setfield(L, -2, "wrong");
    lua_pushinteger(L, (lua_Integer)q.offsets);
    lua_setfield(L, -2, "offsets");
    lua_pushboolean(L, q.sampled);
    lua_setfield(L, -2, "sampled");
    lua_pushnumber(L, q.max_inversion);
    lua_setfield(L, -2, "max_inversion");
    return 2;
}

/* ---- cdvr.render{method = "splat"} ------------------------------------------------------ */

static const luaL_Reg order_methods[] = {{"dims", order_dims}, {NULL, NULL}};

static const luaL_Reg order_meta[] = {{"__gc", order_gc},
                                      {"__close", order_gc},
                                      {"__tostring", order_tostring},
                                      {"__len", order_len},
                                      {NULL, NULL}};

static const luaL_Reg splat_funcs[] = {{"splat_order", l_splat_order},
                                       {"splat_order_quality", l_splat_order_quality},
                                       {NULL, NULL}};

int lcdvr_open_splat(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_SPLAT_ORDER, order_methods, order_meta);
    luaL_getmetatable(L, LCDVR_SPLAT_ORDER); /* mt */
    lua_getfield(L, -1, "__index");          /* mt, methods */
    lua_pushcclosure(L, order_index, 1);     /* mt, index */
    lua_setfield(L, -2, "__index");
    lua_pop(L, 1);
    lcdvr_setfuncs(L, splat_funcs);
    lcdvr_help_add(L, "cdvr.splat_order(dims, dir | {eye=}, how [, {threshold=, volume=, t=}])",
                   "voxel order for splatting, back to front: how = \"dda\" (the seed's extended "
                   "DDA), \"axis\", \"sort\" (radix) or \"quicksort\"; #o voxels, o[i] = linear "
                   "index x + X*(y + Y*z) drawn i-th; with threshold and volume only voxels above "
                   "the threshold");
    lcdvr_help_add(L, "cdvr.splat_order_quality(dims, dir, how | order [, {radius=, budget=}])",
                   "fraction of screen-overlapping voxel pairs drawn in the wrong depth order, "
                   "and {pairs=, wrong=, offsets=, sampled=, max_inversion=}");
    lcdvr_help_add(L, "cdvr.render(volume, {method=\"splat\", order=, threshold=, radius=, sigma=, tf=, camera=, ...})",
                   "Gaussian splats composited back to front (order \"dda\" default, \"axis\", "
                   "\"sort\", \"quicksort\"); radius 2.0 and sigma 0.6 voxel spacings; stats "
                   "{ms=, order_ms=, splats=, fragments=}");
    return 0;
}
