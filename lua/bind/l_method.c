/* lua/bind/l_method.c - render methods in Lua (cdvr/method.h): cdvr.methods(), the state's
 * render context (the OpenCL device and the EGL slicer every binding shares, kept in the
 * registry and closed by its __gc, never in a C global), and the helpers that cdvr.render,
 * cdvr.window and cdvr.player use to read a method, its device and its options from an
 * options table: one reading of the method table for all of them. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cdvr/method.h"
#include "lcdvr.h"

#define LCDVR_RENDER_CTX "cdvr.RenderContext"
#define CTX_KEY "cdvr.render_ctx" /* registry: the state's context userdata */
#define MAX_KEYS 128 /* base + look + scene + method keys (the player has about 50) */

/* User value i + 1: the userdata of the volume the context holds at index i
 * (lcdvr_render_ctx_hold, cdvr_render_ctx_hold_volume), or nil. */
typedef struct lctx {
    cdvr_render_ctx *ctx;
} lctx;

static int ctx_gc(lua_State *L)
{
    lctx *c = (lctx *)luaL_checkudata(L, 1, LCDVR_RENDER_CTX);
    cdvr_render_ctx_free(c->ctx);
    c->ctx = NULL;
    return 0;
}

static int ctx_tostring(lua_State *L)
{
    lctx *c = (lctx *)luaL_checkudata(L, 1, LCDVR_RENDER_CTX);
    lua_pushfstring(L, "cdvr.RenderContext (%p)", (void *)c->ctx);
    return 1;
}

cdvr_render_ctx *lcdvr_render_ctx(lua_State *L)
{
    if (lua_getfield(L, LUA_REGISTRYINDEX, CTX_KEY) == LUA_TUSERDATA) {
        lctx *c = (lctx *)lua_touserdata(L, -1);
        lua_pop(L, 1);
        if (c->ctx)
            return c->ctx;
    } else {
        lua_pop(L, 1);
    }
    lctx *c = (lctx *)lua_newuserdatauv(L, sizeof *c, CDVR_RENDER_CTX_HOLDS); /* userdata
                                                         first, then the object */
    c->ctx = NULL;
    luaL_setmetatable(L, LCDVR_RENDER_CTX);
    cdvr_error err;
    if (cdvr_render_ctx_create(&c->ctx, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    lua_setfield(L, LUA_REGISTRYINDEX, CTX_KEY);
    return c->ctx;
}

/* The context c, its userdata on top of the stack, holds vol, whose userdata is at absolute
 * index idx, as the user value of its hold (the volume held there before, if another, is
 * released: its user value goes); vol NULL: releases them all. */
static void ctx_hold(lua_State *L, lctx *c, int idx, const cdvr_volume *vol)
{
    int at = cdvr_render_ctx_hold_volume(c->ctx, vol); /* before the old userdata may go */
    for (int i = 0; i < CDVR_RENDER_CTX_HOLDS; i++) {
        if (vol && i != at)
            continue;
        if (vol)
            lua_pushvalue(L, idx);
        else
            lua_pushnil(L);                      /* ctx, volume or nil */
        lua_setiuservalue(L, -2, i + 1);         /* ctx */
    }
}

void lcdvr_render_ctx_hold(lua_State *L, int idx, const cdvr_volume *vol)
{
    idx = idx ? lua_absindex(L, idx) : 0;
    lcdvr_render_ctx(L);
    lua_getfield(L, LUA_REGISTRYINDEX, CTX_KEY); /* ctx */
    ctx_hold(L, (lctx *)lua_touserdata(L, -1), idx, idx ? vol : NULL);
    lua_pop(L, 1);
}

void lcdvr_render_ctx_release(lua_State *L, const cdvr_volume *vol)
{
    if (lua_getfield(L, LUA_REGISTRYINDEX, CTX_KEY) == LUA_TUSERDATA) { /* ctx */
        lctx *c = (lctx *)lua_touserdata(L, -1);
        int at = c->ctx ? cdvr_render_ctx_held_index(c->ctx, vol) : -1;
        if (at >= 0) {
            cdvr_render_ctx_release_volume(c->ctx, vol);
            lua_pushnil(L);                      /* ctx, nil */
            lua_setiuservalue(L, -2, at + 1);    /* ctx */
        }
    }
    lua_pop(L, 1);
}

/* ---- reading a method from an options table ---------------------------------------------- */

const cdvr_render_method *lcdvr_method_lookup(lua_State *L, const char *name, const char *what)
{
    const cdvr_render_method *m = cdvr_render_method_find(name);
    if (!m) {
        char names[256];
        cdvr_render_method_names(names, sizeof names);
        luaL_error(L, "%s: option 'method': unknown method '%s' (methods: %s)", what, name, names);
    }
    return m;
}

const cdvr_render_method *lcdvr_method_option(lua_State *L, int idx, const char *what)
{
    const char *name = lcdvr_optstringfield(L, idx, "method", "raycast");
    return lcdvr_method_lookup(L, name, what);
}

const char *const lcdvr_look_keys[] = {"blend", "iso", "shade", "ambient", "diffuse", "specular",
                                       "specular_power", "light", "gradient_opacity",
                                       "annotate", NULL};

/* The keys an options table may hold for method m: `base` (NULL-terminated), the look keys,
 * the scene keys m honours and m's own options; -1 when there are more than MAX_KEYS - 1 (a
 * list cut short would call valid keys unknown, as it once did silently: callers raise). */
static int method_keys(const cdvr_render_method *m, const char *const base[],
                       const char *keys[MAX_KEYS])
{
    static const struct { unsigned bit; const char *key; } scene[] = {
        {CDVR_SCENE_STEP, "step"}, {CDVR_SCENE_UNIT, "unit"}, {CDVR_SCENE_TERM, "term"},
        {CDVR_SCENE_THREADS, "threads"}};
    const char *all[4 * MAX_KEYS]; /* every list is far shorter than MAX_KEYS alone */
    int n = 0;
    for (int i = 0; base[i] && n < 4 * MAX_KEYS; i++)
        all[n++] = base[i];
    for (int i = 0; lcdvr_look_keys[i] && n < 4 * MAX_KEYS; i++)
        all[n++] = lcdvr_look_keys[i];
    for (size_t i = 0; i < sizeof scene / sizeof scene[0] && n < 4 * MAX_KEYS; i++)
        if (m->scene_keys & scene[i].bit)
            all[n++] = scene[i].key;
    for (const cdvr_method_option *o = m->options; o->key && n < 4 * MAX_KEYS; o++)
        all[n++] = o->key;
    if (n > MAX_KEYS - 1)
        return -1;
    memcpy(keys, all, (size_t)n * sizeof *keys);
    keys[n] = NULL;
    return n;
}

void lcdvr_method_checkoptions(lua_State *L, int idx, const cdvr_render_method *m,
                               const char *what, const char *const base[])
{
    const char *keys[MAX_KEYS];
    if (method_keys(m, base, keys) < 0)
        luaL_error(L, "%s: internal error: more than %d option keys for method %s (MAX_KEYS)",
                   what, MAX_KEYS - 1, m->name);
    lcdvr_checkoptions(L, idx, what, keys);
}

int lcdvr_method_takes(const cdvr_render_method *m, const char *key)
{
    static const char *const none[] = {NULL};
    const char *keys[MAX_KEYS];
    if (method_keys(m, none, keys) < 0)
        return 0;
    for (int i = 0; keys[i]; i++)
        if (strcmp(keys[i], key) == 0)
            return 1;
    return 0;
}

/* The value on top of the stack as option text for o (numbers "%.17g" or integers, booleans
 * "true"/"false", strings as they are); raises naming the option when its type is wrong. */
static const char *option_text(lua_State *L, const cdvr_method_option *o, const char *what,
                               char *buf, size_t n)
{
    int type = lua_type(L, -1);
    int number_ok = o->type == CDVR_MOPT_NUMBER || o->type == CDVR_MOPT_INTEGER;
    if (type == LUA_TNUMBER && number_ok) {
        if (lua_isinteger(L, -1))
            snprintf(buf, n, "%lld", (long long)lua_tointeger(L, -1));
        else
            snprintf(buf, n, "%.17g", (double)lua_tonumber(L, -1));
        return buf;
    }
    if (type == LUA_TBOOLEAN && (o->type == CDVR_MOPT_BOOLEAN || o->type == CDVR_MOPT_CHOICE))
        return lua_toboolean(L, -1) ? "true" : "false";
    if (type == LUA_TSTRING && o->type == CDVR_MOPT_CHOICE)
        return lua_tostring(L, -1);
    const char *expected = number_ok ? "a number" : o->type == CDVR_MOPT_BOOLEAN ? "a boolean"
                                                                               : o->choices;
    luaL_error(L, "%s: option '%s': %s expected, got %s", what, o->key, expected,
               type == LUA_TSTRING ? lua_tostring(L, -1) : luaL_typename(L, -1));
    return NULL;
}

void lcdvr_method_params(lua_State *L, int idx, const cdvr_render_method *m, const char *what,
                         cdvr_method_params *out)
{
    memset(out, 0, sizeof *out);
    m->params_default(out);
    if (!lua_istable(L, idx))
        return;
    for (const cdvr_method_option *o = m->options; o->key; o++) {
        if (lua_getfield(L, idx, o->key) == LUA_TNIL) {
            lua_pop(L, 1);
            continue;
        }
        char buf[64];
        const char *text = option_text(L, o, what, buf, sizeof buf);
        cdvr_error err;
        if (m->params_set(out, o->key, text, &err) != CDVR_OK)
            luaL_error(L, "%s: %s", what, err.msg);
        lua_pop(L, 1);
    }
}

/* ---- blend mode, shading, gradient opacity, iso ----------------------------------------- */

static double checked_number(lua_State *L, int idx, const char *key, double def, double lo,
                             double hi, const char *what)
{
    int type = lua_getfield(L, idx, key);
    double v = def;
    if (type != LUA_TNIL) {
        int ok;
        v = lua_tonumberx(L, -1, &ok);
        if (!ok || !(v >= lo && v <= hi)) {
            char range[64]; /* luaL_error has no %g */
            snprintf(range, sizeof range, "[%g, %g]", lo, hi);
            luaL_error(L, "%s: option '%s': a number in %s expected, got %s", what, key, range,
                       ok ? lua_tostring(L, -1) : luaL_typename(L, -1));
        }
    }
    lua_pop(L, 1);
    return v;
}

/* {x, y, z} at the top of the stack into v (finite numbers). */
static void read_vec3(lua_State *L, const char *what, const char *key, double v[3])
{
    if (!lua_istable(L, -1) || luaL_len(L, -1) != 3)
        luaL_error(L, "%s: option '%s': {x, y, z} expected", what, key);
    for (int a = 0; a < 3; a++) {
        lua_geti(L, -1, a + 1);
        int ok;
        v[a] = lua_tonumberx(L, -1, &ok);
        if (!ok || !isfinite(v[a]))
            luaL_error(L, "%s: option '%s': {x, y, z} of finite numbers expected", what, key);
        lua_pop(L, 1);
    }
}

static void read_light(lua_State *L, int idx, cdvr_shading *sh, const char *what)
{
    if (lua_getfield(L, idx, "light") == LUA_TNIL) {
        lua_pop(L, 1);
        return;
    }
    static const char *const keys[] = {"dir", "headlight", NULL};
    if (!lua_istable(L, -1))
        luaL_error(L, "%s: option 'light': {dir={x, y, z}} or {headlight=true} expected", what);
    lcdvr_checkoptions(L, -1, "light", keys);
    if (lua_getfield(L, -1, "dir") != LUA_TNIL) {
        read_vec3(L, what, "light.dir", sh->light_dir);
        sh->light_fixed = 1;
    }
    lua_pop(L, 1);
    if (lcdvr_optbooleanfield(L, -1, "headlight", 0))
        sh->light_fixed = 0;
    lua_pop(L, 1);
}

static void read_gradient_opacity(lua_State *L, int idx, cdvr_gradient_opacity *go,
                                  const char *what)
{
    if (lua_getfield(L, idx, "gradient_opacity") == LUA_TNIL) {
        lua_pop(L, 1);
        return;
    }
    lua_Integer n = lua_istable(L, -1) ? luaL_len(L, -1) : -1;
    if (n < 1 || n > CDVR_GRADIENT_OPACITY_MAX)
        luaL_error(L, "%s: option 'gradient_opacity': a list of 1..%d {magnitude, opacity} pairs "
                   "expected", what, CDVR_GRADIENT_OPACITY_MAX);
    go->npoints = (size_t)n;
    for (lua_Integer i = 1; i <= n; i++) {
        lua_geti(L, -1, i);                       /* list, pair */
        int ok_m = 0, ok_a = 0;
        if (lua_istable(L, -1) && luaL_len(L, -1) == 2) {
            lua_geti(L, -1, 1);
            go->magnitude[i - 1] = lua_tonumberx(L, -1, &ok_m);
            lua_geti(L, -2, 2);
            go->factor[i - 1] = lua_tonumberx(L, -1, &ok_a);
            lua_pop(L, 2);
        }
        if (!ok_m || !ok_a)
            luaL_error(L, "%s: option 'gradient_opacity': entry %d: {magnitude, opacity} expected",
                       what, (int)i);
        lua_pop(L, 1);
    }
    lua_pop(L, 1);
}

static void read_iso(lua_State *L, int idx, cdvr_look *look, const char *what)
{
    static const char *const keys[] = {"value", "color", "opacity", NULL};
    if (!lua_istable(L, -1))
        luaL_error(L, "%s: option 'iso': {value=, color={r, g, b}, opacity=} expected", what);
    lcdvr_checkoptions(L, -1, "iso", keys);
    int iso = lua_gettop(L);
    if (lua_getfield(L, iso, "value") != LUA_TNUMBER)
        luaL_error(L, "%s: option 'iso': value= (a number in data units) is required", what);
    look->iso_value = lua_tonumber(L, -1);
    lua_pop(L, 1);
    if (lua_getfield(L, iso, "color") != LUA_TNIL) {
        double rgb[3];
        read_vec3(L, what, "iso.color", rgb);
        for (int c = 0; c < 3; c++)
            look->iso_color[c] = (float)rgb[c];
        look->iso_color_set = 1;
    }
    lua_pop(L, 1);
    look->iso_opacity = checked_number(L, iso, "opacity", 1.0, 0.0, 1.0, what);
    (void)idx;
}

void lcdvr_read_look(lua_State *L, int idx, const cdvr_render_method *m, const char *what,
                     cdvr_look *look)
{
    memset(look, 0, sizeof *look);
    if (!lua_istable(L, idx))
        return;
    idx = lua_absindex(L, idx);
    const char *blend = lcdvr_optstringfield(L, idx, "blend", NULL);
    int has_iso = lua_getfield(L, idx, "iso") != LUA_TNIL;
    if (has_iso && !blend)
        blend = "iso";
    int b = blend ? cdvr_blend_parse(blend) : CDVR_BLEND_COMPOSITE;
    if (b < 0)
        luaL_error(L, "%s: option 'blend': unknown mode '%s' (composite, max, min, average, iso)",
                   what, blend);
    if (!(m->blends & CDVR_BLEND_BIT(b)))
        luaL_error(L, "%s: method '%s' has no blend mode '%s'", what, m->name, blend);
    look->blend = b;
    if (b == CDVR_BLEND_ISO && !has_iso)
        luaL_error(L, "%s: blend 'iso' needs iso={value=, color=}", what);
    if (has_iso && b != CDVR_BLEND_ISO)
        luaL_error(L, "%s: option 'iso' is for blend 'iso', not '%s'", what, blend);
    if (has_iso)
        read_iso(L, idx, look, what);
    lua_pop(L, 1);
    /* iso surfaces are shaded unless shade=false; composite only with shade=true */
    int shade = lcdvr_optbooleanfield(L, idx, "shade", b == CDVR_BLEND_ISO);
    read_gradient_opacity(L, idx, &look->gradient_opacity, what);
    if ((shade || look->gradient_opacity.npoints) && !m->shading)
        luaL_error(L, "%s: method '%s' does not shade (shade=, gradient_opacity= are for %s)",
                   what, m->name, "raycast");
    cdvr_shading *sh = &look->shade;
    cdvr_shading_default(sh);
    sh->enabled = shade;
    sh->ambient = checked_number(L, idx, "ambient", sh->ambient, 0.0, 1e6, what);
    sh->diffuse = checked_number(L, idx, "diffuse", sh->diffuse, 0.0, 1e6, what);
    sh->specular = checked_number(L, idx, "specular", sh->specular, 0.0, 1e6, what);
    sh->specular_power = checked_number(L, idx, "specular_power", sh->specular_power, 0.0, 1e6, what);
    read_light(L, idx, sh, what);
}

/* ---- annotations (cdvr/annotate.h) -------------------------------------------------------- */

int lcdvr_read_annotate(lua_State *L, int idx, const char *what, cdvr_annotate_opts *o,
                        int *time)
{
    memset(o, 0, sizeof *o);
    *time = 0;
    if (!lua_istable(L, idx))
        return 0;
    idx = lua_absindex(L, idx);
    int type = lua_getfield(L, idx, "annotate");
    if (type == LUA_TNIL || (type == LUA_TBOOLEAN && !lua_toboolean(L, -1))) {
        lua_pop(L, 1);
        return 0;
    }
    if (type == LUA_TBOOLEAN) { /* annotate=true: the bar and the letters */
        o->colorbar = o->axes = 1;
        lua_pop(L, 1);
        return 1;
    }
    if (type != LUA_TTABLE)
        luaL_error(L, "%s: option 'annotate': true or {colorbar=, axes=, title=, time=, unit=, "
                      "space=} expected, got %s", what, luaL_typename(L, -1));
    static const char *const keys[] = {"colorbar", "axes", "title", "time", "unit", "space", NULL};
    lcdvr_checkoptions(L, -1, "annotate", keys);
    o->colorbar = lcdvr_optbooleanfield(L, -1, "colorbar", 0);
    o->axes = lcdvr_optbooleanfield(L, -1, "axes", 0);
    *time = lcdvr_optbooleanfield(L, -1, "time", 0);
    /* the strings live in the options table, which the caller keeps while it draws */
    o->title = lcdvr_optstringfield(L, -1, "title", NULL);
    o->unit = lcdvr_optstringfield(L, -1, "unit", NULL);
    o->space = lcdvr_optstringfield(L, -1, "space", NULL);
    lua_pop(L, 1);
    return o->colorbar || o->axes || *time || (o->title && *o->title);
}

cdvr_device_kind lcdvr_method_device(lua_State *L, int idx, const cdvr_render_method *m,
                                     const char *what)
{
    const char *name = lua_istable(L, idx) ? lcdvr_optstringfield(L, idx, "device", NULL) : NULL;
    if (!name || strcmp(name, "auto") == 0)
        return cdvr_render_method_default_device(m, lcdvr_render_ctx(L));
    int kind = cdvr_device_parse(name);
    cdvr_error err;
    if (kind < 0) {
        char list[64];
        cdvr_render_method_devices(m, list, sizeof list);
        luaL_error(L, "%s: option 'device': unknown device '%s' (method '%s' renders on %s)",
                   what, name, m->name, list);
    }
    if (cdvr_render_method_check_device(m, (cdvr_device_kind)kind, &err) != CDVR_OK)
        luaL_error(L, "%s: %s", what, err.msg);
    return (cdvr_device_kind)kind;
}

void lcdvr_push_render_stats(lua_State *L, const cdvr_render_method *m, cdvr_device_kind device,
                             const cdvr_render_stats *stats)
{
    lua_createtable(L, 0, (int)stats->count + 1);
    lua_pushstring(L, cdvr_device_name(device)); /* a method may name the device more closely */
    lua_setfield(L, -2, "device");
    for (size_t i = 0; i < stats->count; i++) {
        const cdvr_render_stat *s = &stats->items[i];
        if (s->kind == CDVR_STAT_STRING)
            lua_pushstring(L, s->string);
        else if (s->kind == CDVR_STAT_INTEGER)
            lua_pushinteger(L, (lua_Integer)s->integer);
        else
            lua_pushnumber(L, s->number);
        lua_setfield(L, -2, s->key);
    }
    lua_pushstring(L, m->name);
    lua_setfield(L, -2, "method");
}

/* ---- cdvr.methods() ---------------------------------------------------------------------- */

static void push_bits(lua_State *L, unsigned bits, const char *const names[], int count)
{
    lua_createtable(L, count, 0);
    int n = 0;
    for (int i = 0; i < count; i++)
        if (bits & (1u << i)) {
            lua_pushstring(L, names[i]);
            lua_rawseti(L, -2, ++n);
        }
}

static void push_method(lua_State *L, const cdvr_render_method *m)
{
    static const char *const devices[] = {"cpu", "cl", "gl"};
    static const char *const blends[] = {"composite", "max", "min", "average", "iso"};
    static const char *const dist[] = {"time", "bricks"};
    static const char *const scene[] = {"step", "unit", "term", "threads"};
    static const char *const types[] = {"number", "integer", "boolean", "choice"};
    lua_createtable(L, 0, 10);
    lua_pushstring(L, m->name);
    lua_setfield(L, -2, "name");
    lua_pushstring(L, m->description);
    lua_setfield(L, -2, "description");
    push_bits(L, m->devices, devices, 3);
    lua_setfield(L, -2, "devices");
    push_bits(L, m->blends, blends, 5);
    lua_setfield(L, -2, "blends");
    lua_pushboolean(L, m->shading);
    lua_setfield(L, -2, "shading");
    lua_pushboolean(L, m->bricks);
    lua_setfield(L, -2, "bricks");
    push_bits(L, m->distribute, dist, 2);
    lua_setfield(L, -2, "distribute");
    push_bits(L, m->scene_keys, scene, 4);
    lua_setfield(L, -2, "scene_options");
    lua_newtable(L);                              /* method, options */
    int n = 0;
    for (const cdvr_method_option *o = m->options; o->key; o++) {
        lua_createtable(L, 0, 5);
        lua_pushstring(L, o->key);
        lua_setfield(L, -2, "key");
        lua_pushstring(L, types[o->type]);
        lua_setfield(L, -2, "type");
        if (o->def) {
            lua_pushstring(L, o->def);
            lua_setfield(L, -2, "default");
        }
        if (o->choices) {
            lua_pushstring(L, o->choices);
            lua_setfield(L, -2, "choices");
        }
        lua_pushstring(L, o->doc);
        lua_setfield(L, -2, "doc");
        lua_rawseti(L, -2, ++n);
    }
    lua_setfield(L, -2, "options");
}

/* cdvr.methods() -> {{name=, description=, devices={...}, options={{key=, default=, doc=}}, ...}} */
static int l_methods(lua_State *L)
{
    size_t n = cdvr_render_method_count();
    lua_createtable(L, (int)n, 0);
    for (size_t i = 0; i < n; i++) {
        push_method(L, cdvr_render_method_at(i));
        lua_rawseti(L, -2, (lua_Integer)i + 1);
    }
    return 1;
}

/* Help lines made from the table, so cdvr.help and the method's options never disagree. */
static void add_help(lua_State *L, const cdvr_render_method *m)
{
    luaL_Buffer b;
    luaL_buffinit(L, &b);
    char devices[64];
    cdvr_render_method_devices(m, devices, sizeof devices);
    lua_pushfstring(L, "%s (devices: %s)", m->description, devices);
    luaL_addvalue(&b);
    for (const cdvr_method_option *o = m->options; o->key; o++) {
        lua_pushfstring(L, "; %s=%s: %s", o->key, o->def ? o->def : "(unset)", o->doc);
        luaL_addvalue(&b);
    }
    luaL_pushresult(&b);                          /* text */
    char name[64];
    snprintf(name, sizeof name, "cdvr.render(v, {method=\"%s\", ...})", m->name);
    lcdvr_help_add(L, name, lua_tostring(L, -1));
    lua_pop(L, 1);
}

int lcdvr_open_method(lua_State *L)
{
    static const luaL_Reg meta[] = {
        {"__gc", ctx_gc}, {"__close", ctx_gc}, {"__tostring", ctx_tostring}, {NULL, NULL}};
    static const luaL_Reg methods[] = {{NULL, NULL}};
    static const luaL_Reg funcs[] = {{"methods", l_methods}, {NULL, NULL}};
    lcdvr_newclass(L, LCDVR_RENDER_CTX, methods, meta);
    lcdvr_setfuncs(L, funcs);
    lcdvr_help_add(L, "cdvr.methods()",
                   "the render methods: {name=, description=, devices=, blends=, shading=, bricks=, "
                   "distribute=, scene_options=, options={{key=, type=, default=, choices=, doc=}}}; "
                   "the default device is cl when the method has it and an OpenCL device opens, "
                   "else cpu (then gl)");
    for (size_t i = 0; i < cdvr_render_method_count(); i++)
        add_help(L, cdvr_render_method_at(i));
    return 0;
}
