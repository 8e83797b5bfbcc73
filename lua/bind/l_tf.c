/* lua/bind/l_tf.c - cdvr.TF: transfer functions in Lua (cdvr.tf, presets in share/tf, save/load as
 * plain Lua files). */
#include "lcdvr.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
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

/* ---- presets and colour maps (share/tf, share/colormaps) ------------------------------------ */

/* The directories a name is looked up in, in order: presets (TFs), then colour maps. */
static const char *const preset_dirs[] = {"tf", "colormaps", NULL};

/* Pushes "a, b, c" : the names (without .lua) of the files in share/<dir> for every dir. */
static void push_preset_names(lua_State *L, const char *share)
{
    luaL_Buffer b;
    luaL_buffinit(L, &b);
    for (int d = 0; preset_dirs[d]; d++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", share, preset_dirs[d]);
        DIR *dir = opendir(path);
        if (!dir)
            continue;
        char names[128][64];
        int n = 0;
        for (struct dirent *e; (e = readdir(dir)) != NULL && n < 128;) {
            size_t len = strlen(e->d_name);
            if (len > 4 && len - 4 < sizeof names[0] && ends_with(e->d_name, ".lua"))
                snprintf(names[n++], sizeof names[0], "%.*s", (int)(len - 4), e->d_name);
        }
        closedir(dir);
        qsort(names, (size_t)n, sizeof names[0], (int (*)(const void *, const void *))strcmp);
        luaL_addstring(&b, d == 0 ? "presets: " : "; colour maps: ");
        for (int i = 0; i < n; i++) {
            if (i)
                luaL_addstring(&b, ", ");
            luaL_addstring(&b, names[i]);
        }
    }
    luaL_pushresult(&b);
}

/* Runs a preset file as data (an empty environment: a table constructor, numbers and
 * arithmetic only) and leaves its table on the stack. */
static void load_preset_data(lua_State *L, const char *path)
{
    if (luaL_loadfilex(L, path, "t") != LUA_OK)
        luaL_error(L, "cdvr.tf: %s", lua_tostring(L, -1));
    lua_newtable(L);
    lua_setupvalue(L, -2, 1); /* _ENV */
    lua_call(L, 0, 1);
    if (!lua_istable(L, -1))
        luaL_error(L, "%s: a preset file must return a table, got %s", path,
                   luaL_typename(L, -1));
}

static double opt_field(lua_State *L, int idx, const char *key, double def, const char *path)
{
    int type = lua_getfield(L, idx, key);
    double v = def;
    if (type != LUA_TNIL) {
        if (type != LUA_TNUMBER)
            luaL_error(L, "%s: '%s' must be a number", path, key);
        v = lua_tonumber(L, -1);
    }
    lua_pop(L, 1);
    return v;
}

/* shade = {shade=, ambient=, diffuse=, specular=, specular_power=, gradient_opacity=} of the
 * preset table at idx into tf->shade. */
static void read_shade(lua_State *L, int idx, cdvr_tf *tf, const char *path)
{
    if (lua_getfield(L, idx, "shade") == LUA_TTABLE) {
        int s = lua_gettop(L);
        lua_getfield(L, s, "shade");
        tf->shade.on = lua_toboolean(L, -1);
        lua_pop(L, 1);
        tf->shade.ambient = opt_field(L, s, "ambient", 0.1, path);
        tf->shade.diffuse = opt_field(L, s, "diffuse", 0.7, path);
        tf->shade.specular = opt_field(L, s, "specular", 0.2, path);
        tf->shade.specular_power = opt_field(L, s, "specular_power", 10.0, path);
        tf->shade.present = 1;
    }
    lua_pop(L, 1);
}

/* Reads the numbers of entry i (a table of n numbers) of the table at idx into out. */
static void read_numbers(lua_State *L, int idx, lua_Integer i, double *out, int n,
                         const char *what)
{
    if (lua_geti(L, idx, i) != LUA_TTABLE || luaL_len(L, -1) != n)
        luaL_error(L, "%s: entry %d: a table of %d numbers expected", what, (int)i, n);
    for (int k = 0; k < n; k++) {
        lua_geti(L, -1, k + 1);
        int ok;
        out[k] = lua_tonumberx(L, -1, &ok);
        if (!ok)
            luaL_error(L, "%s: entry %d, item %d: number expected", what, (int)i, k + 1);
        lua_pop(L, 1);
    }
    lua_pop(L, 1);
}

/* The opacity of cdvr.tf(colour map, {opacity=}): "ramp" (a = x) or {{x, a}, ...} (x a
 * fraction of the window); returns the number of points written to a (0 = ramp). */
static size_t read_opacity(lua_State *L, int opts, double (*a)[2])
{
    if (lua_isnoneornil(L, opts))
        return 0;
    int type = lua_getfield(L, opts, "opacity");
    if (type == LUA_TNIL || (type == LUA_TSTRING && strcmp(lua_tostring(L, -1), "ramp") == 0)) {
        lua_pop(L, 1);
        return 0;
    }
    if (type != LUA_TTABLE)
        luaL_error(L, "cdvr.tf: option 'opacity': \"ramp\" or {{x, a}, ...} expected, got %s%s%s",
                   luaL_typename(L, -1), type == LUA_TSTRING ? " " : "",
                   type == LUA_TSTRING ? lua_tostring(L, -1) : "");
    lua_Integer n = luaL_len(L, -1);
    if (n < 1 || n > CDVR_TF_MAX_POINTS)
        luaL_error(L, "cdvr.tf: option 'opacity': 1 to %d points {x, a} expected",
                   CDVR_TF_MAX_POINTS);
    for (lua_Integer i = 1; i <= n; i++)
        read_numbers(L, lua_gettop(L), i, a[i - 1], 2, "cdvr.tf: option 'opacity'");
    lua_pop(L, 1);
    return (size_t)n;
}

/* Builds the TF of a colour-map file (table at idx: {x, r, g, b} entries) with the opacity of
 * the options at opts, and pushes it. */
static void push_colormap(lua_State *L, int idx, int opts, const char *path)
{
    lua_Integer n = luaL_len(L, idx);
    if (n < 1 || n > CDVR_TF_MAX_POINTS)
        luaL_error(L, "%s: 1 to %d colour-map entries expected", path, CDVR_TF_MAX_POINTS);
    double(*cmap)[4] = lua_newuserdatauv(L, sizeof *cmap * (size_t)n, 0);
    double(*alpha)[2] = lua_newuserdatauv(L, sizeof *alpha * CDVR_TF_MAX_POINTS, 0);
    for (lua_Integer i = 1; i <= n; i++)
        read_numbers(L, idx, i, cmap[i - 1], 4, path);
    size_t na = read_opacity(L, opts, alpha);
    double unit = opt_field(L, idx, "unit", 0.0, path);
    cdvr_tf tf;
    cdvr_error err;
    if (cdvr_tf_init_colormap(&tf, (const double(*)[4])cmap, (size_t)n,
                              (const double(*)[2])alpha, na, unit, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    lua_pop(L, 2);
    lcdvr_pushtf(L, &tf);
}

/* Builds the TF of a preset file (table at idx: {value, r, g, b, a} points, unit=,
 * normalized=, shade=) and pushes it. */
static void push_preset(lua_State *L, int idx, const char *path)
{
    lua_Integer n = luaL_len(L, idx);
    if (n < 1 || n > CDVR_TF_MAX_POINTS)
        luaL_error(L, "%s: 1 to %d control points expected", path, CDVR_TF_MAX_POINTS);
    cdvr_tf_point *pts = lua_newuserdatauv(L, sizeof *pts * (size_t)n, 0);
    for (lua_Integer i = 1; i <= n; i++) {
        double v[5];
        read_numbers(L, idx, i, v, 5, path);
        pts[i - 1] = (cdvr_tf_point){v[0], v[1], v[2], v[3], v[4]};
    }
    lua_getfield(L, idx, "normalized");
    int normalized = lua_toboolean(L, -1);
    lua_pop(L, 1);
    double unit = opt_field(L, idx, "unit", 0.0, path);
    cdvr_tf tf;
    cdvr_error err;
    cdvr_status st = normalized ? cdvr_tf_init_normalized(&tf, pts, (size_t)n, unit, &err)
                                : cdvr_tf_init(&tf, pts, (size_t)n, unit, &err);
    if (st != CDVR_OK)
        lcdvr_raise(L, &err);
    lua_pop(L, 1);
    read_shade(L, idx, &tf, path);
    lcdvr_pushtf(L, &tf);
}

/* cdvr.tf(name [, opts]): the preset share/tf/name.lua or the colour map
 * share/colormaps/name.lua (*is_map set to 1); an unknown name lists those that exist. */
static int load_preset(lua_State *L, const char *name, int opts, int *is_map_out)
{
    if (!valid_preset_name(name))
        return luaL_error(L, "cdvr.tf: bad preset name '%s' (letters, digits, _ and -)", name);
    lua_getfield(L, lua_upvalueindex(1), "share_dir");
    const char *share = lua_tostring(L, -1);
    share = share ? share : "share";
    for (int d = 0; preset_dirs[d]; d++) {
        const char *path = lua_pushfstring(L, "%s/%s/%s.lua", share, preset_dirs[d], name);
        if (access(path, R_OK) != 0) {
            lua_pop(L, 1);
            continue;
        }
        load_preset_data(L, path);
        int idx = lua_gettop(L);
        int is_map = lua_getfield(L, idx, "colormap") != LUA_TNIL;
        lua_pop(L, 1);
        *is_map_out = is_map;
        if (is_map)
            push_colormap(L, idx, opts, path);
        else
            push_preset(L, idx, path);
        cdvr_tf *tf = lcdvr_checktf(L, -1);
        snprintf(tf->name, sizeof tf->name, "%s", name);
        return 1;
    }
    push_preset_names(L, share);
    return luaL_error(L, "cdvr.tf: unknown preset or colour map '%s' (%s)", name,
                      lua_tostring(L, -1));
}

/* Applies cdvr.tf's options table at opts (may be none) to the TF on top of the stack:
 * range={lo, hi} pins a normalised TF to data values, range="auto" makes it follow the data's
 * percentile window (percentiles={lo, hi} in percent, default {1, 99}); unit= sets the
 * opacity unit; opacity= was taken by the colour map already. */
static void apply_tf_options(lua_State *L, int opts, int from_colormap)
{
    static const char *const keys[] = {"range", "unit", "opacity", "percentiles", "volume", NULL};
    if (lua_isnoneornil(L, opts))
        return;
    luaL_checktype(L, opts, LUA_TTABLE);
    lcdvr_checkoptions(L, opts, "cdvr.tf", keys);
    cdvr_tf *tf = lcdvr_checktf(L, -1);
    int has_opacity = lua_getfield(L, opts, "opacity") != LUA_TNIL;
    lua_pop(L, 1);
    if (!from_colormap && has_opacity)
        luaL_error(L, "cdvr.tf: option 'opacity' applies to a colour map (share/colormaps: viridis, "
                      "...), not to %s%s%s",
                   tf->name[0] ? "the preset '" : "these points", tf->name,
                   tf->name[0] ? "'" : "");
    double range[2];
    cdvr_error err;
    int type = lua_getfield(L, opts, "range");
    lua_pop(L, 1);
    if (type == LUA_TSTRING) {
        lua_getfield(L, opts, "range");
        if (strcmp(lua_tostring(L, -1), "auto") != 0)
            luaL_error(L, "cdvr.tf: option 'range': {lo, hi} or \"auto\" expected, got '%s'",
                       lua_tostring(L, -1));
        lua_pop(L, 1);
        if (!tf->normalized)
            luaL_error(L, "cdvr.tf: range=\"auto\" applies to a normalised TF (a preset or colour "
                          "map that follows the data's window); this one is in data units");
        tf->auto_range = 1;
    } else if (lcdvr_numberarrayfield(L, opts, "range", range, 2) &&
               cdvr_tf_rescale(tf, range[0], range[1], &err) != CDVR_OK) {
        lcdvr_raise(L, &err);
    }
    double pct[2];
    if (lcdvr_numberarrayfield(L, opts, "percentiles", pct, 2)) {
        if (!tf->auto_range)
            luaL_error(L, "cdvr.tf: option 'percentiles' goes with range=\"auto\"");
        if (!(pct[0] >= 0.0 && pct[0] < pct[1] && pct[1] <= 100.0))
            luaL_error(L, "cdvr.tf: percentiles {%f, %f} must satisfy 0 <= lo < hi <= 100",
                       pct[0], pct[1]);
        tf->percentiles[0] = pct[0] / 100.0;
        tf->percentiles[1] = pct[1] / 100.0;
    }
    if (lua_getfield(L, opts, "volume") != LUA_TNIL) { /* resolve range="auto" now */
        if (!tf->auto_range)
            luaL_error(L, "cdvr.tf: option 'volume' goes with range=\"auto\" (its percentiles "
                          "pin the TF to data values)");
        lcdvr_checkoption(L, -1, "cdvr.tf", "volume", LCDVR_VOLUME);
        const cdvr_volume *vol = lcdvr_volume_lazy(L, -1) ? lcdvr_volume_read(L, -1, 0, 1)
                                                          : lcdvr_checkvolume(L, -1);
        if (cdvr_tf_rescale_auto(tf, vol, 0, &err) != CDVR_OK)
            lcdvr_raise(L, &err);
    }
    lua_pop(L, 1);
    double unit = lcdvr_optnumberfield(L, opts, "unit", tf->unit);
    if (!(unit >= 0.0) || !isfinite(unit))
        luaL_error(L, "cdvr.tf: option 'unit' must be >= 0 (0 = one voxel), got %f", unit);
    tf->unit = unit;
}

static int l_tf(lua_State *L)
{
    lua_settop(L, 2); /* source, options */
    int from_colormap = 0;
    if (!lua_isnil(L, 2))
        luaL_checktype(L, 2, LUA_TTABLE);
    if (lua_type(L, 1) == LUA_TSTRING) {
        const char *s = lua_tostring(L, 1);
        if (ends_with(s, ".lua"))
            load_tf_file(L, s);
        else
            load_preset(L, s, 2, &from_colormap);
    } else {
        luaL_checktype(L, 1, LUA_TTABLE);
        push_tf_from_table(L, 1);
    }
    apply_tf_options(L, 2, from_colormap);
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

/* The preset's shading settings {shade=, ambient=, diffuse=, specular=, specular_power=}, or
 * nil when it gave none. */
static int tf_shade(lua_State *L)
{
    const cdvr_tf *tf = lcdvr_checktf(L, 1);
    if (!tf->shade.present) {
        lua_pushnil(L);
        return 1;
    }
    lua_createtable(L, 0, 5);
    lua_pushboolean(L, tf->shade.on);
    lua_setfield(L, -2, "shade");
    const char *keys[] = {"ambient", "diffuse", "specular", "specular_power"};
    const double v[] = {tf->shade.ambient, tf->shade.diffuse, tf->shade.specular,
                        tf->shade.specular_power};
    for (int i = 0; i < 4; i++) {
        lua_pushnumber(L, v[i]);
        lua_setfield(L, -2, keys[i]);
    }
    return 1;
}

/* The preset or colour map the TF came from (nil if none) and whether range="auto". */
static int tf_name(lua_State *L)
{
    const cdvr_tf *tf = lcdvr_checktf(L, 1);
    if (tf->name[0])
        lua_pushstring(L, tf->name);
    else
        lua_pushnil(L);
    lua_pushboolean(L, tf->auto_range);
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
                                      {"shade", tf_shade},   {"name", tf_name},
                                      {NULL, NULL}};

static const luaL_Reg tf_meta[] = {
    {"__gc", tf_gc}, {"__close", tf_gc}, {"__tostring", tf_tostring}, {NULL, NULL}};

int lcdvr_open_tf(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_TF, tf_methods, tf_meta);
    lua_pushvalue(L, -1); /* the cdvr table, for cdvr.share_dir at call time */
    lua_pushcclosure(L, l_tf, 1);
    lua_setfield(L, -2, "tf");
    lcdvr_help_add(L, "cdvr.tf(points | preset | colour map | path.lua [, {range=, unit=, opacity=, percentiles=}])",
                   "transfer function from {{value, r,g,b, a}, ... [, unit=, normalized=]} with values in "
                   "data units (or fractions of the data's window with normalized=true), a preset of "
                   "share/tf (normalised: ct_bone, ct_soft, hot, mri; absolute, from 3D Slicer: CT-Bone, "
                   "CT-AAA, MR-Default, ...), a colour map of share/colormaps (viridis, inferno, magma, "
                   "plasma, cividis, cool_to_warm, black_body, xray, grayscale; opacity=\"ramp\" (default) "
                   "or {{x, a}, ...}) or a saved .lua file; range={lo, hi} pins a normalised one to data "
                   "values, range=\"auto\" to the 1-99% percentile window of the data rendered "
                   "(percentiles={lo, hi} in %; with volume=v its first timestep's, pinned to data values now, "
                   "for the player); a .lua file that cannot be read or is not a TF raises naming it");
    lcdvr_help_add(L, "tf:shade()", "a preset's shading {shade=, ambient=, diffuse=, specular=, specular_power=} or nil");
    lcdvr_help_add(L, "tf:name()", "the preset or colour map it came from (or nil), and whether range=\"auto\"");
    lcdvr_help_add(L, "tf:points()", "the control points {{value, r,g,b, a}, ..., unit=, normalized=}");
    lcdvr_help_add(L, "tf:lookup(v)", "r, g, b, a at value v (data units; a fraction 0..1 if normalised)");
    lcdvr_help_add(L, "tf:normalized()", "true for a TF whose values are fractions of the data's window (presets)");
    lcdvr_help_add(L, "tf:range()", "values of the first and last control points");
    lcdvr_help_add(L, "tf:unit()", "opacity unit length (0 = one voxel spacing)");
    lcdvr_help_add(L, "tf:save(path)", "write a Lua file cdvr.tf(path) reads back; true or nil, msg");
    return 0;
}
