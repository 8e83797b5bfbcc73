/* lua/bind/lcdvr.c - helpers shared by the binding files (see lcdvr.h). */
#include "cdvr/atomicfile.h"
#include "lcdvr.h"

#include <stdarg.h>
#include <string.h>

/* 1 when msg starts with "<name>:" for name = fname or its last component ("render:" in
 * cdvr.render, "cdvr.tf:" in cdvr.tf): the message names its function already. */
static int names_function(const char *msg, const char *fname)
{
    const char *last = strrchr(fname, '.');
    const char *names[2] = {fname, last ? last + 1 : fname};
    for (int i = 0; i < 2; i++) {
        size_t n = strlen(names[i]);
        if (strncmp(msg, names[i], n) == 0 && msg[n] == ':')
            return 1;
    }
    return 0;
}

int lcdvr_raise(lua_State *L, const cdvr_error *err)
{
    if (err->status == CDVR_ERR_CANCELLED)
        return luaL_error(L, "interrupted!");
    const char *msg = err->msg[0] ? err->msg : cdvr_status_name(err->status);
    const char *fname = lcdvr_push_funcname(L);
    if (names_function(msg, fname))
        return luaL_error(L, "%s", msg);
    return luaL_error(L, "%s: %s", fname, msg);
}

static const char *const INTERRUPT_KEY = "cdvr.interrupt";

const atomic_int *lcdvr_interrupt_flag(lua_State *L)
{
    lua_getfield(L, LUA_REGISTRYINDEX, INTERRUPT_KEY);
    const atomic_int *flag = lua_touserdata(L, -1);
    lua_pop(L, 1);
    return flag;
}

void lcdvr_set_interrupt_flag(lua_State *L, atomic_int *flag)
{
    lua_pushlightuserdata(L, flag);
    lua_setfield(L, LUA_REGISTRYINDEX, INTERRUPT_KEY);
}

int lcdvr_fail(lua_State *L, const cdvr_error *err)
{
    luaL_pushfail(L);
    lua_pushstring(L, err->msg[0] ? err->msg : cdvr_status_name(err->status));
    return 2;
}

void lcdvr_warn(lua_State *L, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    const char *msg = lua_pushvfstring(L, fmt, ap);
    va_end(ap);
    fprintf(stderr, "cdvr: warning: %s\n", msg);
    fflush(stderr);
    lua_pop(L, 1);
}

int lcdvr_save_file(lua_State *L, const char *path, int (*write)(FILE *f, const void *obj),
                    const void *obj)
{
    cdvr_atomic_file af;
    cdvr_error err;
    if (cdvr_atomic_open(&af, path, &err) != CDVR_OK ||
        cdvr_atomic_commit(&af, write(af.f, obj) != 0, &err) != CDVR_OK)
        return lcdvr_fail(L, &err);
    lua_pushboolean(L, 1);
    return 1;
}

void lcdvr_newclass(lua_State *L, const char *name, const luaL_Reg *methods, const luaL_Reg *meta)
{
    luaL_newmetatable(L, name);  /* mt (sets __name) */
    if (meta)
        luaL_setfuncs(L, meta, 0);
    lua_newtable(L);             /* mt, methods */
    if (methods)
        luaL_setfuncs(L, methods, 0);
    lcdvr_name_table(L, -1, name);
    lua_setfield(L, -2, "__index"); /* mt */
    lua_pop(L, 1);
}

void lcdvr_name_table(lua_State *L, int idx, const char *name)
{
    idx = lua_absindex(L, idx);
    luaL_getsubtable(L, LUA_REGISTRYINDEX, LUA_LOADED_TABLE);
    lua_pushvalue(L, idx);
    lua_setfield(L, -2, name);
    lua_pop(L, 1);
}

void lcdvr_setfuncs(lua_State *L, const luaL_Reg *funcs)
{
    luaL_setfuncs(L, funcs, 0);
}

void lcdvr_help_add(lua_State *L, const char *name, const char *description)
{
    lua_getfield(L, LUA_REGISTRYINDEX, "cdvr.help");  /* help */
    if (!lua_istable(L, -1)) {
        lua_pop(L, 1);
        lua_newtable(L);
        lua_pushvalue(L, -1);
        lua_setfield(L, LUA_REGISTRYINDEX, "cdvr.help");
    }
    lua_pushstring(L, description);                   /* help, description */
    lua_setfield(L, -2, name);
    lua_pop(L, 1);
}

/* Pushes the function at stack level `level`: its table name (package.loaded[mod][key] ->
 * "mod.key", "cdvr.render", "cdvr.Volume.get"), else the name it was called by, else "cdvr". */
static const char *push_funcname(lua_State *L, int level)
{
    lua_Debug ar;
    if (!lua_getstack(L, level, &ar) || !lua_getinfo(L, "nf", &ar)) {
        lua_pushliteral(L, "cdvr");
        return lua_tostring(L, -1);
    }
    int fn = lua_gettop(L);
    luaL_getsubtable(L, LUA_REGISTRYINDEX, LUA_LOADED_TABLE);
    lua_pushnil(L);
    while (lua_next(L, fn + 1)) {                  /* fn, loaded, mod, table */
        if (lua_type(L, -2) == LUA_TSTRING && lua_istable(L, -1) &&
            strcmp(lua_tostring(L, -2), "_G") != 0) {
            lua_pushnil(L);
            while (lua_next(L, -2)) {              /* ..., mod, table, key, value */
                if (lua_rawequal(L, -1, fn) && lua_type(L, -2) == LUA_TSTRING) {
                    const char *name = lua_pushfstring(L, "%s.%s", lua_tostring(L, -4),
                                                       lua_tostring(L, -2));
                    lua_replace(L, fn);
                    lua_settop(L, fn);
                    return name;
                }
                lua_pop(L, 1);
            }
        }
        lua_pop(L, 1);
    }
    lua_settop(L, fn - 1);
    if (ar.name)
        return lua_pushstring(L, ar.name);
    lua_pushliteral(L, "cdvr");
    return lua_tostring(L, -1);
}

const char *lcdvr_push_funcname(lua_State *L)
{
    return push_funcname(L, 0);
}

int lcdvr_error(lua_State *L, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    const char *msg = lua_pushvfstring(L, fmt, ap);
    va_end(ap);
    const char *fname = lcdvr_push_funcname(L);
    return luaL_error(L, "%s: %s", fname, msg);
}

/* Raises "<function>: option '<key>': <message>" (the running C function's name). */
static int option_error(lua_State *L, const char *key, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    const char *msg = lua_pushvfstring(L, fmt, ap);
    va_end(ap);
    const char *fname = lcdvr_push_funcname(L);
    return luaL_error(L, "%s: option '%s': %s", fname, key, msg);
}

static int field_present(lua_State *L, int idx, const char *key, int type, const char *tname)
{
    int t = lua_getfield(L, idx, key);
    if (t == LUA_TNIL) {
        lua_pop(L, 1);
        return 0;
    }
    if (t != type && !(type == LUA_TNUMBER && lua_isnumber(L, -1)))
        option_error(L, key, "%s expected, got %s", tname, luaL_typename(L, -1));
    return 1; /* value left on the stack */
}

lua_Number lcdvr_optnumberfield(lua_State *L, int idx, const char *key, lua_Number def)
{
    idx = lua_absindex(L, idx);
    if (!field_present(L, idx, key, LUA_TNUMBER, "number"))
        return def;
    lua_Number n = lua_tonumber(L, -1);
    lua_pop(L, 1);
    return n;
}

lua_Integer lcdvr_optintegerfield(lua_State *L, int idx, const char *key, lua_Integer def)
{
    idx = lua_absindex(L, idx);
    if (!field_present(L, idx, key, LUA_TNUMBER, "integer"))
        return def;
    int isint = 0;
    lua_Integer n = lua_tointegerx(L, -1, &isint);
    if (!isint)
        option_error(L, key, "integer expected, got %s", lua_tostring(L, -1));
    lua_pop(L, 1);
    return n;
}

const char *lcdvr_optstringfield(lua_State *L, int idx, const char *key, const char *def)
{
    idx = lua_absindex(L, idx);
    if (!field_present(L, idx, key, LUA_TSTRING, "string"))
        return def;
    /* the string stays alive while the options table holds it */
    const char *s = lua_tostring(L, -1);
    lua_pop(L, 1);
    return s;
}

int lcdvr_optbooleanfield(lua_State *L, int idx, const char *key, int def)
{
    idx = lua_absindex(L, idx);
    if (!field_present(L, idx, key, LUA_TBOOLEAN, "boolean"))
        return def;
    int b = lua_toboolean(L, -1);
    lua_pop(L, 1);
    return b;
}

int lcdvr_numberarrayfield(lua_State *L, int idx, const char *key, double *out, int n)
{
    idx = lua_absindex(L, idx);
    if (!field_present(L, idx, key, LUA_TTABLE, "table"))
        return 0;
    if ((int)luaL_len(L, -1) != n)
        option_error(L, key, "%d numbers expected, got %d", n, (int)luaL_len(L, -1));
    for (int i = 0; i < n; i++) {
        lua_geti(L, -1, i + 1);
        if (!lua_isnumber(L, -1))
            option_error(L, key, "[%d]: number expected, got %s", i + 1, luaL_typename(L, -1));
        out[i] = lua_tonumber(L, -1);
        lua_pop(L, 1);
    }
    lua_pop(L, 1);
    return 1;
}

/* Levenshtein distance of a and b, or a value above limit once it is certain to exceed it
 * (option names are short: strings longer than 63 bytes count as far apart). */
static int edit_distance(const char *a, const char *b, int limit)
{
    size_t na = strlen(a), nb = strlen(b);
    if (na > 63 || nb > 63)
        return limit + 1;
    int row[64];
    for (size_t j = 0; j <= nb; j++)
        row[j] = (int)j;
    for (size_t i = 1; i <= na; i++) {
        int diag = row[0];
        row[0] = (int)i;
        for (size_t j = 1; j <= nb; j++) {
            int up = row[j];
            int best = diag + (a[i - 1] != b[j - 1]);
            if (up + 1 < best)
                best = up + 1;
            if (row[j - 1] + 1 < best)
                best = row[j - 1] + 1;
            row[j] = best;
            diag = up;
        }
    }
    return row[nb];
}

static void check_options(lua_State *L, int idx, const char *what, const char *const keys[],
                          int array)
{
    idx = lua_absindex(L, idx);
    if (!lua_istable(L, idx))
        return;
    lua_Integer n = array ? luaL_len(L, idx) : 0;
    lua_pushnil(L); /* key */
    while (lua_next(L, idx)) { /* key, value */
        lua_pop(L, 1);         /* key */
        if (lua_isinteger(L, -1) && lua_tointeger(L, -1) >= 1 && lua_tointeger(L, -1) <= n)
            continue; /* the array part */
        if (lua_type(L, -1) != LUA_TSTRING) {
            luaL_error(L, "%s: option keys must be names, got a %s key", what,
                       luaL_typename(L, -1));
            return;
        }
        const char *key = lua_tostring(L, -1);
        const char *best = NULL;
        int best_d = 3, known = 0;
        for (int i = 0; keys[i] && !known; i++) {
            known = strcmp(keys[i], key) == 0;
            int d = known ? 0 : edit_distance(key, keys[i], best_d);
            if (!known && d < best_d) {
                best_d = d;
                best = keys[i];
            }
        }
        if (known)
            continue;
        if (best && best_d <= (strlen(key) > 3 ? 2 : 1))
            luaL_error(L, "%s: unknown option '%s' (did you mean '%s'?)", what, key, best);
        else
            luaL_error(L, "%s: unknown option '%s'", what, key);
    }
}

void lcdvr_checkoptions(lua_State *L, int idx, const char *what, const char *const keys[])
{
    check_options(L, idx, what, keys, 0);
}

void lcdvr_checkoptions_array(lua_State *L, int idx, const char *what, const char *const keys[])
{
    check_options(L, idx, what, keys, 1);
}

void *lcdvr_checkoption(lua_State *L, int idx, const char *what, const char *key, const char *tname)
{
    idx = lua_absindex(L, idx);
    void *p = luaL_testudata(L, idx, tname);
    if (!p) {
        const char *got = luaL_getmetafield(L, idx, "__name") == LUA_TSTRING ? lua_tostring(L, -1)
                                                                              : luaL_typename(L, idx);
        if (!what)
            what = lcdvr_push_funcname(L);
        luaL_error(L, "%s: option '%s': %s expected, got %s", what, key, tname, got);
    }
    return p;
}

/* ---- object lifetimes (lcdvr.h) ---------------------------------------------------------- */

#define USES_KEY "cdvr.uses"       /* registry: weak-keyed table, userdata -> C users (> 0) */
#define CLOSING_KEY "cdvr.closing" /* registry: weak-keyed table, userdata -> true (closed in use) */

/* Pushes registry[name], a table with weak keys (created on first use). */
static void push_weak_table(lua_State *L, const char *name)
{
    if (lua_getfield(L, LUA_REGISTRYINDEX, name) == LUA_TTABLE)
        return;
    lua_pop(L, 1);
    lua_newtable(L);              /* t */
    lua_createtable(L, 0, 1);     /* t, mt */
    lua_pushliteral(L, "k");
    lua_setfield(L, -2, "__mode");
    lua_setmetatable(L, -2);      /* t */
    lua_pushvalue(L, -1);
    lua_setfield(L, LUA_REGISTRYINDEX, name);
}

/* registry[table][object at absolute index idx]; nil counts as 0 / false. */
static lua_Integer weak_get(lua_State *L, const char *table, int idx)
{
    push_weak_table(L, table);    /* t */
    lua_pushvalue(L, idx);
    lua_rawget(L, -2);            /* t, value */
    lua_Integer v = lua_isboolean(L, -1) ? lua_toboolean(L, -1) : lua_tointeger(L, -1);
    lua_pop(L, 2);
    return v;
}

static void weak_set(lua_State *L, const char *table, int idx, lua_Integer v)
{
    push_weak_table(L, table);    /* t */
    lua_pushvalue(L, idx);
    if (v > 0)
        lua_pushinteger(L, v);
    else
        lua_pushnil(L);
    lua_rawset(L, -3);            /* t */
    lua_pop(L, 1);
}

void lcdvr_use(lua_State *L, int idx)
{
    idx = lua_absindex(L, idx);
    weak_set(L, USES_KEY, idx, weak_get(L, USES_KEY, idx) + 1);
}

void lcdvr_unuse(lua_State *L, int idx)
{
    idx = lua_absindex(L, idx);
    lua_Integer users = weak_get(L, USES_KEY, idx) - 1;
    weak_set(L, USES_KEY, idx, users);
    if (users > 0 || !lcdvr_closing(L, idx))
        return;
    weak_set(L, CLOSING_KEY, idx, 0);
    if (luaL_getmetafield(L, idx, "__close") == LUA_TNIL) /* __close */
        return;
    lua_pushvalue(L, idx);
    if (lua_pcall(L, 1, 0, 0) != LUA_OK) /* may run inside a __gc: never raise from here */
        lua_pop(L, 1);
}

int lcdvr_defer_close(lua_State *L, int idx)
{
    idx = lua_absindex(L, idx);
    if (weak_get(L, USES_KEY, idx) <= 0)
        return 0;
    weak_set(L, CLOSING_KEY, idx, 1);
    return 1;
}

int lcdvr_closing(lua_State *L, int idx)
{
    if (lua_getfield(L, LUA_REGISTRYINDEX, CLOSING_KEY) != LUA_TTABLE) { /* none deferred yet */
        lua_pop(L, 1);
        return 0;
    }
    lua_pop(L, 1);
    return weak_get(L, CLOSING_KEY, lua_absindex(L, idx)) != 0;
}
