/* lua/host/main.c - the cdvr executable: a Lua 5.4 host with the cdvr API.
 *
 *   cdvr SCRIPT.lua [args]   run a script (args in `arg`, like lua)
 *   cdvr -e 'code'           run a string
 *   cdvr -i                  interactive console (line editing and history with readline)
 *   cdvr --help | --version
 * Exit status: 0 success, 1 script or runtime error (message and traceback on stderr),
 * 2 usage error.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#if defined(CDVR_HAVE_READLINE)
#include <readline/history.h>
#include <readline/readline.h>
#endif

#include "cdvr/plugin.h"
#include "lcdvr.h"

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

static int msghandler(lua_State *L)
{
    const char *msg = lua_tostring(L, 1);
    if (msg == NULL) {
        if (luaL_callmeta(L, 1, "__tostring") && lua_type(L, -1) == LUA_TSTRING)
            return 1;
        msg = lua_pushfstring(L, "(error object is a %s value)", luaL_typename(L, 1));
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
    lcdvr_open_volume(L);
    lcdvr_open_image(L);
    lcdvr_open_tf(L);
    lcdvr_open_camera(L);
    lcdvr_open_render(L);
    lcdvr_open_compare(L);
    lcdvr_open_store(L);
    lcdvr_open_device(L);
    lcdvr_open_player(L);
    lcdvr_open_splat(L);
    lcdvr_open_codec(L);

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

static char *read_line(const char *prompt)
{
#if defined(CDVR_HAVE_READLINE)
    if (isatty(STDIN_FILENO)) {
        char *line = readline(prompt);
        if (line && *line)
            add_history(line);
        return line;
    }
#endif
    if (isatty(STDIN_FILENO)) { /* piped input: no prompts, so output stays plain */
        fputs(prompt, stdout);
        fflush(stdout);
    }
    size_t cap = 0;
    char *line = NULL;
    ssize_t len = getline(&line, &cap, stdin);
    if (len < 0) {
        free(line);
        return NULL;
    }
    if (len > 0 && line[len - 1] == '\n')
        line[len - 1] = '\0';
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
 * statement, reading continuation lines while the chunk is incomplete. */
static int load_console_chunk(lua_State *L, char *first)
{
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
        char *more = read_line(">> ");
        if (!more) {
            lua_pop(L, 1);
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
    if (lua_pcall(L, n, 0, 0) != LUA_OK)
        report(L, LUA_ERRRUN);
}

static void console(lua_State *L)
{
    char history[4096] = "";
#if defined(CDVR_HAVE_READLINE)
    const char *home = getenv("HOME");
    if (home && isatty(STDIN_FILENO)) {
        snprintf(history, sizeof history, "%s/.cdvr_history", home);
        read_history(history);
    }
#endif
    if (isatty(STDIN_FILENO))
        printf("cdvr %s (%s) - cdvr.help() lists the API, Ctrl-D quits\n", CDVR_VERSION, LUA_RELEASE);
    char *line;
    while ((line = read_line("> ")) != NULL) {
        lua_settop(L, 0);
        int status = load_console_chunk(L, line);
        free(line);
        if (status == LUA_OK)
            status = docall(L, 0, LUA_MULTRET);
        if (status == LUA_OK)
            print_results(L);
        else
            report(L, status);
    }
    lua_settop(L, 0);
    if (isatty(STDIN_FILENO))
        putchar('\n');
#if defined(CDVR_HAVE_READLINE)
    if (history[0])
        write_history(history);
#endif
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

    load_plugins();
    lua_State *L = luaL_newstate();
    if (!L) {
        fprintf(stderr, "cdvr: cannot create Lua state: not enough memory\n");
        return 1;
    }
    luaL_openlibs(L);
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
    lua_close(L);
    return status == LUA_OK ? 0 : 1;
}
