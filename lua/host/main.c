/* lua/host/main.c - the cdvr executable: a Lua 5.4 host with the cdvr API.
 *
 *   cdvr SCRIPT.lua [args]   run a script (args in `arg`, like lua)
 *   cdvr -e 'code'           run a string
 *   cdvr -i                  interactive console (line editing and history with readline; a
 *                            window beside it when a display exists; Ctrl-C interrupts a line)
 *   cdvr --help | --version
 * Exit status: 0 success, 1 script or runtime error (message and traceback on stderr),
 * 2 usage error.
 */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#if defined(CDVR_HAVE_READLINE)
#include <readline/history.h>
#include <readline/readline.h>
#endif

#include "cdvr/device.h"
#include "cdvr/dist.h"
#include "cdvr/plugin.h"
#include "lcdvr.h"

/* Sanitizer builds: the leak check runs when main has freed everything and joined its threads,
 * before exit's handlers and the libraries' destructors run. At exit, a driver's threads may be
 * ending (PoCL, Mesa's llvmpipe, FFmpeg) while LeakSanitizer stops the world, and its tracer
 * then crashes ("Tracer caught signal 11", seen in CI); here they are all idle. */
#if defined(__SANITIZE_ADDRESS__)
#define CDVR_LSAN_NOW 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CDVR_LSAN_NOW 1
#endif
#endif
#ifdef CDVR_LSAN_NOW
#include <sanitizer/lsan_interface.h>
#endif

#ifndef CDVR_SHARE_DIR
#define CDVR_SHARE_DIR "share"
#endif

static const char *usage_text =
    "usage: cdvr [options] [script.lua [args...]]\n"
    "  script.lua [args]  run a Lua script; its arguments are in the table `arg`\n"
    "  -e CODE            run CODE (may be repeated; runs before a script)\n"
    "  -i                 interactive console (after -e and script, if any)\n"
    "  -                  read the script from standard input\n"
    "  --help             this text\n"
    "  --version          print the version\n"
    "Environment: CDVR_SHARE (share directory), CDVR_CL_DEVICE (OpenCL device choice),\n"
    "  CDVR_PLUGIN_PATH (colon-separated directories whose *.so codec plugins load at start;\n"
    "  unset: the plugins directory beside the executable; empty: none).\n"
    "  CDVR_HISTORY (console history file, default ~/.cdvr_history).\n"
    "In Lua, cdvr.help() lists every function.\n";

static int is_dir(const char *path)
{
    struct stat sb;
    return stat(path, &sb) == 0 && S_ISDIR(sb.st_mode);
}

/* share/ directory: $CDVR_SHARE, the source tree's share/, or <exe>/../share/cdvr. */
static void find_share_dir(char *out, size_t n)
{
    const char *env = getenv("CDVR_SHARE");
    if (env && *env) {
        snprintf(out, n, "%s", env);
        return;
    }
    if (is_dir(CDVR_SHARE_DIR)) {
        snprintf(out, n, "%s", CDVR_SHARE_DIR);
        return;
    }
    char exe[4096];
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (len > 0) {
        exe[len] = '\0';
        char *slash = strrchr(exe, '/');
        if (slash)
            *slash = '\0';
        snprintf(out, n, "%.3800s/../share/cdvr", exe);
        return;
    }
    snprintf(out, n, "share");
}

static void warn_plugin(void *ud, const char *message)
{
    (void)ud;
    fprintf(stderr, "cdvr: warning: %s\n", message);
}

/* Codec plugins at start-up: every *.so in $CDVR_PLUGIN_PATH, or, when it is unset, in the
 * plugins directory beside the executable (build/plugins). Failures are one warning each. */
static void load_plugins(void)
{
    const char *env = getenv("CDVR_PLUGIN_PATH");
    if (env) {
        cdvr_plugin_load_dirs(env, warn_plugin, NULL);
        return;
    }
    char exe[4096];
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (len <= 0)
        return;
    exe[len] = '\0';
    char *slash = strrchr(exe, '/');
    if (!slash)
        return;
    snprintf(slash, sizeof exe - (size_t)(slash - exe), "/plugins");
    if (is_dir(exe))
        cdvr_plugin_load_dirs(exe, warn_plugin, NULL);
}

static int l_help(lua_State *L)
{
    const char *only = luaL_optstring(L, 1, NULL);
    lua_getfield(L, LUA_REGISTRYINDEX, "cdvr.help"); /* help */
    lua_newtable(L);                                 /* help, names */
    int n = 0;
    lua_pushnil(L);
    while (lua_next(L, -3)) {                        /* help, names, key, value */
        lua_pop(L, 1);
        lua_pushvalue(L, -1);
        lua_rawseti(L, -3, ++n);                     /* help, names, key */
    }
    lua_getglobal(L, "table");
    lua_getfield(L, -1, "sort");                     /* help, names, table, sort */
    lua_pushvalue(L, -3);
    lua_call(L, 1, 0);
    lua_pop(L, 1);                                   /* help, names */
    for (int i = 1; i <= n; i++) {
        lua_rawgeti(L, -1, i);                       /* help, names, name */
        const char *name = lua_tostring(L, -1);
        if (!only || strstr(name, only)) {
            lua_getfield(L, -3, name);               /* help, names, name, description */
            printf("%-44s %s\n", name, lua_tostring(L, -1));
            lua_pop(L, 1);
        }
        lua_pop(L, 1);
    }
    lua_pop(L, 2);
    return 0;
}

/* cdvr.help_add(name, description): lets Lua modules (share/lua/cdvr) document themselves. */
static int l_help_add(lua_State *L)
{
    lcdvr_help_add(L, luaL_checkstring(L, 1), luaL_checkstring(L, 2));
    return 0;
}

/* The error object as text (its __tostring, else "(error object is a table value)"), with
 * the traceback. */
static int msghandler(lua_State *L)
{
    const char *msg = lua_tostring(L, 1);
    if (msg == NULL) {
        if (luaL_getmetafield(L, 1, "__tostring") != LUA_TNIL) {
            lua_pop(L, 1);
            msg = luaL_tolstring(L, 1, NULL); /* raises if __tostring returns no string */
        } else {
            msg = lua_pushfstring(L, "(error object is a %s value)", luaL_typename(L, 1));
        }
    }
    luaL_traceback(L, L, msg, 1);
    return 1;
}

static int docall(lua_State *L, int narg, int nres)
{
    int base = lua_gettop(L) - narg;
    lua_pushcfunction(L, msghandler);
    lua_insert(L, base);
    int status = lua_pcall(L, narg, nres, base);
    lua_remove(L, base);
    return status;
}

static int report(lua_State *L, int status)
{
    if (status != LUA_OK) {
        const char *msg = lua_tostring(L, -1);
        if (cdvr_dist_size() > 1) /* mpirun: say which rank failed */
            fprintf(stderr, "cdvr: rank %d of %d: %s\n", cdvr_dist_rank(), cdvr_dist_size(),
                    msg ? msg : "(error)");
        else
            fprintf(stderr, "cdvr: %s\n", msg ? msg : "(error)");
        fflush(stderr);
        lua_pop(L, 1);
    }
    return status;
}

/* Opens the API: global table cdvr, package.loaded.cdvr, package.path for share/lua. */
static int open_cdvr(lua_State *L)
{
    char share[4096];
    find_share_dir(share, sizeof share);

    lua_getglobal(L, "package");                  /* package */
    lua_getfield(L, -1, "path");                  /* package, path */
    lua_pushfstring(L, "%s/lua/?.lua;%s/lua/?/init.lua;%s", share, share, lua_tostring(L, -1));
    lua_setfield(L, -3, "path");
    lua_pop(L, 2);

    lua_newtable(L);                              /* cdvr */
    lua_pushstring(L, CDVR_VERSION);
    lua_setfield(L, -2, "version");
    lua_pushstring(L, share);
    lua_setfield(L, -2, "share_dir");
    lua_pushcfunction(L, l_help);
    lua_setfield(L, -2, "help");
    lua_pushcfunction(L, l_help_add);
    lua_setfield(L, -2, "help_add");
    lcdvr_help_add(L, "cdvr.help([filter])", "list every function with a one-line description");
    lcdvr_open_data(L);
    lcdvr_open_volume(L);
    lcdvr_open_image(L);
    lcdvr_open_tf(L);
    lcdvr_open_camera(L);
    lcdvr_open_render(L);
    lcdvr_open_method(L);
    lcdvr_open_compare(L);
    lcdvr_open_store(L);
    lcdvr_open_device(L);
    lcdvr_open_player(L);
    lcdvr_open_splat(L);
    lcdvr_open_codec(L);
    lcdvr_open_gl(L);
    lcdvr_open_window(L);
    lcdvr_open_mpi(L);
    lcdvr_open_movie(L);

    lua_pushvalue(L, -1);
    lua_setglobal(L, "cdvr");
    luaL_getsubtable(L, LUA_REGISTRYINDEX, LUA_LOADED_TABLE); /* cdvr, loaded */
    lua_pushvalue(L, -2);
    lua_setfield(L, -2, "cdvr");
    lua_pop(L, 2);

    /* Policy and convenience written in Lua: share/lua/cdvr/prelude.lua extends the table. */
    lua_getglobal(L, "require");
    lua_pushstring(L, "cdvr.prelude");
    return docall(L, 1, 0);
}

static void create_arg_table(lua_State *L, char **argv, int argc, int script)
{
    lua_createtable(L, argc - script, script + 1);
    for (int i = 0; i < argc; i++) {
        lua_pushstring(L, argv[i]);
        lua_rawseti(L, -2, i - script);
    }
    lua_setglobal(L, "arg");
}

static int run_script(lua_State *L, const char *path, char **argv, int argc, int script)
{
    int status = luaL_loadfile(L, path);
    if (status != LUA_OK)
        return report(L, status);
    int nargs = argc - script - 1;
    luaL_checkstack(L, nargs + 3, "too many arguments");
    for (int i = script + 1; i < argc; i++)
        lua_pushstring(L, argv[i]);
    return report(L, docall(L, nargs, 0));
}

/* ---- console ------------------------------------------------------------------------- */
/* The console runs each line as `lua -i` does (an expression prints its values, an incomplete
 * chunk reads continuation lines). On a terminal it reads through readline's callback
 * interface, so that open windows (cdvr.window, l_window.c) keep being driven between
 * keystrokes, and they redraw after every line that ran; Lua runs on this thread only.
 * Ctrl-C interrupts the running line (a Lua loop through a hook, a render or playback through
 * the core's cancel flag) and returns to the prompt with "interrupted!"; at the prompt it
 * clears the line. History (readline) is appended to the history file after every line, so a
 * session that ends with os.exit() keeps it. */

/* What the SIGINT handler sees: a handler gets no context, so this is the console's one piece
 * of process-wide state. `running` is set while Lua runs for the console (a line, a window
 * frame); the flag is what the core polls (lcdvr_interrupt_flag). */
static struct {
    lua_State *L;
    volatile sig_atomic_t running;
    atomic_int interrupted;
    struct session *reading;   /* the session whose readline callback is installed */
} console_signal;

typedef struct session {
    lua_State *L;
    int tty;                   /* stdin is a terminal: prompts */
    int use_readline;          /* readline's callback interface */
    char history[4096];        /* history file, "" for none */
    int changed;               /* a line ran since the windows last drew */
    int cancelled;             /* read_line stopped by Ctrl-C at the prompt */
    char *line;                /* readline's callback result */
    int line_done;
    char *buf;                 /* plain input: bytes read, not yet split into lines */
    size_t len, cap;
    int eof;
} session;

static void interrupt_hook(lua_State *L, lua_Debug *ar)
{
    (void)ar;
    lua_sethook(L, NULL, 0, 0);
    luaL_error(L, "interrupted!");
}

static void on_sigint(int sig)
{
    (void)sig;
    atomic_store(&console_signal.interrupted, 1);
    if (console_signal.running) /* lua_sethook is safe in a signal handler (see lua.c) */
        lua_sethook(console_signal.L, interrupt_hook,
                    LUA_MASKCALL | LUA_MASKRET | LUA_MASKCOUNT, 1);
}

/* docall (the function below its narg arguments), with Ctrl-C armed: the hook and the core's
 * cancel flag stop it with "interrupted!". */
static int console_call(lua_State *L, int narg, int nres)
{
    console_signal.running = 1;
    int status = docall(L, narg, nres);
    console_signal.running = 0;
    lua_sethook(L, NULL, 0, 0);
    return status;
}

/* Drives the open windows once; returns how long to wait for input (ms, -1: no window). */
static int drive_windows(session *c)
{
    int printed = 0;
    console_signal.running = 1;
    int wait = lcdvr_window_tick(c->L, c->changed, &printed);
    console_signal.running = 0;
    lua_sethook(c->L, NULL, 0, 0);
    c->changed = 0;
#if defined(CDVR_HAVE_READLINE)
    if (printed && c->use_readline && console_signal.reading) {
        rl_on_new_line();
        rl_redisplay();
    }
#endif
    return wait;
}

/* Waits until stdin is readable (1), the timeout passes (0) or a signal arrives (-1). */
static int wait_input(int timeout_ms)
{
    struct pollfd pfd = {STDIN_FILENO, POLLIN, 0};
    int r = poll(&pfd, 1, timeout_ms);
    return r > 0 ? 1 : r == 0 ? 0 : -1;
}

static void remember(session *c, const char *line)
{
#if defined(CDVR_HAVE_READLINE)
    if (!c->use_readline || !*line)
        return;
    add_history(line);
    if (c->history[0] && append_history(1, c->history) != 0) {
        fprintf(stderr, "cdvr: cannot append to the history file %s\n", c->history);
        c->history[0] = '\0';
    }
#else
    (void)c;
    (void)line;
#endif
}

#if defined(CDVR_HAVE_READLINE)
static void on_readline(char *line)
{
    session *c = console_signal.reading;
    c->line = line;
    c->line_done = 1;
    rl_callback_handler_remove();
    console_signal.reading = NULL;
}

static char *read_line_readline(session *c, const char *prompt)
{
    c->line = NULL;
    c->line_done = 0;
    console_signal.reading = c;
    rl_callback_handler_install(prompt, on_readline);
    while (!c->line_done) {
        int ready = wait_input(drive_windows(c));
        if (atomic_exchange(&console_signal.interrupted, 0)) { /* Ctrl-C at the prompt */
            rl_replace_line("", 0);
            rl_callback_handler_remove();
            console_signal.reading = NULL;
            fputc('\n', stdout);
            c->cancelled = 1;
            return NULL;
        }
        if (ready > 0)
            rl_callback_read_char();
    }
    return c->line;
}
#endif

/* Splits the next line off the plain input buffer, or NULL if none is complete. */
static char *take_line(session *c, int at_eof)
{
    if (c->len == 0)
        return NULL;
    char *nl = memchr(c->buf, '\n', c->len);
    if (!nl && !at_eof)
        return NULL;
    size_t n = nl ? (size_t)(nl - c->buf) : c->len;
    char *line = malloc(n + 1);
    if (!line)
        return NULL;
    memcpy(line, c->buf, n);
    line[n] = '\0';
    size_t used = nl ? n + 1 : n;
    memmove(c->buf, c->buf + used, c->len - used);
    c->len -= used;
    return line;
}

static char *read_line_plain(session *c, const char *prompt)
{
    if (c->tty) { /* piped input: no prompts, so output stays plain */
        fputs(prompt, stdout);
        fflush(stdout);
    }
    for (;;) {
        char *line = take_line(c, c->eof);
        if (line || c->eof)
            return line;
        int ready = wait_input(drive_windows(c));
        if (atomic_exchange(&console_signal.interrupted, 0)) {
            if (c->tty)
                fputc('\n', stdout);
            c->len = 0;
            c->cancelled = 1;
            return NULL;
        }
        if (ready <= 0)
            continue;
        if (c->len + 4096 > c->cap) {
            char *grown = realloc(c->buf, c->cap + 65536);
            if (!grown)
                return NULL;
            c->buf = grown;
            c->cap += 65536;
        }
        ssize_t n = read(STDIN_FILENO, c->buf + c->len, c->cap - c->len);
        if (n > 0)
            c->len += (size_t)n;
        else if (n == 0 || errno != EINTR)
            c->eof = 1;
    }
}

/* The next line without its newline (malloc'd), or NULL at the end of input or after Ctrl-C
 * (c->cancelled). Non-empty lines go to the history. */
static char *read_line(session *c, const char *prompt)
{
    c->cancelled = 0;
    char *line;
#if defined(CDVR_HAVE_READLINE)
    if (c->use_readline)
        line = read_line_readline(c, prompt);
    else
#endif
        line = read_line_plain(c, prompt);
    if (line)
        remember(c, line);
    return line;
}

static int incomplete(lua_State *L, int status)
{
    if (status == LUA_ERRSYNTAX) {
        size_t lmsg;
        const char *msg = lua_tolstring(L, -1, &lmsg);
        const char *eof = "<eof>";
        size_t leof = strlen(eof);
        if (lmsg >= leof && strcmp(msg + lmsg - leof, eof) == 0) {
            lua_pop(L, 1);
            return 1;
        }
    }
    return 0;
}

/* Compiles the console input: first as "return <line>" (so expressions print), else as a
 * statement, reading continuation lines while the chunk is incomplete. Returns -1 when Ctrl-C
 * abandoned the chunk (nothing pushed). */
static int load_console_chunk(session *c, char *first)
{
    lua_State *L = c->L;
    lua_pushfstring(L, "return %s", first);
    const char *ret = lua_tostring(L, -1);
    if (luaL_loadbuffer(L, ret, strlen(ret), "=stdin") == LUA_OK) {
        lua_remove(L, -2);
        return LUA_OK;
    }
    lua_pop(L, 2);
    lua_pushstring(L, first);                     /* code */
    for (;;) {
        size_t len;
        const char *code = lua_tolstring(L, -1, &len);
        int status = luaL_loadbuffer(L, code, len, "=stdin");
        if (!incomplete(L, status)) {
            lua_remove(L, -2);                    /* chunk or message */
            return status;
        }
        char *more = read_line(c, ">> ");
        if (!more) {
            lua_pop(L, 1);
            if (c->cancelled)
                return -1;
            lua_pushstring(L, "incomplete input at end of file");
            return LUA_ERRSYNTAX;
        }
        lua_pushliteral(L, "\n");
        lua_pushstring(L, more);
        lua_concat(L, 3);                         /* code .. "\n" .. more */
        free(more);
    }
}

static void print_results(lua_State *L)
{
    int n = lua_gettop(L);
    if (n == 0)
        return;
    luaL_checkstack(L, LUA_MINSTACK, "too many results to print");
    lua_getglobal(L, "print");
    lua_insert(L, 1);
    if (console_call(L, n, 0) != LUA_OK)
        report(L, LUA_ERRRUN);
}

static void open_history(session *c)
{
#if defined(CDVR_HAVE_READLINE)
    const char *path = getenv("CDVR_HISTORY"), *home = getenv("HOME");
    if (path && *path)
        snprintf(c->history, sizeof c->history, "%s", path);
    else if (home && *home)
        snprintf(c->history, sizeof c->history, "%s/.cdvr_history", home);
    if (!c->history[0])
        return;
    if (read_history(c->history) != 0 && write_history(c->history) != 0) {
        fprintf(stderr, "cdvr: cannot create the history file %s: history not kept\n", c->history);
        c->history[0] = '\0';
    }
#else
    (void)c;
#endif
}

static void console_run(session *c)
{
    lua_State *L = c->L;
    for (;;) {
        char *line = read_line(c, "> ");
        if (!line) {
            if (c->cancelled)
                continue;
            break;
        }
        lua_settop(L, 0);
        int status = load_console_chunk(c, line);
        free(line);
        if (status < 0)
            continue;
        if (status == LUA_OK)
            status = console_call(L, 0, LUA_MULTRET);
        if (status == LUA_OK)
            print_results(L);
        else
            report(L, status);
        atomic_store(&console_signal.interrupted, 0);
        c->changed = 1;
    }
}

static void console(lua_State *L)
{
    session c;
    memset(&c, 0, sizeof c);
    c.L = L;
    c.tty = isatty(STDIN_FILENO);
#if defined(CDVR_HAVE_READLINE)
    c.use_readline = c.tty;
    rl_catch_signals = 0; /* Ctrl-C is the console's (on_sigint) */
#endif
    if (c.use_readline)
        open_history(&c);
    console_signal.L = L;
    atomic_init(&console_signal.interrupted, 0);
    lcdvr_set_interrupt_flag(L, &console_signal.interrupted);
    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_sigint;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old); /* no SA_RESTART: a wait for input returns on Ctrl-C */
    if (c.tty)
        printf("cdvr %s (%s) - cdvr.help() lists the API, Ctrl-C interrupts, Ctrl-D quits\n",
               CDVR_VERSION, LUA_RELEASE);
    lcdvr_window_console(L);
    console_run(&c);
    lua_settop(L, 0);
    if (c.tty)
        putchar('\n');
    sigaction(SIGINT, &old, NULL);
    lcdvr_set_interrupt_flag(L, NULL);
    free(c.buf);
}

int main(int argc, char **argv)
{
    int interactive = 0, script = 0;
    int i;
    for (i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            fputs(usage_text, stdout);
            return 0;
        } else if (strcmp(a, "--version") == 0 || strcmp(a, "-v") == 0) {
            printf("cdvr %s (%s)\n", CDVR_VERSION, LUA_RELEASE);
            return 0;
        } else if (strcmp(a, "-i") == 0) {
            interactive = 1;
        } else if (strcmp(a, "-e") == 0) {
            if (++i >= argc) {
                fprintf(stderr, "cdvr: '-e' needs an argument\n%s", usage_text);
                return 2;
            }
        } else if (strcmp(a, "-") == 0 || a[0] != '-') {
            script = i;
            break;
        } else if (strcmp(a, "--") == 0) {
            if (i + 1 < argc)
                script = i + 1;
            break;
        } else {
            fprintf(stderr, "cdvr: unrecognized option '%s'\n%s", a, usage_text);
            return 2;
        }
    }
    int has_e = 0;
    for (int k = 1; k < (script ? script : argc); k++)
        if (strcmp(argv[k], "-e") == 0)
            has_e = 1;
    if (!script && !has_e && !interactive) {
        if (isatty(STDIN_FILENO)) {
            interactive = 1;
        } else {
            fputs(usage_text, stderr);
            return 2;
        }
    }

#if CDVR_HAVE_OPENCL
    /* before plugins and MPI start threads, and before any OpenCL call */
    cdvr_cl_default_affinity();
#endif
    load_plugins();
    cdvr_error derr;
    if (cdvr_dist_init(&argc, &argv, &derr) != CDVR_OK) {
        fprintf(stderr, "cdvr: %s\n", derr.msg);
        return 1;
    }
    lua_State *L = lcdvr_newstate(); /* its allocator bounds what callbacks allocate */
    if (!L) {
        fprintf(stderr, "cdvr: cannot create Lua state: not enough memory\n");
        return 1;
    }
    luaL_openlibs(L);
    lcdvr_open_budget(L); /* before any Lua code: budgeted coroutines, guarded __gc, debug */
    int status = report(L, open_cdvr(L));
    create_arg_table(L, argv, argc, script ? script : argc - 1);
    for (int k = 1; status == LUA_OK && k < (script ? script : argc); k++) {
        if (strcmp(argv[k], "-e") == 0) {
            const char *code = argv[++k];
            status = luaL_loadbuffer(L, code, strlen(code), "=(command line)");
            status = report(L, status == LUA_OK ? docall(L, 0, 0) : status);
        }
    }
    if (status == LUA_OK && script)
        status = run_script(L, strcmp(argv[script], "-") == 0 ? NULL : argv[script], argv, argc, script);
    if (status == LUA_OK && interactive)
        console(L);
    if (status != LUA_OK)
        cdvr_dist_abort(1); /* mpirun: end every rank, none waits for this one */
    if (lcdvr_close(L) > 0) /* a __gc stopped by its budget (printed) */
        status = LUA_ERRRUN;
    cdvr_dist_finalize();
#ifdef CDVR_LSAN_NOW
    __lsan_do_leak_check(); /* see the top of this file; later checks are no-ops */
#endif
    return status == LUA_OK ? 0 : 1;
}
