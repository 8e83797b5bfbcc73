/* lua/bind/lbudget.c - callback budgets, the Lua state's memory limit and the data-file loader
 * (lcdvr.h, "Callback budgets").
 *
 * What a budget bounds, and how:
 *   instructions  a count hook on the callback's thread and on every coroutine it runs
 *                 (coroutines made inside inherit the hook; coroutine.resume, wrap and close
 *                 are reimplemented here to pass it on to older ones); C loops that run no VM
 *                 instruction charge the budget themselves: pattern matching (lstrmatch.c),
 *                 string.rep, table.move;
 *   memory        the state's allocator (lcdvr_newstate) counts its bytes; while a callback
 *                 runs, an allocation beyond what the state held when it started plus its
 *                 memory budget fails (Lua raises "not enough memory", which the budgeted call
 *                 reports as "callback exceeded its memory budget (callback_memory = N MB)");
 *   escapes       debug.* (but traceback and getinfo) raises inside a callback; the upvalues of
 *                 C functions are not reachable (debug.getupvalue/setupvalue refuse them) and
 *                 no wrapper here keeps Lua's own function as an upvalue, so nothing leads back
 *                 to an unbudgeted coroutine.resume or xpcall;
 *   finalizers    Lua runs __gc with hooks off, so a looping one could never be stopped.
 *                 setmetatable and debug.setmetatable move a metatable's __gc aside and put
 *                 gc_runner in its place, which runs the real one in a fresh coroutine under the
 *                 running callback's budget, or under a budget of its own (the defaults)
 *                 outside callbacks and at lua_close (lcdvr_close).
 * The running budget lives in the allocator's context (lua_getallocf), out of reach of Lua.
 * Not bounded: native code and blocking system calls (package.loadlib and C modules,
 * os.execute, io.read), memory that C bindings allocate, and a __gc assigned into a guarded
 * metatable during a callback and collected before the callback returns (guards are renewed
 * when a budget starts and before lua_close, not at every assignment).
 */
#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "lcdvr.h"

/* ---- the state's context: allocator and running budget ----------------------------------- */

typedef struct callback_budget callback_budget;

typedef struct state_ctx {
    lua_Alloc base;              /* the allocator luaL_newstate gave the state */
    void *base_ud;
    size_t used;                 /* bytes the state holds */
    size_t limit;                /* allocations beyond it fail (SIZE_MAX: none) */
    callback_budget *budget;     /* the innermost running budget, NULL outside callbacks */
    int opened;                  /* lcdvr_open_budget ran */
    int gc_failures;             /* finalizers stopped by their budget */
} state_ctx;

struct callback_budget {
    lua_Integer limit, used;     /* VM instructions (and charged C steps) */
    int spent;                   /* once set, every instruction raises */
    size_t memory;               /* the memory budget in bytes */
    size_t saved_limit;          /* the state's limit before this budget */
    int mem_refused;             /* an allocation was refused */
    int detached;                /* a finalizer's own budget: not counted against the outer */
    const void *chunk;           /* a data file: the only function that may run; else NULL */
    lua_State *L;                /* the thread that runs the callback */
    callback_budget *outer;
};

static void *budget_alloc(void *ud, void *ptr, size_t osize, size_t nsize)
{
    state_ctx *c = ud;
    size_t old = ptr ? osize : 0;
    if (nsize > old && (c->used > c->limit || nsize - old > c->limit - c->used)) {
        if (c->budget)
            c->budget->mem_refused = 1;
        return NULL;
    }
    void *p = c->base(c->base_ud, ptr, osize, nsize);
    if (p || nsize == 0)
        c->used = c->used - old + nsize;
    return p;
}

static state_ctx *ctx_of(lua_State *L)
{
    void *ud = NULL;
    return lua_getallocf(L, &ud) == budget_alloc ? ud : NULL;
}

lua_State *lcdvr_newstate(void)
{
    state_ctx *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    lua_State *L = luaL_newstate(); /* Lua's panic and warning functions */
    if (!L) {
        free(c);
        return NULL;
    }
    c->base = lua_getallocf(L, &c->base_ud);
    c->used = (size_t)lua_gc(L, LUA_GCCOUNT, 0) * 1024 + (size_t)lua_gc(L, LUA_GCCOUNTB, 0);
    c->limit = SIZE_MAX;
    lua_setallocf(L, budget_alloc, c);
    return L;
}

static void guard_all_finalizers(lua_State *L);

int lcdvr_close(lua_State *L)
{
    state_ctx *c = ctx_of(L);
    if (c)
        guard_all_finalizers(L);
    lua_close(L); /* finalizers run through gc_runner, each under its own budget */
    if (!c)
        return 0;
    int failures = c->gc_failures;
    free(c);
    return failures;
}

/* ---- budgets --------------------------------------------------------------------------- */

#define BUDGET_SLICE 10000 /* instructions between two checks of the budget */
#define BUDGET_MESSAGE "callback exceeded its instruction budget (callback_limit = %I instructions)"
#define MEMORY_MESSAGE "callback exceeded its memory budget (callback_memory = %d MB)"
#define DATA_BASE_BUDGET 100000 /* VM instructions a data file may run, plus DATA_PER_BYTE a byte */
#define DATA_PER_BYTE 16

static int budget_slice(const callback_budget *b)
{
    return (int)(b->limit < BUDGET_SLICE ? b->limit : BUDGET_SLICE);
}

static int memory_mb(const callback_budget *b)
{
    return (int)(b->memory >> 20);
}

static void budget_hook(lua_State *L, lua_Debug *ar);

/* Marks b spent and makes every further instruction of its thread and of L raise. */
static void budget_spend(lua_State *L, callback_budget *b)
{
    b->spent = 1;
    int mask = LUA_MASKCOUNT | (b->chunk ? LUA_MASKCALL : 0);
    if (lua_gethook(L) != budget_hook || lua_gethookcount(L) != 1)
        lua_sethook(L, budget_hook, mask, 1);
    if (b->L != L && lua_gethookcount(b->L) != 1)
        lua_sethook(b->L, budget_hook, mask, 1);
}

static int budget_error(lua_State *L, const callback_budget *b)
{
    return luaL_error(L, BUDGET_MESSAGE, (LUAI_UACINT)b->limit);
}

void lcdvr_budget_charge(lua_State *L, lua_Integer steps)
{
    state_ctx *c = ctx_of(L);
    callback_budget *b = c ? c->budget : NULL;
    if (!b)
        return;
    if (!b->spent) {
        b->used += steps;
        if (b->used < b->limit)
            return;
        budget_spend(L, b);
    }
    budget_error(L, b);
}

/* Count (and, for a data file, call) hook of a budget, on its thread and on every coroutine
 * it runs. Outside a budget (a coroutine hooked by an earlier one) it removes itself. */
static void budget_hook(lua_State *L, lua_Debug *ar)
{
    state_ctx *c = ctx_of(L);
    callback_budget *b = c ? c->budget : NULL;
    if (!b) {
        lua_sethook(L, NULL, 0, 0);
        return;
    }
    if (ar->event == LUA_HOOKCALL || ar->event == LUA_HOOKTAILCALL) {
        if (!b->chunk)
            return;
        lua_getinfo(L, "f", ar);
        const void *f = lua_topointer(L, -1);
        lua_pop(L, 1);
        if (f != b->chunk)
            luaL_error(L, "data file calls a function (not plain data)");
        return;
    }
    if (!b->spent) {
        b->used += lua_gethookcount(L);
        if (b->used < b->limit)
            return;
    }
    budget_spend(L, b);
    budget_error(L, b);
}

static void budget_begin(state_ctx *c, callback_budget *b, lua_State *L, const lcdvr_limits *lim)
{
    memset(b, 0, sizeof *b);
    b->limit = lim->instructions > 0 ? lim->instructions : 1;
    b->memory = lim->memory;
    b->L = L;
    b->outer = c->budget;
    b->saved_limit = c->limit;
    size_t want = c->used + lim->memory < c->used ? SIZE_MAX : c->used + lim->memory;
    if (want < c->limit)
        c->limit = want;
    c->budget = b;
}

/* Ends b: the state's limit and the outer budget come back; what b used counts against the
 * outer budget (a nested budget never lengthens the outer one). */
static void budget_end(state_ctx *c, callback_budget *b)
{
    c->budget = b->outer;
    c->limit = b->saved_limit;
    callback_budget *o = b->outer;
    if (o && !o->spent && !b->detached) {
        o->used += b->used;
        if (o->used >= o->limit)
            budget_spend(o->L, o);
    }
}

/* The error object as text (its __tostring: luaL_tolstring; "(error object is a table
 * value)" without one), with the traceback. */
static int traceback_handler(lua_State *L)
{
    const char *msg = lua_tostring(L, 1);
    if (!msg && luaL_getmetafield(L, 1, "__tostring") != LUA_TNIL) {
        lua_pop(L, 1);
        msg = luaL_tolstring(L, 1, NULL);
    }
    if (!msg)
        msg = lua_pushfstring(L, "(error object is a %s value)", luaL_typename(L, 1));
    luaL_traceback(L, L, msg, 1);
    return 1;
}

/* The function below its nargs arguments in protected mode under lim; with a traceback
 * handler unless data (a data file: calls refused, so no handler may run either). */
static int run_budgeted(lua_State *L, int nargs, int nres, const lcdvr_limits *lim,
                        const void *data)
{
    state_ctx *c = ctx_of(L);
    if (!c) {
        lua_pop(L, nargs + 1);
        lua_pushliteral(L, "callback budgets need a Lua state made by lcdvr_newstate");
        return LUA_ERRRUN;
    }
    guard_all_finalizers(L);
    int base = lua_gettop(L) - nargs; /* the function */
    if (!data) {
        lua_pushcfunction(L, traceback_handler);
        lua_insert(L, base);              /* handler, function, args */
    }
    lua_Hook old_hook = lua_gethook(L);
    int old_mask = lua_gethookmask(L), old_count = lua_gethookcount(L);
    callback_budget b;
    budget_begin(c, &b, L, lim);
    b.chunk = data;
    lua_sethook(L, budget_hook, LUA_MASKCOUNT | (data ? LUA_MASKCALL : 0), budget_slice(&b));
    int status = lua_pcall(L, nargs, nres, data ? 0 : base);
    lua_sethook(L, old_hook, old_mask, old_count);
    budget_end(c, &b);
    if (b.outer && b.outer->spent && lua_gethook(L) == budget_hook)
        lua_sethook(L, budget_hook, lua_gethookmask(L), 1);
    if (status == LUA_OK && b.spent) { /* it caught every budget error and returned */
        lua_pop(L, nres);
        lua_pushfstring(L, BUDGET_MESSAGE " (the callback caught the error and went on)",
                        (LUAI_UACINT)b.limit);
        status = LUA_ERRRUN;
    } else if (status != LUA_OK && b.mem_refused && !b.spent) {
        const char *msg = lua_tostring(L, -1);
        if (status == LUA_ERRMEM || status == LUA_ERRERR || !msg || strstr(msg, "not enough memory")) {
            lua_pop(L, 1);
            lua_pushfstring(L, MEMORY_MESSAGE, memory_mb(&b));
            status = LUA_ERRMEM;
        }
    }
    if (status != LUA_OK && data && b.spent) {
        lua_pop(L, 1);
        lua_pushfstring(L, "data file runs too long (more than %I VM instructions: not plain data)",
                        (LUAI_UACINT)b.limit);
    }
    if (!data)
        lua_remove(L, base);
    return status;
}

int lcdvr_pcall_limits(lua_State *L, int nargs, int nres, const lcdvr_limits *lim)
{
    return run_budgeted(L, nargs, nres, lim, NULL);
}

int lcdvr_pcall_budget(lua_State *L, int nargs, int nres, lua_Integer limit)
{
    lcdvr_limits lim = {limit, (size_t)LCDVR_CALLBACK_MEMORY_MB << 20};
    return run_budgeted(L, nargs, nres, &lim, NULL);
}

void lcdvr_limits_options(lua_State *L, int idx, const char *what, lcdvr_limits *out)
{
    out->instructions = LCDVR_CALLBACK_LIMIT;
    out->memory = (size_t)LCDVR_CALLBACK_MEMORY_MB << 20;
    if (!lua_istable(L, idx))
        return;
    lua_Integer n = lcdvr_optintegerfield(L, idx, "callback_limit", LCDVR_CALLBACK_LIMIT);
    if (n < 1 || n > INT_MAX)
        luaL_error(L, "%s: option 'callback_limit' must be 1 .. %d VM instructions, got %I", what,
                   INT_MAX, (LUAI_UACINT)n);
    lua_Number mb = lcdvr_optnumberfield(L, idx, "callback_memory", LCDVR_CALLBACK_MEMORY_MB);
    if (!(mb >= 1 && mb <= 1 << 20))
        luaL_error(L, "%s: option 'callback_memory' must be 1 .. %d MB, got %f", what, 1 << 20,
                   (LUAI_UACNUMBER)mb);
    out->instructions = n;
    out->memory = (size_t)(mb * 1048576.0);
}

/* ---- coroutines and xpcall that pass the budget on --------------------------------------- */

/* Gives coroutine co the budget hook of L, when L runs a budget. */
static void pass_budget_on(lua_State *L, lua_State *co)
{
    lua_Hook hook = lua_gethook(L);
    if (hook != budget_hook || co == L)
        return;
    int mask = lua_gethookmask(L), count = lua_gethookcount(L);
    if (lua_gethook(co) != hook || lua_gethookmask(co) != mask || lua_gethookcount(co) != count)
        lua_sethook(co, hook, mask, count);
}

/* lcorolib.c's auxresume, with the budget passed on. */
static int aux_resume(lua_State *L, lua_State *co, int narg)
{
    if (!lua_checkstack(co, narg)) {
        lua_pushliteral(L, "too many arguments to resume");
        return -1;
    }
    pass_budget_on(L, co);
    lua_xmove(L, co, narg);
    int nres = 0;
    int status = lua_resume(co, L, narg, &nres);
    if (status == LUA_OK || status == LUA_YIELD) {
        if (!lua_checkstack(L, nres + 1)) {
            lua_pop(co, nres);
            lua_pushliteral(L, "too many results to resume");
            return -1;
        }
        lua_xmove(co, L, nres);
        return nres;
    }
    lua_xmove(co, L, 1);
    return -1;
}

static int co_resume(lua_State *L)
{
    lua_State *co = lua_tothread(L, 1);
    luaL_argexpected(L, co, 1, "coroutine");
    int r = aux_resume(L, co, lua_gettop(L) - 1);
    if (r < 0) {
        lua_pushboolean(L, 0);
        lua_insert(L, -2);
        return 2;
    }
    lua_pushboolean(L, 1);
    lua_insert(L, -(r + 1));
    return r + 1;
}

#if LUA_VERSION_RELEASE_NUM >= 50406
#define reset_coroutine(co, L) lua_closethread(co, L)
#else
#define reset_coroutine(co, L) ((void)(L), lua_resetthread(co))
#endif

/* A function made by coroutine.wrap (upvalue 1 the coroutine); errors as in lcorolib.c. */
static int co_wrapped(lua_State *L)
{
    lua_State *co = lua_tothread(L, lua_upvalueindex(1));
    int r = aux_resume(L, co, lua_gettop(L));
    if (r >= 0)
        return r;
    int stat = lua_status(co);
    if (stat != LUA_OK && stat != LUA_YIELD) {
        pass_budget_on(L, co);                 /* pending __close variables run Lua code */
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

static int co_wrap(lua_State *L)
{
    luaL_checktype(L, 1, LUA_TFUNCTION);
    lua_State *co = lua_newthread(L);
    lua_pushvalue(L, 1);
    lua_xmove(L, co, 1);
    lua_pushcclosure(L, co_wrapped, 1);
    return 1;
}

enum { COS_RUN, COS_DEAD, COS_YIELD, COS_NORM };

static int co_status(lua_State *L, lua_State *co)
{
    if (L == co)
        return COS_RUN;
    switch (lua_status(co)) {
    case LUA_YIELD:
        return COS_YIELD;
    case LUA_OK: {
        lua_Debug ar;
        if (lua_getstack(co, 0, &ar))
            return COS_NORM;
        return lua_gettop(co) == 0 ? COS_DEAD : COS_YIELD;
    }
    default:
        return COS_DEAD;
    }
}

static int co_close(lua_State *L)
{
    static const char *const names[] = {"running", "dead", "suspended", "normal"};
    lua_State *co = lua_tothread(L, 1);
    luaL_argexpected(L, co, 1, "coroutine");
    int status = co_status(L, co);
    if (status != COS_DEAD && status != COS_YIELD)
        return luaL_error(L, "cannot close a %s coroutine", names[status]);
    pass_budget_on(L, co);
    if (reset_coroutine(co, L) == LUA_OK) {
        lua_pushboolean(L, 1);
        return 1;
    }
    lua_pushboolean(L, 0);
    lua_xmove(co, L, 1);
    return 2;
}

/* 1 while a budget runs whose instructions are spent. */
static int budget_spent(lua_State *L)
{
    state_ctx *c = ctx_of(L);
    return c && c->budget && c->budget->spent;
}

/* A message handler given to xpcall (upvalue 1). Once the budget is spent it is not called:
 * the budget error is raised from inside the count hook, where Lua runs a message handler with
 * hooks off, so a handler that loops would never be stopped. */
static int budget_message_handler(lua_State *L)
{
    if (budget_spent(L))
        return 1;
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_insert(L, 1);
    lua_call(L, lua_gettop(L) - 1, 1);
    return 1;
}

/* lbaselib.c's finishpcall and xpcall, with the handler behind budget_message_handler. */
static int finish_pcall(lua_State *L, int status, lua_KContext extra)
{
    if (status != LUA_OK && status != LUA_YIELD) {
        lua_pushboolean(L, 0);
        lua_pushvalue(L, -2);
        return 2;
    }
    return lua_gettop(L) - (int)extra;
}

static int budget_xpcall(lua_State *L)
{
    int n = lua_gettop(L);
    luaL_checktype(L, 2, LUA_TFUNCTION);
    lua_pushvalue(L, 2);
    lua_pushcclosure(L, budget_message_handler, 1);
    lua_replace(L, 2);
    lua_pushboolean(L, 1);
    lua_pushvalue(L, 1);
    lua_rotate(L, 3, 2);
    int status = lua_pcallk(L, n - 2, LUA_MULTRET, 2, 2, finish_pcall);
    return finish_pcall(L, status, 2);
}

/* ---- finalizers -------------------------------------------------------------------------- */

#define GC_KEY "cdvr.finalizers" /* registry: weak-keyed, metatable -> its real __gc */

static int gc_runner(lua_State *L);

static void push_finalizers(lua_State *L)
{
    if (lua_getfield(L, LUA_REGISTRYINDEX, GC_KEY) == LUA_TTABLE)
        return;
    lua_pop(L, 1);
    lua_newtable(L);
    lua_createtable(L, 0, 1);
    lua_pushliteral(L, "k");
    lua_setfield(L, -2, "__mode");
    lua_setmetatable(L, -2);
    lua_pushvalue(L, -1);
    lua_setfield(L, LUA_REGISTRYINDEX, GC_KEY);
}

/* Puts gc_runner in the __gc of the metatable at idx, the real finalizer aside. */
static void guard_gc(lua_State *L, int idx)
{
    idx = lua_absindex(L, idx);
    lua_pushliteral(L, "__gc");
    int t = lua_rawget(L, idx);                    /* gc */
    if (t == LUA_TNIL || lua_tocfunction(L, -1) == gc_runner) {
        lua_pop(L, 1);
        return;
    }
    push_finalizers(L);                            /* gc, fins */
    lua_pushvalue(L, idx);
    lua_pushvalue(L, -3);
    lua_rawset(L, -3);                             /* fins[mt] = gc */
    lua_pop(L, 2);
    lua_pushliteral(L, "__gc");
    lua_pushcfunction(L, gc_runner);
    lua_rawset(L, idx);
}

/* Guards again every metatable whose __gc the script replaced since (mt.__gc = f). */
static void guard_all_finalizers(lua_State *L)
{
    if (lua_getfield(L, LUA_REGISTRYINDEX, GC_KEY) != LUA_TTABLE) {
        lua_pop(L, 1);
        return;
    }
    int fins = lua_gettop(L);
    lua_pushnil(L);
    while (lua_next(L, fins)) {                    /* mt, gc */
        lua_pop(L, 1);
        lua_pushliteral(L, "__gc");
        int t = lua_rawget(L, -2);                 /* mt, current */
        if (t != LUA_TNIL && lua_tocfunction(L, -1) != gc_runner) {
            lua_pushvalue(L, -2);
            lua_insert(L, -2);                     /* mt, mt, current */
            lua_rawset(L, fins);                   /* an existing key: allowed while traversing */
            lua_pushliteral(L, "__gc");
            lua_pushcfunction(L, gc_runner);
            lua_rawset(L, -3);
        } else {
            lua_pop(L, 1);
        }
    }
    lua_pop(L, 1);
}

/* The __gc of every guarded metatable: the real finalizer in a new coroutine, under the
 * running budget, or one of its own (the default limits) outside callbacks. */
static int gc_runner(lua_State *L)
{
    state_ctx *c = ctx_of(L);
    if (!lua_getmetatable(L, 1))
        return 0;
    push_finalizers(L);
    lua_pushvalue(L, -2);
    if (lua_rawget(L, -2) == LUA_TNIL || !c)       /* mt, fins, gc */
        return 0;
    callback_budget *outer = c->budget;
    if (outer && outer->spent)
        return 0;                                  /* the callback is failing already */
    if (outer && outer->chunk)
        outer = NULL;      /* run while a data file loads: not the file's, a budget of its own */
    lua_State *co = lua_newthread(L);              /* mt, fins, gc, co */
    lua_pushvalue(L, -2);
    lua_pushvalue(L, 1);
    lua_xmove(L, co, 2);
    callback_budget own;
    if (outer) {
        lua_sethook(co, budget_hook, LUA_MASKCOUNT, budget_slice(outer));
    } else {
        lcdvr_limits lim = {LCDVR_CALLBACK_LIMIT, (size_t)LCDVR_CALLBACK_MEMORY_MB << 20};
        budget_begin(c, &own, co, &lim);
        own.detached = 1;
        lua_sethook(co, budget_hook, LUA_MASKCOUNT, budget_slice(&own));
    }
    int nres = 0;
    int status = lua_resume(co, L, 1, &nres);
    if (!outer)
        budget_end(c, &own);
    if (status == LUA_OK || status == LUA_YIELD)
        return 0;
    const char *msg = lua_tostring(co, -1);
    if (!outer && (own.spent || own.mem_refused)) {
        c->gc_failures++;
        if (own.spent)
            fprintf(stderr, "cdvr: __gc metamethod stopped: callback exceeded its instruction "
                    "budget (callback_limit = %lld instructions)\n", (long long)own.limit);
        else
            fprintf(stderr, "cdvr: __gc metamethod stopped: callback exceeded its memory "
                    "budget (callback_memory = %d MB)\n", memory_mb(&own));
        fflush(stderr);
        return 0;
    }
    lua_warning(L, "error in __gc metamethod (", 1); /* what Lua itself does (luaE_warnerror) */
    lua_warning(L, msg ? msg : "error object is not a string", 1);
    lua_warning(L, ")", 0);
    return 0;
}

/* setmetatable as lbaselib.c's, guarding the metatable's __gc. */
static int guarded_setmetatable(lua_State *L)
{
    int t = lua_type(L, 2);
    luaL_checktype(L, 1, LUA_TTABLE);
    luaL_argexpected(L, t == LUA_TNIL || t == LUA_TTABLE, 2, "nil or table");
    if (luaL_getmetafield(L, 1, "__metatable") != LUA_TNIL)
        return luaL_error(L, "cannot change a protected metatable");
    if (t == LUA_TTABLE)
        guard_gc(L, 2);
    lua_settop(L, 2);
    lua_setmetatable(L, 1);
    return 1;
}

/* ---- debug, string.rep, table.move ------------------------------------------------------ */

/* Every debug.* function (upvalue 1 Lua's, upvalue 2 its name): inside a budget only
 * traceback and getinfo run; the upvalues of C functions are never handed out. */
static int debug_guard(lua_State *L)
{
    const char *name = lua_tostring(L, lua_upvalueindex(2));
    state_ctx *c = ctx_of(L);
    if (c && c->budget && strcmp(name, "traceback") != 0 && strcmp(name, "getinfo") != 0)
        return luaL_error(L, "debug.%s is not available in a callback (it could lift the "
                          "callback's budget)", name);
    if ((strcmp(name, "getupvalue") == 0 || strcmp(name, "setupvalue") == 0) &&
        lua_iscfunction(L, 1))
        return luaL_error(L, "debug.%s: the upvalues of C functions are not available in cdvr",
                          name);
    if (strcmp(name, "setmetatable") == 0 && lua_istable(L, 2))
        guard_gc(L, 2);
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_insert(L, 1);
    lua_call(L, lua_gettop(L) - 1, LUA_MULTRET);
    return lua_gettop(L);
}

#define MAXSIZE ((size_t)INT_MAX) /* lstrlib.c's limit on the strings it builds */

/* string.rep as lstrlib.c's, but an empty result is made at once (Lua's loops n times to copy
 * nothing: string.rep("", 1e15) never ends) and the copy is charged to the budget. */
static int guarded_rep(lua_State *L)
{
    size_t l, lsep;
    const char *s = luaL_checklstring(L, 1, &l);
    lua_Integer n = luaL_checkinteger(L, 2);
    const char *sep = luaL_optlstring(L, 3, "", &lsep);
    if (n <= 0 || (l == 0 && lsep == 0)) {
        lua_pushliteral(L, "");
        return 1;
    }
    if (l + lsep < l || l + lsep > MAXSIZE / (size_t)n)
        return luaL_error(L, "resulting string too large");
    size_t total = (size_t)n * l + (size_t)(n - 1) * lsep;
    luaL_Buffer b;
    char *p = luaL_buffinitsize(L, &b, total); /* the memory budget first */
    lcdvr_budget_charge(L, (lua_Integer)(total / 64));
    while (n-- > 1) {
        memcpy(p, s, l);
        p += l;
        if (lsep > 0) {
            memcpy(p, sep, lsep);
            p += lsep;
        }
    }
    memcpy(p, s, l);
    luaL_pushresultsize(&b, total);
    return 1;
}

static int check_field(lua_State *L, const char *key, int n)
{
    lua_pushstring(L, key);
    return lua_rawget(L, -n) != LUA_TNIL;
}

/* ltablib.c's checktab. */
static void check_tab(lua_State *L, int arg, int write)
{
    if (lua_type(L, arg) == LUA_TTABLE)
        return;
    int n = 1;
    if (lua_getmetatable(L, arg) && (write || check_field(L, "__index", ++n)) &&
        (!write || check_field(L, "__newindex", ++n)))
        lua_pop(L, n);
    else
        luaL_checktype(L, arg, LUA_TTABLE);
}

/* table.move as ltablib.c's, charging each element to the budget (table.move({}, 1, 1e15, 1)
 * loops in C). */
static int guarded_move(lua_State *L)
{
    lua_Integer f = luaL_checkinteger(L, 2);
    lua_Integer e = luaL_checkinteger(L, 3);
    lua_Integer t = luaL_checkinteger(L, 4);
    int tt = !lua_isnoneornil(L, 5) ? 5 : 1;
    check_tab(L, 1, 0);
    check_tab(L, tt, 1);
    if (e >= f) {
        luaL_argcheck(L, f > 0 || e < LUA_MAXINTEGER + f, 3, "too many elements to move");
        lua_Integer n = e - f + 1;
        luaL_argcheck(L, t <= LUA_MAXINTEGER - n + 1, 4, "destination wrap around");
        int forward = t > e || t <= f || (tt != 1 && !lua_compare(L, 1, tt, LUA_OPEQ));
        for (lua_Integer k = 0; k < n; k++) {
            lua_Integer i = forward ? k : n - 1 - k;
            if ((k & 1023) == 1023)
                lcdvr_budget_charge(L, 1024);
            lua_geti(L, 1, f + i);
            lua_seti(L, tt, t + i);
        }
    }
    lua_pushvalue(L, tt);
    return 1;
}

static void set_field_function(lua_State *L, const char *table, const char *name, lua_CFunction f)
{
    if (lua_getglobal(L, table) == LUA_TTABLE) {
        lua_pushcfunction(L, f);
        lua_setfield(L, -2, name);
    }
    lua_pop(L, 1);
}

void lcdvr_open_budget(lua_State *L)
{
    state_ctx *c = ctx_of(L);
    if (!c || c->opened)
        return;
    c->opened = 1;
    lua_pushcfunction(L, budget_xpcall);
    lua_setglobal(L, "xpcall");
    lua_pushcfunction(L, guarded_setmetatable);
    lua_setglobal(L, "setmetatable");
    set_field_function(L, "coroutine", "resume", co_resume);
    set_field_function(L, "coroutine", "wrap", co_wrap);
    set_field_function(L, "coroutine", "close", co_close);
    set_field_function(L, "string", "rep", guarded_rep);
    set_field_function(L, "table", "move", guarded_move);
    lcdvr_open_strmatch(L);
    if (lua_getglobal(L, "debug") == LUA_TTABLE) {  /* debug */
        int dbg = lua_gettop(L);
        lua_pushnil(L);
        while (lua_next(L, dbg)) {                  /* debug, name, f */
            if (lua_type(L, -2) == LUA_TSTRING && lua_isfunction(L, -1)) {
                lua_pushvalue(L, -2);               /* debug, name, f, name */
                lua_pushcclosure(L, debug_guard, 2);
                lua_pushvalue(L, -2);
                lua_insert(L, -2);                  /* debug, name, name, guard */
                lua_rawset(L, dbg);                 /* an existing key */
            } else {
                lua_pop(L, 1);
            }
        }
    }
    lua_pop(L, 1);
}

/* ---- data files -------------------------------------------------------------------------- */

int lcdvr_load_data(lua_State *L, const char *path)
{
    struct stat sb;
    if (stat(path, &sb) != 0) {
        lua_pushfstring(L, "cannot open %s: %s", path, strerror(errno));
        return LUA_ERRFILE;
    }
    if (!S_ISREG(sb.st_mode)) {
        lua_pushfstring(L, "%s: not a regular file", path);
        return LUA_ERRFILE;
    }
    lcdvr_limits lim = {DATA_BASE_BUDGET, (size_t)LCDVR_CALLBACK_MEMORY_MB << 20};
    if ((uintmax_t)sb.st_size > lim.memory) {
        lua_pushfstring(L, "%s: data file is %I bytes (at most %d MB)", path,
                        (LUAI_UACINT)sb.st_size, (int)(lim.memory >> 20));
        return LUA_ERRFILE;
    }
    FILE *f = fopen(path, "rb");
    int first = f ? getc(f) : EOF;
    if (f)
        fclose(f);
    if (first == LUA_SIGNATURE[0]) {
        lua_pushfstring(L, "%s: a precompiled (binary) chunk is not a data file (text only)", path);
        return LUA_ERRSYNTAX;
    }
    lim.instructions += DATA_PER_BYTE * (lua_Integer)sb.st_size;
    int status = luaL_loadfilex(L, path, "t");
    if (status != LUA_OK) {
        const char *msg = lua_tostring(L, -1);
        if (msg && strncmp(msg, path, strlen(path)) != 0) {
            lua_pushfstring(L, "%s: %s", path, msg);
            lua_remove(L, -2);
        }
        return status;
    }
    lua_newtable(L);                               /* chunk, env: nothing to reach */
    if (!lua_setupvalue(L, -2, 1))
        lua_pop(L, 1);
    const void *chunk = lua_topointer(L, -1);
    status = run_budgeted(L, 0, 1, &lim, chunk);
    if (status != LUA_OK) {
        const char *msg = lua_tostring(L, -1);
        if (!msg)
            msg = "error object is not a string";
        if (status == LUA_ERRMEM)
            lua_pushfstring(L, "%s: data file exceeded its memory budget (callback_memory = %d MB)",
                            path, (int)(lim.memory >> 20));
        else if (strncmp(msg, path, strlen(path)) != 0)
            lua_pushfstring(L, "%s: %s", path, msg);
        else
            lua_pushfstring(L, "%s (a data file has an empty environment and calls no function)",
                            msg);
        lua_remove(L, -2);
    }
    return status;
}

/* cdvr.load_lua(file) -> value | nil, message */
static int l_load_lua(lua_State *L)
{
    const char *path = luaL_checkstring(L, 1);
    if (lcdvr_load_data(L, path) != LUA_OK) {
        lua_pushfstring(L, "load_lua: %s", lua_tostring(L, -1));
        luaL_pushfail(L);
        lua_insert(L, -2);
        return 2;
    }
    if (lua_isnil(L, -1)) {
        luaL_pushfail(L);
        lua_pushfstring(L, "load_lua: %s returns no value", path);
        return 2;
    }
    return 1;
}

void lcdvr_open_data(lua_State *L)
{
    lua_pushcfunction(L, l_load_lua);
    lua_setfield(L, -2, "load_lua");
}
