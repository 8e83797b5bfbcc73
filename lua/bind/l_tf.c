/* lua/bind/l_tf.c - cdvr.TF: transfer functions in Lua (cdvr.tf, presets in share/tf, save/load as
 * plain Lua files). */
#include "lcdvr.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct ltf {
    cdvr_tf tf;
} ltf;

cdvr_tf *lcdvr_checktf(lua_State *L, int idx)
{
    return &((ltf *)luaL_checkudata(L, idx, LCDVR_TF))->tf;
}

cdvr_tf *lcdvr_pushtf(lua_State *L, const cdvr_tf *tf)
{
    ltf *ud = (ltf *)lua_newuserdatauv(L, sizeof *ud, 0);
    ud->tf = *tf;
    luaL_setmetatable(L, LCDVR_TF);
    return &ud->tf;
}

/* Reads element i of the points table at idx as {value, r, g, b, a}. */
static void read_point(lua_State *L, int idx, lua_Integer i, cdvr_tf_point *p)
{
    if (lua_geti(L, idx, i) != LUA_TTABLE)
        luaL_error(L, "cdvr.tf: point %d: table {value, r, g, b, a} expected, got %s", (int)i,
                   luaL_typename(L, -1));
    double v[5];
    if (luaL_len(L, -1) != 5)
        luaL_error(L, "cdvr.tf: point %d: 5 numbers {value, r, g, b, a} expected, got %d",
                   (int)i, (int)luaL_len(L, -1));
    for (int k = 0; k < 5; k++) {
        lua_geti(L, -1, k + 1);
        if (!lua_isnumber(L, -1))
            luaL_error(L, "cdvr.tf: point %d, entry %d: number expected, got %s", (int)i, k + 1,
                       luaL_typename(L, -1));
        v[k] = lua_tonumber(L, -1);
        lua_pop(L, 1);
    }
    lua_pop(L, 1);
    p->value = v[0], p->r = v[1], p->g = v[2], p->b = v[3], p->a = v[4];
}

/* Builds a TF from the points table at idx ({value, r, g, b, a}, ..., unit=, normalized=)
 * and pushes it. */
static int push_tf_from_table(lua_State *L, int idx)
{
    static const char *const keys[] = {"unit", "normalized", NULL};
    idx = lua_absindex(L, idx);
    lcdvr_checkoptions_array(L, idx, "cdvr.tf", keys);
    lua_Integer n = luaL_len(L, idx);
    if (n < 1 || n > CDVR_TF_MAX_POINTS)
        return luaL_error(L, "cdvr.tf: 1 to %d control points expected, got %d",
                          CDVR_TF_MAX_POINTS, (int)n);
    cdvr_tf_point *pts = lua_newuserdatauv(L, sizeof *pts * (size_t)n, 0);
    for (lua_Integer i = 1; i <= n; i++)
        read_point(L, idx, i, &pts[i - 1]);
    double unit = lcdvr_optnumberfield(L, idx, "unit", 0.0);
    int normalized = lcdvr_optbooleanfield(L, idx, "normalized", 0);
    cdvr_tf tf;
    cdvr_error err;
    cdvr_status st = normalized ? cdvr_tf_init_normalized(&tf, pts, (size_t)n, unit, &err)
                                : cdvr_tf_init(&tf, pts, (size_t)n, unit, &err);
    if (st != CDVR_OK)
        return lcdvr_raise(L, &err);
    lcdvr_pushtf(L, &tf);
    return 1;
}

/* Applies cdvr.tf's options table at opts (may be none) to the TF on top of the stack:
 * range={lo, hi} pins a normalised TF to data values, unit= sets the opacity unit. */
static void apply_tf_options(lua_State *L, int opts)
{
    static const char *const keys[] = {"range", "unit", NULL};
    if (lua_isnoneornil(L, opts))
        return;
    luaL_checktype(L, opts, LUA_TTABLE);
    lcdvr_checkoptions(L, opts, "cdvr.tf", keys);
    cdvr_tf *tf = lcdvr_checktf(L, -1);
    double range[2];
    cdvr_error err;
    if (lcdvr_numberarrayfield(L, opts, "range", range, 2) &&
        cdvr_tf_rescale(tf, range[0], range[1], &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    double unit = lcdvr_optnumberfield(L, opts, "unit", tf->unit);
    if (!(unit >= 0.0) || !isfinite(unit))
        luaL_error(L, "cdvr.tf: option 'unit' must be >= 0 (0 = one voxel), got %f", unit);
    tf->unit = unit;
}

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcmp(s + n - m, suffix) == 0;
}

static int valid_preset_name(const char *name)
{
    if (!*name)
        return 0;
    for (const char *c = name; *c; c++)
        if (!((*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
              *c == '_' || *c == '-'))
            return 0;
    return 1;
}

/* Loads a data file that returns a points table (lcdvr_load_data: empty environment, no
 * calls, budgeted) and builds the TF from it; an unreadable or malformed file raises (its
 * message names the file and the reason), as loaders do. */
static int load_tf_file(lua_State *L, const char *path)
{
    if (lcdvr_load_data(L, path) != LUA_OK)
        return luaL_error(L, "cdvr.tf: %s", lua_tostring(L, -1));
    if (!lua_istable(L, -1))
        return luaL_error(L, "%s: transfer function file must return a table, got %s", path,
                          luaL_typename(L, -1));
    return push_tf_from_table(L, -1);
}

static int load_preset(lua_State *L, const char *name)
{
    if (!valid_preset_name(name))
        return luaL_error(L, "cdvr.tf: bad preset name '%s' (letters, digits, _ and -)", name);
    lua_getfield(L, lua_upvalueindex(1), "share_dir");
    const char *share = lua_tostring(L, -1);
    const char *path = lua_pushfstring(L, "%s/tf/%s.lua", share ? share : "share", name);
    if (access(path, R_OK) != 0)
        return luaL_error(L, "cdvr.tf: unknown preset '%s' (no %s)", name, path);
    return load_tf_file(L, path);
}

static int l_tf(lua_State *L)
{
    lua_settop(L, 2); /* source, options */
    if (lua_type(L, 1) == LUA_TSTRING) {
        const char *s = lua_tostring(L, 1);
        if (ends_with(s, ".lua"))
            load_tf_file(L, s);
        else
            load_preset(L, s);
    } else {
        luaL_checktype(L, 1, LUA_TTABLE);
        push_tf_from_table(L, 1);
    }
    apply_tf_options(L, 2);
    return 1;
}

static void push_points(lua_State *L, const cdvr_tf *tf)
{
    lua_createtable(L, (int)tf->npoints, 1);
    for (size_t i = 0; i < tf->npoints; i++) {
        const cdvr_tf_point *p = &tf->points[i];
        const double v[5] = {p->value, p->r, p->g, p->b, p->a};
        lua_createtable(L, 5, 0);
        for (int k = 0; k < 5; k++) {
            lua_pushnumber(L, v[k]);
            lua_rawseti(L, -2, k + 1);
        }
        lua_rawseti(L, -2, (lua_Integer)i + 1);
    }
    lua_pushnumber(L, tf->unit);
    lua_setfield(L, -2, "unit");
    if (tf->normalized) {
        lua_pushboolean(L, 1);
        lua_setfield(L, -2, "normalized");
    }
}

static int tf_points(lua_State *L)
{
    push_points(L, lcdvr_checktf(L, 1));
    return 1;
}

static int tf_lookup(lua_State *L)
{
    const cdvr_tf *tf = lcdvr_checktf(L, 1);
    float out[4];
    cdvr_tf_eval(tf, luaL_checknumber(L, 2), out);
    for (int c = 0; c < 4; c++)
        lua_pushnumber(L, out[c]);
    return 4;
}

static int tf_unit(lua_State *L)
{
    lua_pushnumber(L, lcdvr_checktf(L, 1)->unit);
    return 1;
}

static int tf_normalized(lua_State *L)
{
    lua_pushboolean(L, lcdvr_checktf(L, 1)->normalized);
    return 1;
}

/* Values of the lowest and highest control points (fractions of the window when normalised). */
static int tf_range(lua_State *L)
{
    const cdvr_tf *tf = lcdvr_checktf(L, 1);
    lua_pushnumber(L, tf->points[0].value);
    lua_pushnumber(L, tf->points[tf->npoints - 1].value);
    return 2;
}

/* Writes the TF as a Lua file returning its points table; returns 0 or -1 (errno set). */
static int write_tf(FILE *f, const void *obj)
{
    const cdvr_tf *tf = obj;
    fprintf(f, "-- cdvr transfer function: {%s, r, g, b, alpha per unit}\nreturn {\n",
            tf->normalized ? "fraction of the data's value window" : "data value");
    fprintf(f, "  unit = %.17g,\n", tf->unit);
    if (tf->normalized)
        fprintf(f, "  normalized = true,\n");
    for (size_t i = 0; i < tf->npoints; i++) {
        const cdvr_tf_point *p = &tf->points[i];
        fprintf(f, "  {%.17g, %.17g, %.17g, %.17g, %.17g},\n", p->value, p->r, p->g, p->b, p->a);
    }
    fprintf(f, "}\n");
    return ferror(f) ? -1 : 0;
}

static int tf_save(lua_State *L)
{
    const cdvr_tf *tf = lcdvr_checktf(L, 1);
    return lcdvr_save_file(L, luaL_checkstring(L, 2), write_tf, tf);
}

static int tf_tostring(lua_State *L)
{
    const cdvr_tf *tf = lcdvr_checktf(L, 1);
    lua_pushfstring(L, "cdvr.TF %d points, %s, unit %f (%p)", (int)tf->npoints,
                    tf->normalized ? "normalised" : "data units", tf->unit, lua_topointer(L, 1));
    return 1;
}

static int tf_gc(lua_State *L)
{
    (void)lcdvr_checktf(L, 1); /* the TF lives inside the userdata: nothing to free */
    return 0;
}

static const luaL_Reg tf_methods[] = {{"points", tf_points}, {"lookup", tf_lookup},
                                      {"save", tf_save},     {"unit", tf_unit},
                                      {"normalized", tf_normalized}, {"range", tf_range},
                                      {NULL, NULL}};

static const luaL_Reg tf_meta[] = {
    {"__gc", tf_gc}, {"__close", tf_gc}, {"__tostring", tf_tostring}, {NULL, NULL}};

int lcdvr_open_tf(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_TF, tf_methods, tf_meta);
    lua_pushvalue(L, -1); /* the cdvr table, for cdvr.share_dir at call time */
    lua_pushcclosure(L, l_tf, 1);
    lua_setfield(L, -2, "tf");
    lcdvr_help_add(L, "cdvr.tf(points | preset | path.lua [, {range=, unit=}])",
                   "transfer function from {{value, r,g,b, a}, ... [, unit=, normalized=]} with values in "
                   "data units (or fractions of the data's window with normalized=true), a preset of "
                   "share/tf (grayscale, ct_bone, ct_soft, hot, mri: normalised, they follow the data's "
                   "window; range={lo, hi} pins them to data values) or a saved .lua file");
    lcdvr_help_add(L, "tf:points()", "the control points {{value, r,g,b, a}, ..., unit=, normalized=}");
    lcdvr_help_add(L, "tf:lookup(v)", "r, g, b, a at value v (data units; a fraction 0..1 if normalised)");
    lcdvr_help_add(L, "tf:normalized()", "true for a TF whose values are fractions of the data's window (presets)");
    lcdvr_help_add(L, "tf:range()", "values of the first and last control points");
    lcdvr_help_add(L, "tf:unit()", "opacity unit length (0 = one voxel spacing)");
    lcdvr_help_add(L, "tf:save(path)", "write a Lua file cdvr.tf(path) reads back; true or nil, msg");
    return 0;
}
