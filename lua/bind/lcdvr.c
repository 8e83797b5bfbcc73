/* lua/bind/lcdvr.c - helpers shared by the binding files (see lcdvr.h). */
#include "cdvr/atomicfile.h"
#include "lcdvr.h"

#include <stdarg.h>
#include <string.h>

int lcdvr_raise(lua_State *L, const cdvr_error *err)
{
    if (err->status == CDVR_ERR_CANCELLED)
        return luaL_error(L, "interrupted!");
    return luaL_error(L, "%s", err->msg[0] ? err->msg : cdvr_status_name(err->status));
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
    lua_setfield(L, -2, "__index"); /* mt */
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

static int field_present(lua_State *L, int idx, const char *key, int type, const char *tname)
{
    int t = lua_getfield(L, idx, key);
    if (t == LUA_TNIL) {
        lua_pop(L, 1);
        return 0;
    }
    if (t != type && !(type == LUA_TNUMBER && lua_isnumber(L, -1)))
        luaL_error(L, "option '%s': %s expected, got %s", key, tname, luaL_typename(L, -1));
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
        luaL_error(L, "option '%s': integer expected, got %s", key, lua_tostring(L, -1));
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
        luaL_error(L, "option '%s': %d numbers expected, got %d", key, n, (int)luaL_len(L, -1));
    for (int i = 0; i < n; i++) {
        lua_geti(L, -1, i + 1);
        if (!lua_isnumber(L, -1))
            luaL_error(L, "option '%s'[%d]: number expected, got %s", key, i + 1, luaL_typename(L, -1));
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

/* ---- callback budgets (lcdvr.h) ---------------------------------------------------------- */

#define BUDGET_KEY "cdvr.budget" /* registry: light userdata, the running callback's budget */
#define BUDGET_SLICE 10000       /* instructions between two checks of the budget */

typedef struct callback_budget {
    lua_Integer limit, used;
    int spent;                   /* once set, every instruction raises */
    lua_State *L;                /* the thread that runs the callback */
} callback_budget;

#define BUDGET_MESSAGE "callback exceeded its instruction budget (callback_limit = %I instructions)"

static int traceback_handler(lua_State *L)
{
    const char *msg = lua_tostring(L, 1);
    luaL_traceback(L, L, msg ? msg : "(error object is not a string)", 1);
    return 1;
}

/* Count hook of a budgeted callback, on its thread and on every coroutine it resumes. Outside
 * a callback (a coroutine hooked by an earlier one) it removes itself. */
static void budget_hook(lua_State *L, lua_Debug *ar)
{
    (void)ar;
    lua_getfield(L, LUA_REGISTRYINDEX, BUDGET_KEY);
    callback_budget *b = (callback_budget *)lua_touserdata(L, -1);
    lua_pop(L, 1);
    if (!b) {
        lua_sethook(L, NULL, 0, 0);
        return;
    }
    if (!b->spent) {
        b->used += lua_gethookcount(L);
        if (b->used < b->limit)
            return;
        b->spent = 1;
    }
    if (lua_gethookcount(L) != 1)
        lua_sethook(L, budget_hook, LUA_MASKCOUNT, 1);
    if (b->L != L && lua_gethookcount(b->L) != 1) /* spent inside a coroutine */
        lua_sethook(b->L, budget_hook, LUA_MASKCOUNT, 1);
    luaL_error(L, BUDGET_MESSAGE, (LUAI_UACINT)b->limit);
}

int lcdvr_pcall_budget(lua_State *L, int nargs, int nres, lua_Integer limit)
{
    callback_budget b = {limit > 0 ? limit : 1, 0, 0, L};
    int base = lua_gettop(L) - nargs;              /* the function */
    lua_pushcfunction(L, traceback_handler);
    lua_insert(L, base);                           /* handler, function, args */
    lua_getfield(L, LUA_REGISTRYINDEX, BUDGET_KEY);
    void *outer = lua_touserdata(L, -1);           /* a callback running this one, or NULL */
    lua_pop(L, 1);
    lua_Hook old_hook = lua_gethook(L);
    int old_mask = lua_gethookmask(L), old_count = lua_gethookcount(L);
    lua_pushlightuserdata(L, &b);
    lua_setfield(L, LUA_REGISTRYINDEX, BUDGET_KEY);
    lua_sethook(L, budget_hook, LUA_MASKCOUNT, (int)(b.limit < BUDGET_SLICE ? b.limit : BUDGET_SLICE));
    int status = lua_pcall(L, nargs, nres, base);
    lua_sethook(L, old_hook, old_mask, old_count);
    if (status == LUA_OK && b.spent) { /* it caught every budget error and returned: still a failure */
        lua_pop(L, nres);
        lua_pushfstring(L, BUDGET_MESSAGE " (the callback caught the error and went on)", (LUAI_UACINT)b.limit);
        status = LUA_ERRRUN;
    }
    if (outer)
        lua_pushlightuserdata(L, outer);
    else
        lua_pushnil(L);
    lua_setfield(L, LUA_REGISTRYINDEX, BUDGET_KEY);
    lua_remove(L, base);
    return status;
}

/* Gives coroutine co the budget hook of L, when L runs a budgeted callback. */
static void pass_budget_on(lua_State *L, lua_State *co)
{
    lua_Hook hook = lua_gethook(L);
    if (hook != budget_hook || co == L)
        return;
    int mask = lua_gethookmask(L), count = lua_gethookcount(L);
    if (lua_gethook(co) != hook || lua_gethookmask(co) != mask || lua_gethookcount(co) != count)
        lua_sethook(co, hook, mask, count);
}

/* coroutine.resume and coroutine.close: Lua's own (upvalue 1) after passing the budget on. */
static int budget_passing_call(lua_State *L)
{
    lua_State *co = lua_tothread(L, 1);
    luaL_argexpected(L, co, 1, "coroutine");
    pass_budget_on(L, co);
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_insert(L, 1);                              /* original, co, args */
    lua_call(L, lua_gettop(L) - 1, LUA_MULTRET);
    return lua_gettop(L);
}

#if LUA_VERSION_RELEASE_NUM >= 50406
#define reset_coroutine(co, L) lua_closethread(co, L)
#else
#define reset_coroutine(co, L) ((void)(L), lua_resetthread(co))
#endif

/* A function made by coroutine.wrap: upvalue 1 the coroutine, upvalue 2 Lua's resume. Errors
 * as in Lua's coroutine.wrap (lcorolib.c auxwrap): the dead coroutine's pending to-be-closed
 * variables are closed and a string message gets the caller's position. */
static int budget_wrapped(lua_State *L)
{
    lua_State *co = lua_tothread(L, lua_upvalueindex(1));
    pass_budget_on(L, co);
    int nargs = lua_gettop(L);
    lua_pushvalue(L, lua_upvalueindex(2));
    lua_insert(L, 1);
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_insert(L, 2);                              /* resume, co, args */
    lua_call(L, nargs + 1, LUA_MULTRET);           /* ok, results or message */
    if (lua_toboolean(L, 1)) {
        lua_remove(L, 1);
        return lua_gettop(L);
    }
    int stat = lua_status(co);
    if (stat != LUA_OK && stat != LUA_YIELD) {
        stat = reset_coroutine(co, L);
        lua_xmove(co, L, 1);
    }
    if (stat != LUA_ERRMEM && lua_type(L, -1) == LUA_TSTRING) {
        luaL_where(L, 1);
        lua_insert(L, -2);
        lua_concat(L, 2);
    }
    return lua_error(L);
}

/* coroutine.wrap(f); upvalue 1 is Lua's coroutine.resume. */
static int budget_wrap(lua_State *L)
{
    luaL_checktype(L, 1, LUA_TFUNCTION);
    lua_State *co = lua_newthread(L);              /* f, co */
    lua_pushvalue(L, 1);
    lua_xmove(L, co, 1);                           /* the body goes to co's stack */
    lua_pushvalue(L, lua_upvalueindex(1));         /* f, co, resume */
    lua_pushcclosure(L, budget_wrapped, 2);
    return 1;
}

/* 1 while a budgeted callback runs whose budget is spent. */
static int budget_spent(lua_State *L)
{
    lua_getfield(L, LUA_REGISTRYINDEX, BUDGET_KEY);
    callback_budget *b = (callback_budget *)lua_touserdata(L, -1);
    lua_pop(L, 1);
    return b && b->spent;
}

/* A message handler given to xpcall (upvalue 1). Once the budget is spent it is not called:
 * the budget error is raised from inside the count hook, where Lua runs a message handler with
 * hooks off, so a handler that loops would never be stopped. */
static int budget_message_handler(lua_State *L)
{
    if (budget_spent(L))
        return 1;                                  /* the message as it is */
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_insert(L, 1);
    lua_call(L, lua_gettop(L) - 1, 1);
    return 1;
}

static int return_all(lua_State *L, int status, lua_KContext ctx)
{
    (void)status;
    (void)ctx;
    return lua_gettop(L);
}

/* xpcall(f, msgh, ...): Lua's own (upvalue 1) with msgh behind budget_message_handler. */
static int budget_xpcall(lua_State *L)
{
    luaL_checktype(L, 2, LUA_TFUNCTION);
    lua_pushvalue(L, 2);
    lua_pushcclosure(L, budget_message_handler, 1);
    lua_replace(L, 2);
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_insert(L, 1);                              /* xpcall, f, handler, args */
    lua_callk(L, lua_gettop(L) - 1, LUA_MULTRET, 0, return_all); /* yields pass through */
    return lua_gettop(L);
}

void lcdvr_open_budget(lua_State *L)
{
    if (lua_getglobal(L, "xpcall") == LUA_TFUNCTION) { /* xpcall */
        lua_pushcclosure(L, budget_xpcall, 1);
        lua_setglobal(L, "xpcall");
    } else {
        lua_pop(L, 1);
    }
    if (lua_getglobal(L, "coroutine") != LUA_TTABLE) { /* co */
        lua_pop(L, 1);
        return;
    }
    lua_getfield(L, -1, "resume");                 /* co, resume */
    lua_pushvalue(L, -1);
    lua_pushcclosure(L, budget_passing_call, 1);
    lua_setfield(L, -3, "resume");
    lua_pushcclosure(L, budget_wrap, 1);           /* co, wrap */
    lua_setfield(L, -2, "wrap");
    if (lua_getfield(L, -1, "close") == LUA_TFUNCTION) { /* co, close */
        lua_pushcclosure(L, budget_passing_call, 1);
        lua_setfield(L, -2, "close");
    } else {
        lua_pop(L, 1);
    }
    lua_pop(L, 1);
}
