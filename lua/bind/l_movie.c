/* lua/bind/l_movie.c - cdvr.movie{path=, fps=, codec=, crf=, preset=, width=, height=}: a movie
 * written frame by frame from a script's own loop (cdvr/movie.h).
 *
 *   local m <close> = cdvr.movie{path = "orbit.mp4", fps = 30}
 *   for i = 1, 90 do m:add(cdvr.render{...}) end
 *   -- leaving the scope commits the movie; leaving it by an error drops it
 *
 * cdvr.Movie follows liolib: the userdata exists (closed) before the core movie is opened;
 * m:close() commits (true, or nil and a message on an I/O failure), m:abort() drops the file;
 * __close commits on a normal exit of its scope and drops on an error; __gc drops a movie that
 * was never closed (an unfinished movie is never left under its name).
 */
#include <string.h>

#include "cdvr/movie.h"
#include "lcdvr.h"

#define LCDVR_MOVIE "cdvr.Movie"

typedef struct lmovie {
    cdvr_movie *m; /* NULL once closed or aborted */
} lmovie;

static lmovie *checkmovie(lua_State *L, int idx)
{
    lmovie *lm = (lmovie *)luaL_checkudata(L, idx, LCDVR_MOVIE);
    if (!lm->m)
        luaL_error(L, "attempt to use a closed movie");
    return lm;
}

/* Raises, except an I/O failure: nil and the message (the savers' rule). */
static int movie_result(lua_State *L, cdvr_status s, const cdvr_error *err)
{
    if (s == CDVR_OK) {
        lua_pushboolean(L, 1);
        return 1;
    }
    if (s == CDVR_ERR_IO)
        return lcdvr_fail(L, err);
    return lcdvr_raise(L, err);
}

static int l_movie(lua_State *L)
{
    static const char *const keys[] = {"path", "fps", "codec", "crf", "preset", "width", "height", "threads", NULL};
    luaL_checktype(L, 1, LUA_TTABLE);
    lcdvr_checkoptions(L, 1, "cdvr.movie", keys);
    const char *path = lcdvr_optstringfield(L, 1, "path", NULL);
    if (!path)
        return luaL_error(L, "cdvr.movie: option 'path' (the movie file: .mp4, .webm, .mkv or .gif) is required");
    cdvr_movie_opts o = cdvr_movie_defaults();
    o.fps = lcdvr_optnumberfield(L, 1, "fps", o.fps);
    o.codec = lcdvr_optstringfield(L, 1, "codec", NULL);
    lua_Integer crf = lcdvr_optintegerfield(L, 1, "crf", -1);
    lua_Integer w = lcdvr_optintegerfield(L, 1, "width", 0), h = lcdvr_optintegerfield(L, 1, "height", 0);
    lua_Integer threads = lcdvr_optintegerfield(L, 1, "threads", o.threads);
    if (crf < -1 || crf > 1000 || w < 0 || w > 65536 || h < 0 || h > 65536 || threads < 1 || threads > 64)
        return luaL_error(L, "cdvr.movie: crf, width, height or threads out of range");
    o.crf = (int)crf, o.width = (int)w, o.height = (int)h, o.threads = (int)threads;
    o.preset = lcdvr_optstringfield(L, 1, "preset", NULL);
    lmovie *lm = (lmovie *)lua_newuserdatauv(L, sizeof *lm, 0); /* userdata first (liolib) */
    lm->m = NULL;
    luaL_setmetatable(L, LCDVR_MOVIE);
    cdvr_error err;
    cdvr_error_clear(&err);
    cdvr_status st = cdvr_movie_open(path, &o, &lm->m, &err);
    if (st == CDVR_ERR_ARG) /* a bad path= or option value: name the option */
        return luaL_error(L, "cdvr.movie: option 'path' or its options: %s", err.msg);
    if (st != CDVR_OK)
        return lcdvr_raise(L, &err);
    return 1;
}

/* m:add(img): one frame, the image's RGB8 (as its PNG). */
static int movie_add(lua_State *L)
{
    lmovie *lm = checkmovie(L, 1);
    cdvr_image *img = lcdvr_checkimage(L, 2);
    cdvr_error err;
    cdvr_error_clear(&err);
    return movie_result(L, cdvr_movie_add_image(lm->m, img, &err), &err);
}

/* m:close(): commits; closing a closed movie does nothing. */
static int movie_close(lua_State *L)
{
    lmovie *lm = (lmovie *)luaL_checkudata(L, 1, LCDVR_MOVIE);
    if (!lm->m) {
        lua_pushboolean(L, 1);
        return 1;
    }
    cdvr_movie *m = lm->m;
    lm->m = NULL;
    cdvr_error err;
    cdvr_error_clear(&err);
    return movie_result(L, cdvr_movie_close(m, &err), &err);
}

static int movie_abort(lua_State *L)
{
    lmovie *lm = (lmovie *)luaL_checkudata(L, 1, LCDVR_MOVIE);
    cdvr_movie_abort(lm->m);
    lm->m = NULL;
    return 0;
}

/* __close(m, e): commits on a normal exit of the scope (raising on failure), drops on an error. */
static int movie_closemeta(lua_State *L)
{
    if (!lua_isnil(L, 2))
        return movie_abort(L);
    lmovie *lm = (lmovie *)luaL_checkudata(L, 1, LCDVR_MOVIE);
    if (!lm->m)
        return 0;
    cdvr_movie *m = lm->m;
    lm->m = NULL;
    cdvr_error err;
    cdvr_error_clear(&err);
    if (cdvr_movie_close(m, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    return 0;
}

static int movie_frames(lua_State *L)
{
    lua_pushinteger(L, (lua_Integer)cdvr_movie_frames(checkmovie(L, 1)->m));
    return 1;
}

static int movie_tostring(lua_State *L)
{
    lmovie *lm = (lmovie *)luaL_checkudata(L, 1, LCDVR_MOVIE);
    if (!lm->m)
        lua_pushliteral(L, "cdvr.Movie (closed)");
    else
        lua_pushfstring(L, "cdvr.Movie %s (%s, %d frames)", cdvr_movie_path(lm->m), cdvr_movie_codec(lm->m),
                        (int)cdvr_movie_frames(lm->m));
    return 1;
}

static const luaL_Reg movie_methods[] = {
    {"add", movie_add}, {"close", movie_close}, {"abort", movie_abort}, {"frames", movie_frames}, {NULL, NULL}};
static const luaL_Reg movie_meta[] = {
    {"__gc", movie_abort}, {"__close", movie_closemeta}, {"__tostring", movie_tostring}, {NULL, NULL}};
static const luaL_Reg movie_funcs[] = {{"movie", l_movie}, {NULL, NULL}};

int lcdvr_open_movie(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_MOVIE, movie_methods, movie_meta);
    lcdvr_setfuncs(L, movie_funcs);
    lua_pushboolean(L, cdvr_movie_available());
    lua_setfield(L, -2, "has_movie");
    lcdvr_help_add(L, "cdvr.movie{path=, fps=25, codec=, crf=, preset=, width=, height=, threads=1}",
                   "a movie written frame by frame: .mp4 (H.264 yuv420p, crf 18, preset medium), .webm (VP9), "
                   ".mkv (FFV1 lossless RGB), .gif (256-colour palette); odd sizes are padded by one row/column for "
                   "yuv420p; written to a temporary file that m:close() (or leaving a `local m <close>` scope) "
                   "commits; an error, Ctrl-C or m:abort() leaves nothing; cdvr.has_movie says whether this build "
                   "has FFmpeg");
    lcdvr_help_add(L, "m:add(img), m:close(), m:abort(), m:frames()",
                   "add a cdvr.Image (its PNG colours); commit (true, or nil and a message); drop the file; frames so far");
    return 0;
}
