/* lua/bind/l_gl.c - the level-of-detail plan cdvr.lod_plan{...} of 2D-texture slicing
 * (cdvr/gl.h, seed 002) and cdvr.have_gl. Slicing itself is the "slice" render method
 * (core/render/gl/slice_method.c), drawn through the state's render context (l_method.c). */
#include <math.h>
#include <string.h>

#include "cdvr/gl.h"
#include "cdvr/timing.h"
#include "lcdvr.h"

static void setnumber(lua_State *L, const char *key, double v)
{
    lua_pushnumber(L, v);
    lua_setfield(L, -2, key);
}

static void setinteger(lua_State *L, const char *key, lua_Integer v)
{
    lua_pushinteger(L, v);
    lua_setfield(L, -2, key);
}

/* Option lod of the table at idx: true or "seed" (default), "screen", false. */
static int lod_mode(lua_State *L, int idx, const char *what)
{
    int type = lua_getfield(L, idx, "lod");
    int mode = CDVR_LOD_SEED;
    if (type == LUA_TBOOLEAN) {
        mode = lua_toboolean(L, -1) ? CDVR_LOD_SEED : CDVR_LOD_OFF;
    } else if (type == LUA_TSTRING && strcmp(lua_tostring(L, -1), "seed") == 0) {
        mode = CDVR_LOD_SEED;
    } else if (type == LUA_TSTRING && strcmp(lua_tostring(L, -1), "screen") == 0) {
        mode = CDVR_LOD_SCREEN;
    } else if (type != LUA_TNIL) {
        luaL_error(L, "%s: option 'lod': boolean, \"seed\" or \"screen\" expected, got %s", what,
                   type == LUA_TSTRING ? lua_tostring(L, -1) : luaL_typename(L, -1));
    }
    lua_pop(L, 1);
    return mode;
}

/* ---- cdvr.lod_plan ----------------------------------------------------------------------- */

/* box={lo, hi} (a cube) or box={{x0, y0, z0}, {x1, y1, z1}}. */
static void read_box(lua_State *L, int idx, double lo[3], double hi[3])
{
    if (lua_getfield(L, idx, "box") != LUA_TTABLE || luaL_len(L, -1) != 2)
        luaL_error(L, "cdvr.lod_plan: box={lo, hi} or {{x0, y0, z0}, {x1, y1, z1}} expected");
    for (int i = 0; i < 2; i++) {
        double *out = i == 0 ? lo : hi;
        int type = lua_geti(L, -1, i + 1);        /* box, corner */
        if (type == LUA_TNUMBER) {
            out[0] = out[1] = out[2] = lua_tonumber(L, -1);
        } else if (type == LUA_TTABLE && luaL_len(L, -1) == 3) {
            for (int a = 0; a < 3; a++) {
                lua_geti(L, -1, a + 1);
                if (!lua_isnumber(L, -1))
                    luaL_error(L, "cdvr.lod_plan: box corners must be numbers");
                out[a] = lua_tonumber(L, -1);
                lua_pop(L, 1);
            }
        } else {
            luaL_error(L, "cdvr.lod_plan: box={lo, hi} or {{x0, y0, z0}, {x1, y1, z1}} expected");
        }
        lua_pop(L, 1);
    }
    lua_pop(L, 1);
}

/* Geometry from volume= or from dims= and box= (box spans the voxel centres). */
static void read_grid(lua_State *L, cdvr_grid *g)
{
    if (lua_getfield(L, 1, "volume") != LUA_TNIL) {
        lcdvr_checkoption(L, -1, "cdvr.lod_plan", "volume", LCDVR_VOLUME);
        cdvr_grid_of_volume(lcdvr_checkvolume(L, -1), g);
        lua_pop(L, 1);
        return;
    }
    lua_pop(L, 1);
    double dims[3], lo[3], hi[3];
    if (!lcdvr_numberarrayfield(L, 1, "dims", dims, 3))
        luaL_error(L, "cdvr.lod_plan: dims={x, y, z} or volume= expected");
    read_box(L, 1, lo, hi);
    memset(g, 0, sizeof *g);
    for (int a = 0; a < 3; a++) {
        if (!(dims[a] >= 2 && dims[a] <= 1e9) || dims[a] != floor(dims[a]) || !(hi[a] > lo[a]))
            luaL_error(L, "cdvr.lod_plan: dims must be integers >= 2 and box hi > lo (axis %d)", a + 1);
        g->dims[a] = (size_t)dims[a];
        g->origin[a] = lo[a];
        g->spacing[a] = (hi[a] - lo[a]) / (dims[a] - 1.0);
        g->direction[4 * a] = 1.0;
    }
}

/* The seed's eye: centred over the slices, at distance D before the first slice of axis. */
static void axis_eye(const cdvr_grid *g, int axis, double distance, double eye[3])
{
    for (int a = 0; a < 3; a++)
        eye[a] = g->origin[a] + 0.5 * (double)(g->dims[a] - 1) * g->spacing[a];
    eye[axis] = g->origin[axis] - distance;
}

static int l_lod_plan(lua_State *L)
{
    static const char *const keys[] = {"dims", "box", "volume", "bytes_per_voxel", "distance",
                                       "axis", "camera", "lod", NULL};
    luaL_checktype(L, 1, LUA_TTABLE);
    lcdvr_checkoptions(L, 1, "cdvr.lod_plan", keys);
    cdvr_grid g;
    read_grid(L, &g);
    lua_Integer bpv = lcdvr_optintegerfield(L, 1, "bytes_per_voxel", 1);
    if (bpv < 1 || bpv > 64)
        luaL_error(L, "cdvr.lod_plan: option 'bytes_per_voxel' must be 1..64, got %I", (LUAI_UACINT)bpv);
    int lod = lod_mode(L, 1, "cdvr.lod_plan");
    double eye[3], min_nearest = 0.0;
    int axis;
    if (lua_getfield(L, 1, "camera") != LUA_TNIL) {
        lcdvr_checkoption(L, -1, "cdvr.lod_plan", "camera", LCDVR_CAMERA);
        const cdvr_camera *cam = lcdvr_checkcamera(L, -1);
        axis = cdvr_slice_axis(&g, cam);
        memcpy(eye, cam->eye, sizeof eye);
        if (lod == CDVR_LOD_SCREEN)
            min_nearest = cdvr_lod_pixel_distance(&g, axis, cam);
        if (cam->orthographic)
            lod = CDVR_LOD_OFF;
    } else {
        if (lod == CDVR_LOD_SCREEN)
            luaL_error(L, "cdvr.lod_plan: lod=\"screen\" needs camera=");
        lua_Integer a = lcdvr_optintegerfield(L, 1, "axis", 3);
        luaL_argcheck(L, a >= 1 && a <= 3, 1, "axis must be 1, 2 or 3");
        axis = (int)a - 1;
        double distance = lcdvr_optnumberfield(L, 1, "distance", NAN);
        if (!(distance > 0.0) || !isfinite(distance))
            return luaL_error(L, "cdvr.lod_plan: distance= (positive) or camera= expected");
        axis_eye(&g, axis, distance, eye);
    }
    lua_pop(L, 1);
    cdvr_lod_plan plan;
    cdvr_error err;
    if (cdvr_lod_plan_compute(&g, axis, eye, (size_t)bpv, lod, min_nearest, &plan, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_createtable(L, 0, 6);
    lua_createtable(L, (int)plan.nslices, 0);
    for (size_t k = 0; k < plan.nslices; k++) {
        lua_pushinteger(L, plan.levels[k]);
        lua_rawseti(L, -2, (lua_Integer)k + 1);
    }
    lua_setfield(L, -2, "levels");
    setinteger(L, "axis", axis + 1);
    setnumber(L, "nearest", plan.nearest);
    setinteger(L, "total_bytes", (lua_Integer)plan.total_bytes);
    setinteger(L, "full_bytes", (lua_Integer)plan.full_bytes);
    cdvr_lod_plan_free(&plan);
    return 1;
}

static const luaL_Reg gl_funcs[] = {{"lod_plan", l_lod_plan}, {NULL, NULL}};

int lcdvr_open_gl(lua_State *L)
{
    lcdvr_setfuncs(L, gl_funcs);
    lua_pushboolean(L, CDVR_HAVE_GL);
    lua_setfield(L, -2, "have_gl");
    lcdvr_help_add(L, "cdvr.lod_plan{dims=, box=, bytes_per_voxel=, distance= | volume=, camera=, lod=}",
                   "per-slice level of detail of seed 002 without rendering: {levels=, total_bytes=, "
                   "full_bytes=, axis=, nearest=}; the eye on the stack's axis at distance before "
                   "its first slice, or camera=");
    lcdvr_help_add(L, "cdvr.have_gl", "true when this cdvr has the EGL slicer and the window");
    return 0;
}
