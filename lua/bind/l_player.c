/* lua/bind/l_player.c - cdvr.player{...} and p:run{...}: playback of a store with per-stage
 * timings, Lua rate-control policies and camera paths (DESIGN.md §3, §7).
 *
 * Callbacks (policy, camera) run on the calling thread under an instruction budget
 * (`callback_limit`, default 5e7 VM instructions): a callback that runs too long or raises
 * stops playback with its traceback instead of stalling it. The policy's stats, the budgeted
 * call, the default variant and device are the scene contract it shares with the window
 * (l_scene.c).
 */
#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cdvr/dist.h"
#include "cdvr/movie.h"
#include "cdvr/timing.h"
#include "cdvr/player.h"
#include "lcdvr.h"

/* out= pattern, parsed once: the name of frame n is prefix, n formatted by `conversion`,
 * suffix. `conversion` is built here from a checked integer conversion of the user's text
 * ("%" flags width precision "d"), so user text never reaches printf as a format. */
typedef struct out_pattern {
    char prefix[1024], suffix[1024];
    char conversion[16];
} out_pattern;

typedef struct lplayer {
    cdvr_player *player;
    cdvr_player_opts opts;
    cdvr_annotate_opts annotate; /* opts.annotate points here when annotate= is given */
    lua_State *L;        /* the running state, during p:run only */
    int running;         /* p:run in progress: run and close are refused */
    int holds_store;     /* the store (UV_STORE) is marked in use (lcdvr_use) */
    int capture;         /* out= set: quality never adapts, frames are deterministic */
    int has_policy;      /* policy= given: it decides, also when capturing (stats.capture) */
    const char *variant_why; /* why opts.variant (a literal) */
    lcdvr_limits limits; /* callback_limit, callback_memory */
    double target_fps, min_psnr; /* for stats: target_fps 0 and min_psnr NaN when not given */
    int frame_callback;  /* frame= given (UV_FRAME) */
    int shows_frames;    /* this process shows the frames (frame=, out=; cdvr/dist.h) */
    out_pattern out;
    /* out= naming a movie container (cdvr/movie.h): one movie per p:run, opened before the run,
     * committed after it, dropped when it fails */
    int to_movie;
    char movie_path[1024];
    cdvr_movie_opts movie_opts; /* fps 0: the target fps or 25 at p:run */
    char movie_preset[16];
    cdvr_movie *movie;          /* during p:run */
    /* capture progress on stderr when it is a terminal (progress=false: never) */
    int progress, progress_shown;
    size_t run_frames;          /* frames asked of this p:run */
    double run_t0;
    cdvr_dist_play *dist; /* distribute= (cdvr/dist.h) */
    /* Failed frames (a damaged chunk, ...): see frame_failed. */
    int on_error_skip;   /* on_error="skip": a capture writes a marked frame and goes on */
    int strict;          /* p:run{strict=}: a failed frame is an error of p:run */
    size_t failed;       /* failed frames of this run */
    int stopped;         /* the run was stopped by a failed frame (first_failure says which) */
    char first_failure[CDVR_ERRMSG_MAX + 96];
} lplayer;

/* Uservalue slots of the player userdata. */
enum { UV_OPTS = 1, UV_POLICY, UV_CAMERA, UV_STORE, UV_TF, UV_FRAME, UV_COUNT = UV_FRAME };

static lplayer *checkplayer(lua_State *L, int idx)
{
    lplayer *lp = (lplayer *)luaL_checkudata(L, idx, LCDVR_PLAYER);
    if (!lp->player)
        luaL_error(L, "attempt to use a closed player");
    return lp;
}

/* A player inside p:run (its own callbacks are running) refuses run and close. */
static lplayer *checkidleplayer(lua_State *L, int idx, const char *what)
{
    lplayer *lp = checkplayer(L, idx);
    if (lp->running)
        luaL_error(L, "p:%s: player is running (called from its own policy or camera callback?)", what);
    return lp;
}

/* ---- callbacks ---------------------------------------------------------------------------- */

/* Calls the function below its nargs arguments under the callback budget (the scene
 * contract, lcdvr_call_callback). */
static cdvr_status call_budgeted(lplayer *lp, lua_State *L, int nargs, int nres, const char *what,
                                 cdvr_error *err)
{
    return lcdvr_call_callback(L, nargs, nres, &lp->limits, what, err);
}

/* Runs fn(ctx, player) in protected mode on the running state, so that no Lua error (memory
 * errors included) ever unwinds through the player's C code; fn reports through ctx. */
static cdvr_status run_protected(lplayer *lp, lua_CFunction fn, void *ctx, const char *what,
                                 cdvr_error *err)
{
    lua_State *L = lp->L;
    lua_pushcfunction(L, fn);
    lua_pushlightuserdata(L, ctx);
    lua_pushvalue(L, 1);                          /* fn, ctx, player (index 1 of p:run) */
    if (lua_pcall(L, 2, 0, 0) != LUA_OK) {
        cdvr_error_set(err, CDVR_ERR_ARG, "%s: %s", what, lua_tostring(L, -1));
        lua_pop(L, 1);
        return CDVR_ERR_ARG;
    }
    return CDVR_OK;
}

static void setnum(lua_State *L, const char *key, double v)
{
    lua_pushnumber(L, v);
    lua_setfield(L, -2, key);
}

typedef struct decide_ctx {
    lplayer *lp;
    cdvr_player *player;
    size_t t, group;
    int variant;
    char *reason;
    size_t reason_size;
    cdvr_error *err;
    cdvr_status status;
} decide_ctx;

/* Protected part of decide_cb: decide_ctx (light userdata), player. */
static int decide_lua(lua_State *L)
{
    decide_ctx *c = (decide_ctx *)lua_touserdata(L, 1);
    lplayer *lp = c->lp;
    const cdvr_store *st = lp->opts.store;
    lua_getiuservalue(L, 2, UV_POLICY);           /* policy */
    lcdvr_policy_view view = {c->t, c->group, lp->target_fps, lp->min_psnr, lp->opts.pipelined,
                              lp->capture, lp->opts.cache, cdvr_player_lod_error(c->player),
                              lp->opts.lod_error, cdvr_store_get_info(st)->nlevels};
    size_t nrows;
    const cdvr_frame_row *rows = cdvr_player_rows(c->player, &nrows);
    lcdvr_push_policy_stats(L, st, &view, rows, nrows); /* policy, stats */
    c->status = call_budgeted(lp, L, 1, 3, "policy", c->err);
    if (c->status != CDVR_OK)
        return 0;
    /* a third result: the brick cache's lod_error for the group (cache=true only) */
    int has_lod = !lua_isnil(L, -1);
    double lod = lua_tonumber(L, -1);
    if (has_lod && (!lua_isnumber(L, -1) || !lp->opts.cache)) {
        c->status = cdvr_error_set(c->err, CDVR_ERR_ARG, "policy returned lod_error %s (%s)",
                                   lcdvr_push_quoted(L, -1), lp->opts.cache ? "a number >= 0 "
                                   "expected" : "only with cache=true");
        return 0;
    }
    lua_pop(L, 1);
    c->status = lcdvr_policy_result(L, st, &c->variant, c->reason, c->reason_size, c->err);
    if (c->status == CDVR_OK && has_lod)
        c->status = cdvr_player_set_lod_error(c->player, lod, c->err);
    return 0;
}

/* Capture without a policy: the user's `variant` (0-based), or with min_psnr the cheapest
 * variant meeting it, or else the best quality. With a policy, the policy decides with
 * stats.capture = true: share/lua/cdvr/policy.lua's rule (deterministic: the fastest variant
 * meeting the floor, the best quality when there is none); capture waits for data either way. */
static cdvr_status decide_cb(void *ud, cdvr_player *player, size_t t, size_t group, int *variant,
                             char *reason, size_t reason_size, cdvr_error *err)
{
    lplayer *lp = ud;
    const cdvr_store *st = lp->opts.store;
    if (lp->capture && !lp->has_policy) {
        *variant = lp->opts.variant;
        snprintf(reason, reason_size, "capture: %s (%s; capture waits for data, never adapts)",
                 cdvr_store_variant(st, (size_t)*variant)->name, lp->variant_why);
        return CDVR_OK;
    }
    decide_ctx c = {lp, player, t, group, *variant, reason, reason_size, err, CDVR_OK};
    cdvr_status s = run_protected(lp, decide_lua, &c, "policy", err);
    if (s != CDVR_OK)
        return s;
    if (c.status == CDVR_OK)
        *variant = c.variant;
    return c.status;
}

typedef struct camera_ctx {
    lplayer *lp;
    size_t t, frame;
    cdvr_camera *cam;
    cdvr_error *err;
    cdvr_status status;
} camera_ctx;

/* Protected part of camera_cb: camera_ctx (light userdata), player. */
static int camera_lua(lua_State *L)
{
    camera_ctx *c = (camera_ctx *)lua_touserdata(L, 1);
    cdvr_camera *cam = c->cam;
    lua_getiuservalue(L, 2, UV_CAMERA);           /* camera function */
    lua_pushinteger(L, (lua_Integer)c->frame + 1);
    lua_pushinteger(L, (lua_Integer)c->t + 1);
    c->status = call_budgeted(c->lp, L, 2, 1, "camera", c->err);
    if (c->status != CDVR_OK)
        return 0;
    c->status = lcdvr_camera_result(L, -1, cam, c->err);
    return 0;
}

static cdvr_status camera_cb(void *ud, size_t t, size_t frame, cdvr_camera *cam, cdvr_error *err)
{
    lplayer *lp = ud;
    camera_ctx c = {lp, t, frame, cam, err, CDVR_OK};
    cdvr_status s = run_protected(lp, camera_lua, &c, "camera", err);
    return s == CDVR_OK ? c.status : s;
}

static int make_parent_dirs(char *path)
{
    for (char *s = strchr(path + 1, '/'); s; s = strchr(s + 1, '/')) {
        *s = '\0';
        int ok = mkdir(path, 0777) == 0 || errno == EEXIST;
        *s = '/';
        if (!ok)
            return 0;
    }
    return 1;
}

/* Parses out= into p; returns 1, or 0 with what is wrong in why. */
static int parse_out_pattern(const char *text, out_pattern *p, char *why, size_t why_size)
{
    size_t n = 0, conversions = 0;
    char *dst = p->prefix;
    memset(p, 0, sizeof *p);
    for (const char *s = text; *s; s++) {
        if (n + 1 >= sizeof p->prefix) {
            snprintf(why, why_size, "it is longer than %zu bytes", sizeof p->prefix - 1);
            return 0;
        }
        if (*s != '%' || s[1] == '%') {
            dst[n++] = *s;
            s += *s == '%';                       /* "%%" is one literal '%' */
            continue;
        }
        const char *c = s + 1;
        size_t flags = strspn(c, "-+ 0"), width = strspn(c + flags, "0123456789"), prec = 0;
        if (c[flags + width] == '.')
            prec = 1 + strspn(c + flags + width + 1, "0123456789");
        size_t len = flags + width + prec;
        int integer = c[len] == 'd' || c[len] == 'i';
        if (!integer || flags > 4 || width > 2 || prec > 3) {
            snprintf(why, why_size, "\"%.*s\" %s", (int)(len + (c[len] != '\0') + 1), s,
                     integer ? "has too many flags or digits (width and precision: at most 99)"
                             : "is not an integer conversion");
            return 0;
        }
        if (++conversions > 1) {
            snprintf(why, why_size, "it has more than one conversion");
            return 0;
        }
        snprintf(p->conversion, sizeof p->conversion, "%%%.*sd", (int)len, c);
        dst[n] = '\0';
        dst = p->suffix;
        n = 0;
        s = c + len;
    }
    if (conversions == 0)
        snprintf(why, why_size, "it has no conversion for the frame number");
    return conversions == 1;
}

typedef struct frame_ctx {
    lplayer *lp;
    const cdvr_frame_row *row;
    const cdvr_image *img;
    cdvr_error *err;
    cdvr_status status;
} frame_ctx;

/* Protected part of frame_cb for frame=function(row, image): frame_ctx (light userdata),
 * player. The function gets a copy of the frame. */
static int frame_lua(lua_State *L)
{
    frame_ctx *c = (frame_ctx *)lua_touserdata(L, 1);
    const cdvr_image *img = c->img;
    lua_getiuservalue(L, 2, UV_FRAME);            /* fn */
    lcdvr_push_frame_row(L, c->lp->opts.store, c->row);       /* fn, row */
    cdvr_image *copy;
    c->status = cdvr_image_create(img->width, img->height, &copy, c->err);
    if (c->status != CDVR_OK)
        return 0;
    memcpy(copy->rgba, img->rgba, (size_t)img->width * (size_t)img->height * 4 * sizeof(float));
    memcpy(copy->background, img->background, sizeof copy->background);
    lcdvr_pushimage(L, copy);                     /* fn, row, image */
    c->status = call_budgeted(c->lp, L, 2, 0, "frame", c->err);
    return 0;
}

/* "\rcapture NAME: n/N frames, F fps, ETA S s" after each written frame (stderr is a terminal). */
static void show_progress(lplayer *lp, size_t done)
{
    if (!lp->progress)
        return;
    double s = (cdvr_now_ms() - lp->run_t0) / 1000.0, fps = s > 0 ? (double)done / s : 0;
    double eta = fps > 0 && lp->run_frames > done ? (double)(lp->run_frames - done) / fps : 0;
    fprintf(stderr, "\rcapture %s: %zu/%zu frames, %.1f fps, ETA %.0f s  ",
            lp->to_movie ? lp->movie_path : "frames", done, lp->run_frames, fps, eta);
    fflush(stderr);
    lp->progress_shown = 1;
}

/* Hands a frame to frame= and, with out=, writes its PNG. */
static cdvr_status show_frame(lplayer *lp, const cdvr_frame_row *row, const cdvr_image *img, cdvr_error *err)
{
    if (lp->frame_callback) {
        frame_ctx c = {lp, row, img, err, CDVR_OK};
        cdvr_status s = run_protected(lp, frame_lua, &c, "frame", err);
        if (s == CDVR_OK)
            s = c.status;
        if (s != CDVR_OK)
            return s;
    }
    if (!lp->capture)
        return CDVR_OK;
    if (lp->to_movie) {
        if ((int64_t)row->frame != cdvr_movie_frames(lp->movie))
            return cdvr_error_set(err, CDVR_ERR_ARG, "%s: frame %zu arrived as frame %lld of the movie",
                                  lp->movie_path, row->frame + 1, (long long)cdvr_movie_frames(lp->movie) + 1);
        cdvr_status s = cdvr_movie_add_image(lp->movie, img, err);
        if (s == CDVR_OK)
            show_progress(lp, row->frame + 1);
        return s;
    }
    char number[128], path[2200];
    snprintf(number, sizeof number, lp->out.conversion, (int)row->frame + 1);
    snprintf(path, sizeof path, "%s%s%s", lp->out.prefix, number, lp->out.suffix);
    if (!make_parent_dirs(path))
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot create its directory: %s", path, strerror(errno));
    cdvr_status s = cdvr_image_save_png(img, path, err);
    if (s == CDVR_OK)
        show_progress(lp, row->frame + 1);
    return s;
}

/* The frame a capture writes in place of one that could not be made (on_error="skip"): the
 * background with an opaque red border and a red cross corner to corner, each
 * max(2, min(width, height) / 32) pixels thick. */
static cdvr_status marked_frame(const lplayer *lp, cdvr_image **out, cdvr_error *err)
{
    int w = lp->opts.camera.width, h = lp->opts.camera.height;
    cdvr_status s = cdvr_image_create(w, h, out, err);
    if (s != CDVR_OK)
        return s;
    cdvr_image *img = *out;
    memcpy(img->background, lp->opts.background, sizeof img->background);
    int thick = (w < h ? w : h) / 32 > 2 ? (w < h ? w : h) / 32 : 2;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double d1 = fabs((double)x / w - (double)y / h), d2 = fabs((double)x / w + (double)y / h - 1.0);
            int border = x < thick || y < thick || x >= w - thick || y >= h - thick;
            int cross = fmin(d1, d2) * (w < h ? w : h) < thick / 2.0;
            float *px = img->rgba + 4 * ((size_t)y * (size_t)w + (size_t)x);
            if (border || cross) {
                px[0] = px[3] = 1.0f; /* premultiplied opaque red */
                px[1] = px[2] = 0.0f;
            }
        }
    return CDVR_OK;
}

/* A frame that could not be made (row->error names the chunk and the store). It is counted
 * and the first is remembered; then a capture with on_error="skip" writes the marked frame in
 * its place and goes on, while a capture with on_error="stop" (the default) or a strict run
 * stops here with an error naming the frame, the timestep and the cause. */
static cdvr_status frame_failed(lplayer *lp, const cdvr_frame_row *row, cdvr_error *err)
{
    if (lp->failed++ == 0)
        snprintf(lp->first_failure, sizeof lp->first_failure, "frame %zu (timestep %zu) could not be made: %s",
                 row->frame + 1, row->t + 1, row->error[0] ? row->error : cdvr_status_name(row->status));
    if (lp->capture && lp->on_error_skip) {
        cdvr_image *img = NULL;
        cdvr_status s = marked_frame(lp, &img, err);
        if (s == CDVR_OK)
            s = show_frame(lp, row, img, err);
        cdvr_image_free(img);
        return s;
    }
    if (!lp->capture && !lp->strict)
        return CDVR_OK; /* interactive playback: the row keeps its error, the run goes on */
    lp->stopped = 1;
    return cdvr_error_set(err, row->status, "p:run: %s%s", lp->first_failure,
                          lp->capture ? "; the capture stops there (cdvr.player{on_error=\"skip\"} writes a "
                                        "marked frame in its place and goes on)" : "");
}

/* After each frame: stops the run on Ctrl-C in the console; where this process shows the
 * frames (distribute='bricks': rank 0), hands it to frame= and, with out=, writes the PNG; a
 * failed frame (img NULL) goes to frame_failed. */
static cdvr_status frame_cb(void *ud, const cdvr_frame_row *row, const cdvr_image *img, cdvr_error *err)
{
    lplayer *lp = ud;
    const atomic_int *interrupt = lcdvr_interrupt_flag(lp->L);
    if (interrupt && atomic_load(interrupt))
        return cdvr_error_set(err, CDVR_ERR_CANCELLED, "playback interrupted");
    if (!lp->shows_frames)
        return CDVR_OK;
    if (!img || row->status != CDVR_OK)
        return frame_failed(lp, row, err);
    return show_frame(lp, row, img, err);
}

/* ---- cdvr.player ------------------------------------------------------------------------ */

static int is_callable(lua_State *L, int idx)
{
    if (lua_isfunction(L, idx))
        return 1;
    if (luaL_getmetafield(L, idx, "__call") != LUA_TNIL) {
        lua_pop(L, 1);
        return 1;
    }
    return 0;
}

/* variant= (name or index, 0-based result); absent: the best quality. */
static int variant_option(lua_State *L, const cdvr_store *st)
{
    int t = lua_getfield(L, 1, "variant");
    int v = cdvr_store_best_variant(st);
    if (t == LUA_TNUMBER) {
        v = (int)lua_tointeger(L, -1) - 1;
    } else if (t == LUA_TSTRING) {
        v = lcdvr_find_variant(L, -1, st);
        if (v < 0)
            luaL_error(L, "cdvr.player: store %s has no variant %s", cdvr_store_path(st), lcdvr_push_quoted(L, -1));
    } else if (t != LUA_TNIL) {
        luaL_error(L, "cdvr.player: option 'variant': name or index expected");
    }
    lua_pop(L, 1);
    if (v < 0 || (size_t)v >= cdvr_store_get_info(st)->nvariants)
        luaL_error(L, "cdvr.player: variant %d out of range", v + 1);
    return v;
}

/* Cheapest variant whose encode-time PSNR is at least min_psnr (capture floor). */
static int variant_for_psnr(const cdvr_store *st, double min_psnr)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    int best = -1;
    for (size_t v = 0; v < info->nvariants; v++) {
        const cdvr_variant_info *var = cdvr_store_variant(st, v);
        if (var->psnr >= min_psnr && (best < 0 || var->bytes < cdvr_store_variant(st, (size_t)best)->bytes))
            best = (int)v;
    }
    return best;
}

/* Pushes the options a named policy gets from the player's: target_fps and the variant
 * (as its name: the capture floor of policy.lua). */
static void push_policy_options(lua_State *L, const cdvr_store *st, int variant)
{
    lua_createtable(L, 0, 2);
    lua_getfield(L, 1, "target_fps");
    lua_setfield(L, -2, "target_fps");
    lua_getfield(L, 1, "variant");
    int given = !lua_isnil(L, -1);
    lua_pop(L, 1);
    if (given) {
        lua_pushstring(L, cdvr_store_variant(st, (size_t)variant)->name);
        lua_setfield(L, -2, "variant");
    }
}

/* Resolves policy= (function, callable, or a name for cdvr.policy.get) into UV_POLICY. */
static int resolve_policy(lua_State *L, int ud, const cdvr_store *st, int variant)
{
    int t = lua_getfield(L, 1, "policy");         /* policy */
    if (t == LUA_TNIL) {
        lua_pop(L, 1);
        return 0;
    }
    if (t == LUA_TSTRING) {
        lua_getglobal(L, "require");
        lua_pushliteral(L, "cdvr.policy");
        lua_call(L, 1, 1);                        /* name, policy module */
        lua_getfield(L, -1, "get");
        lua_pushvalue(L, -3);
        push_policy_options(L, st, variant);
        if (lua_pcall(L, 2, 1, 0) != LUA_OK)      /* name, module, policy fn */
            luaL_error(L, "cdvr.player: option 'policy': %s", luaL_tolstring(L, -1, NULL));
        lua_replace(L, -3);
        lua_pop(L, 1);                            /* policy fn */
    }
    if (!is_callable(L, -1))
        luaL_error(L, "cdvr.player: option 'policy': function or policy name expected, got %s", luaL_typename(L, -1));
    lua_setiuservalue(L, ud, UV_POLICY);
    return 1;
}

/* ---- option values (checked when the player is made) ------------------------------------- */

/* Number option `key` of the options table: def when absent; raises unless lo <= value <= hi
 * (NaN never passes), with `rule` saying what is allowed. */
static double number_option(lua_State *L, const char *key, double def, double lo, double hi, const char *rule)
{
    int absent = lua_getfield(L, 1, key) == LUA_TNIL;
    lua_pop(L, 1);
    if (absent)
        return def;
    double v = lcdvr_optnumberfield(L, 1, key, def);
    if (!(v >= lo && v <= hi))
        luaL_error(L, "cdvr.player: option '%s' = %f: %s", key, (lua_Number)v, rule);
    return v;
}

/* A rate option (read_mbps, target_fps): def when absent, 0 for "none" where zero_ok, else
 * min .. CDVR_PLAYER_MAX_RATE (player.h), so that no rate makes the run wait for ever. */
static double rate_option(lua_State *L, const char *key, double def, int zero_ok, double min, const char *unit)
{
    int absent = lua_getfield(L, 1, key) == LUA_TNIL;
    lua_pop(L, 1);
    if (absent)
        return def;
    double v = number_option(L, key, def, 0, HUGE_VAL, "a finite number >= 0 expected");
    if ((v == 0 && !zero_ok) || (v != 0 && !(v >= min && v <= CDVR_PLAYER_MAX_RATE))) {
        char msg[256];
        snprintf(msg, sizeof msg, "cdvr.player: option '%s' = %g: %s%g .. %g %s expected (the limits keep the run "
                 "bounded)", key, v, zero_ok ? "0 (none) or " : "", min, CDVR_PLAYER_MAX_RATE, unit);
        luaL_error(L, "%s", msg);
    }
    return v;
}

static lua_Integer integer_option(lua_State *L, const char *key, lua_Integer def, lua_Integer lo, lua_Integer hi)
{
    lua_Integer v = lcdvr_optintegerfield(L, 1, key, def);
    if (v < lo || v > hi)
        luaL_error(L, "cdvr.player: option '%s' = %I: must be %I..%I", key, (LUAI_UACINT)v, (LUAI_UACINT)lo,
                   (LUAI_UACINT)hi);
    return v;
}

/* background={r, g, b [, a]}, entries in [0, 1] (as cdvr.render). */
static void background_option(lua_State *L, float bg[4])
{
    bg[0] = bg[1] = bg[2] = 0.0f;
    bg[3] = 1.0f;
    int t = lua_getfield(L, 1, "background");      /* background */
    lua_Integer n = t == LUA_TTABLE ? luaL_len(L, -1) : 0;
    if (t != LUA_TNIL && n != 3 && n != 4)
        luaL_error(L, "cdvr.player: option 'background': {r, g, b [, a]} expected");
    for (lua_Integer i = 1; i <= n; i++) {
        lua_geti(L, -1, i);
        int ok;
        lua_Number c = lua_tonumberx(L, -1, &ok);
        if (!ok || !(c >= 0.0 && c <= 1.0))
            luaL_error(L, "cdvr.player: option 'background'[%d]: a number in [0, 1] expected", (int)i);
        bg[i - 1] = (float)c;
        lua_pop(L, 1);
    }
    lua_pop(L, 1);
}

/* Largest diagonal / step the renderers accept (render_cpu.c: at most INT_MAX samples). */
static double box_diagonal(const cdvr_store_info *info)
{
    double sum = 0;
    for (int i = 0; i < 3; i++) {
        double len = (double)(info->dims[i] - 1) * info->spacing[i];
        sum += len * len;
    }
    return sqrt(sum);
}

/* fetch = "auto" | "sample" | "bulk": cdvr_cl_fetch_path (cdvr/device.h) as 0, 1, 2. */
static int fetch_option(lua_State *L)
{
    static const char *const names[] = {"auto", "sample", "bulk"};
    const char *name = lcdvr_optstringfield(L, 1, "fetch", "auto");
    for (int i = 0; i < 3; i++)
        if (strcmp(name, names[i]) == 0)
            return i;
    return luaL_error(L, "cdvr.player: option 'fetch': auto, sample or bulk expected, got '%s'",
                      name);
}

/* step, unit, term, background, threads, ring, read_mbps: the render and pipeline options. */
static void render_options(lua_State *L, lplayer *lp, const cdvr_store_info *info)
{
    lp->opts.step = number_option(L, "step", 0, 0, DBL_MAX, "a finite number >= 0 expected (0: half a voxel)");
    if (lp->opts.step > 0 && box_diagonal(info) / lp->opts.step > (double)INT_MAX)
        luaL_error(L, "cdvr.player: option 'step' = %f is too small for the store's box (diagonal %f)",
                   (lua_Number)lp->opts.step, (lua_Number)box_diagonal(info));
    lp->opts.unit = number_option(L, "unit", 0, 0, DBL_MAX, "a finite number >= 0 expected (0: the TF's unit)");
    lp->opts.term_alpha = number_option(L, "term", 0, 0, DBL_MAX,
                                        "a finite number >= 0 expected (0: 0.99; 1 or more: no early termination)");
    background_option(L, lp->opts.background);
    lp->opts.threads = (int)integer_option(L, "threads", 0, 0, 256);
    lp->opts.pipelined = lcdvr_optbooleanfield(L, 1, "pipeline", 1);
    lp->opts.ring = (int)integer_option(L, "ring", 3, 1, 64);
    lp->opts.cold = lcdvr_optbooleanfield(L, 1, "cold", 0);
    lp->opts.read_mbps = rate_option(L, "read_mbps", 0, 1, CDVR_PLAYER_MIN_READ_MBPS, "MB/s");
    lp->opts.empty_skip = lcdvr_optbooleanfield(L, 1, "empty_skip", 1);
    lp->opts.decode_whole = lcdvr_optbooleanfield(L, 1, "decode_whole", 0);
    lp->opts.fetch_path = fetch_option(L);
    lp->opts.cache = lcdvr_optbooleanfield(L, 1, "cache", 0);
    lp->opts.cache_async = lcdvr_optbooleanfield(L, 1, "cache_async", 0);
    if (lp->opts.cache_async && !lp->opts.cache)
        luaL_error(L, "cdvr.player: option 'cache_async' needs cache=true");
    lp->opts.cache_budget_mb = number_option(L, "budget_mb", 0, 0, 1e12,
                                             "MB >= 0 expected (0: a quarter of the device's memory)");
    lp->opts.lod_error = number_option(L, "lod_error", 1, 0, 1e12, "pixels >= 0 expected");
    lp->opts.brick_skip = lcdvr_optbooleanfield(L, 1, "brick_skip", 1);
}

/* fps=, crf=, preset= of a movie out= (refused otherwise); the codec's checks come at p:run. */
static void movie_options(lua_State *L, lplayer *lp, int movie)
{
    static const char *const keys[] = {"fps", "crf", "preset", NULL};
    for (int i = 0; keys[i] && !movie; i++) {
        if (lua_getfield(L, 1, keys[i]) != LUA_TNIL)
            luaL_error(L, "cdvr.player: option '%s' applies to a movie out= (.mp4, .webm, .mkv, .gif)", keys[i]);
        lua_pop(L, 1);
    }
    if (!movie)
        return;
    lp->movie_opts = cdvr_movie_defaults();
    lp->movie_opts.fps = number_option(L, "fps", 0, CDVR_PLAYER_MIN_FPS, 1000, "frames/s (0, 1000] expected");
    lp->movie_opts.crf = (int)integer_option(L, "crf", -1, -1, 63);
    const char *preset = lcdvr_optstringfield(L, 1, "preset", NULL);
    if (preset && strlen(preset) >= sizeof lp->movie_preset)
        luaL_error(L, "cdvr.player: option 'preset' = \"%s\": unknown preset", preset);
    if (preset) {
        snprintf(lp->movie_preset, sizeof lp->movie_preset, "%s", preset);
        lp->movie_opts.preset = lp->movie_preset;
    }
}

/* out=: capture settings (pattern, capture floor); returns 1 when capturing. */
static int capture_options(lua_State *L, lplayer *lp, const cdvr_store *st)
{
    const char *out = lcdvr_optstringfield(L, 1, "out", NULL);
    const char *on_error = lcdvr_optstringfield(L, 1, "on_error", NULL);
    if (on_error && strcmp(on_error, "stop") != 0 && strcmp(on_error, "skip") != 0)
        luaL_error(L, "cdvr.player: option 'on_error' = \"%s\": \"stop\" (the default: a frame that cannot "
                      "be made stops the capture) or \"skip\" (a marked frame in its place) expected", on_error);
    if (on_error && !out)
        luaL_error(L, "cdvr.player: option 'on_error' applies to captures (out=), and out= is not set");
    lp->on_error_skip = on_error && strcmp(on_error, "skip") == 0;
    if (!out) {
        movie_options(L, lp, 0);
        return 0;
    }
    char why[96];
    if (cdvr_movie_is_movie_path(out)) {
        if (strchr(out, '%'))
            luaL_error(L, "cdvr.player: option 'out' = \"%s\": a movie file (its extension) with a frame number "
                          "conversion; give \"movie.mp4\" for one movie or \"frames/%%04d.png\" for PNG frames", out);
        if (strlen(out) >= sizeof lp->movie_path)
            luaL_error(L, "cdvr.player: option 'out': longer than %d bytes", (int)sizeof lp->movie_path - 1);
        if (!cdvr_movie_available())
            luaL_error(L, "cdvr.player: option 'out' = \"%s\": this cdvr was built without FFmpeg (libavformat, "
                          "libavcodec, libswscale, libavutil) and writes no movies (cdvr.has_movie is false)", out);
        snprintf(lp->movie_path, sizeof lp->movie_path, "%s", out);
        lp->to_movie = 1;
    } else if (!parse_out_pattern(out, &lp->out, why, sizeof why)) {
        luaL_error(L, "cdvr.player: option 'out' = \"%s\": %s; out= needs exactly one integer conversion "
                      "for the frame number (%%d, %%04d, %%5d, ...; %%%% for a literal %%), or a movie file "
                      "(.mp4, .webm, .mkv, .gif)",
                   out, why);
    }
    movie_options(L, lp, lp->to_movie);
    lp->progress = lcdvr_optbooleanfield(L, 1, "progress", 1) && isatty(STDERR_FILENO);
    double min_psnr = number_option(L, "min_psnr", -HUGE_VAL, -HUGE_VAL, HUGE_VAL, "a number in dB expected");
    lua_getfield(L, 1, "variant");
    int user_variant = !lua_isnil(L, -1);
    lua_pop(L, 1);
    if (user_variant)
        lp->variant_why = "the variant set by the user";
    if (!user_variant && min_psnr > -HUGE_VAL) {
        int v = variant_for_psnr(st, min_psnr);
        if (v < 0)
            luaL_error(L, "cdvr.player: no variant of %s reaches min_psnr %f", cdvr_store_path(st), (lua_Number)min_psnr);
        lp->opts.variant = v;
        lp->variant_why = "the cheapest variant meeting min_psnr";
    }
    return 1;
}

static void camera_option(lua_State *L, int ud, lplayer *lp, const cdvr_store_info *info)
{
    int width = (int)integer_option(L, "width", 512, 1, 65536);
    int height = (int)integer_option(L, "height", 512, 1, 65536);
    cdvr_camera *cam = NULL;
    lua_getfield(L, 1, "camera");                 /* camera option */
    if ((cam = luaL_testudata(L, -1, LCDVR_CAMERA)) != NULL) {
        lp->opts.camera = *cam;
        if (lua_getfield(L, 1, "width") == LUA_TNIL)
            width = cam->width;
        if (lua_getfield(L, 1, "height") == LUA_TNIL)
            height = cam->height;
        lua_pop(L, 2);
    } else {
        /* default view: the whole oriented box (world bounds) from the -y side, z up */
        cdvr_volume box = {.timesteps = 1};
        memcpy(box.dims, info->dims, sizeof box.dims);
        memcpy(box.spacing, info->spacing, sizeof box.spacing);
        memcpy(box.origin, info->origin, sizeof box.origin);
        memcpy(box.direction, info->direction, sizeof box.direction);
        double lo[3], hi[3], c[3], ext = 0;
        cdvr_volume_bounds(&box, lo, hi);
        for (int i = 0; i < 3; i++) {
            c[i] = 0.5 * (lo[i] + hi[i]);
            ext = hi[i] - lo[i] > ext ? hi[i] - lo[i] : ext;
        }
        cdvr_camera def = {{c[0], c[1] - 2.2 * ext - 1, c[2] + 0.6 * ext}, {c[0], c[1], c[2]}, {0, 0, 1}, 30, width, height, 0, 0};
        lp->opts.camera = def;
        if (!lua_isnil(L, -1)) {
            if (!is_callable(L, -1))
                luaL_error(L, "cdvr.player: option 'camera': cdvr.Camera, function or path expected, got %s",
                           luaL_typename(L, -1));
            lua_pushvalue(L, -1);
            lua_setiuservalue(L, ud, UV_CAMERA);
            lp->opts.camera_fn = camera_cb;
            lp->opts.camera_ud = lp;
        }
    }
    lua_pop(L, 1);
    lp->opts.camera.width = width;
    lp->opts.camera.height = height;
}

/* store= and tf=: checked, kept in user values; the store is marked in use for the player's
 * lifetime (st:close() meanwhile is deferred until the player is closed). */
static cdvr_store *store_and_tf(lua_State *L, int ud, lplayer *lp)
{
    lua_getfield(L, 1, "store");
    lcdvr_checkoption(L, -1, "cdvr.player", "store", LCDVR_STORE);
    cdvr_store *st = lcdvr_checkstore(L, -1);
    lcdvr_use(L, -1);
    lp->holds_store = 1;
    lua_setiuservalue(L, ud, UV_STORE);
    lua_getfield(L, 1, "tf");
    lcdvr_checkoption(L, -1, "cdvr.player", "tf", LCDVR_TF);
    cdvr_tf *tf = lcdvr_pushtf(L, lcdvr_checktf(L, -1)); /* tf, copy */
    const cdvr_store_info *info = cdvr_store_get_info(st);
    cdvr_error tf_err;
    if (cdvr_tf_set_window(tf, info->qlo, info->qhi, &tf_err) != CDVR_OK) /* tf.h: data units */
        lcdvr_raise(L, &tf_err);
    lua_setiuservalue(L, ud, UV_TF);
    lua_pop(L, 1);
    lp->opts.tf = tf;
    lp->opts.store = st;
    return st;
}

/* frame=function(row, image): each shown frame handed to the script. */
static void frame_option(lua_State *L, int ud, lplayer *lp)
{
    if (lua_getfield(L, 1, "frame") != LUA_TNIL) { /* frame function */
        if (!is_callable(L, -1))
            luaL_error(L, "cdvr.player: option 'frame': function(row, image) expected, got %s",
                       luaL_typename(L, -1));
        lua_pushvalue(L, -1);
        lua_setiuservalue(L, ud, UV_FRAME);
        lp->frame_callback = 1;
    }
    lua_pop(L, 1);
}

/* distribute= (cdvr/dist.h): this rank's share of the run. */
static void distribute_option(lua_State *L, lplayer *lp)
{
    static const char *const modes[] = {"none", "time", "bricks", NULL};
    const char *mode = lcdvr_optstringfield(L, 1, "distribute", "none");
    int m = 0;
    while (modes[m] && strcmp(modes[m], mode) != 0)
        m++;
    if (!modes[m])
        luaL_error(L, "cdvr.player: invalid distribute '%s' (none, time, bricks)", mode);
    const cdvr_render_method *method = lp->opts.method;
    unsigned need = m == CDVR_DIST_TIME ? CDVR_METHOD_DIST_TIME
                  : m == CDVR_DIST_BRICKS ? CDVR_METHOD_DIST_BRICKS : 0;
    if (need && !(method->distribute & need))
        luaL_error(L, "cdvr.player: method '%s' cannot be distributed by '%s'", method->name, mode);
    if (m == CDVR_DIST_BRICKS && (lp->opts.look.blend != CDVR_BLEND_COMPOSITE ||
                                  lp->opts.look.shade.enabled ||
                                  lp->opts.look.gradient_opacity.npoints))
        luaL_error(L, "cdvr.player: distribute='bricks' composites brick images front to back: "
                      "blend '%s' and shading are not supported there (distribute='time' is)",
                   cdvr_blend_name(lp->opts.look.blend));
    if (m == CDVR_DIST_BRICKS && cdvr_dist_size() > 1 && lp->has_policy && !lp->capture)
        luaL_error(L, "cdvr.player: distribute='bricks': every rank must read the same variant, so "
                      "a policy cannot adapt per rank (give variant=, or capture with out=)");
    cdvr_error err;
    if (cdvr_dist_play_create((cdvr_dist_mode)m, &lp->opts, &lp->dist, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    lp->shows_frames = cdvr_dist_play_shows_frames(lp->dist); /* bricks: rank 0's composite */
}

static cdvr_status open_movie(lplayer *lp, cdvr_error *err);

static int l_player(lua_State *L)
{
    static const char *const keys[] = {"store", "tf", "camera", "policy", "target_fps", "min_psnr",
                                       "variant", "device", "step", "unit", "term", "background",
                                       "threads", "pipeline", "ring", "cold", "read_mbps",
                                       "empty_skip", "decode_whole", "fetch", "cache", "cache_async", "budget_mb", "lod_error", "callback_limit", "callback_memory", "out", "pace", "width",
                                       "height", "loop", "brick_skip", "frame", "distribute",
                                       "on_error", "fps", "crf", "preset", "progress", NULL};
    luaL_checktype(L, 1, LUA_TTABLE);
    const cdvr_render_method *method = lcdvr_method_option(L, 1, "cdvr.player");
    lcdvr_method_checkoptions(L, 1, method, "cdvr.player", keys);
    lplayer *lp = (lplayer *)lua_newuserdatauv(L, sizeof *lp, UV_COUNT); /* ud */
    memset(lp, 0, sizeof *lp);
    int ud = lua_gettop(L);
    luaL_setmetatable(L, LCDVR_PLAYER);
    lua_pushvalue(L, 1);
    lua_setiuservalue(L, ud, UV_OPTS);
    cdvr_store *st = store_and_tf(L, ud, lp);
    const cdvr_store_info *info = cdvr_store_get_info(st);

    /* the method, its device (absent or "auto": the scene contract's rule, as the window's),
     * its options and the look, all from the method table */
    lp->opts.method = method;
    lp->opts.device = lcdvr_method_device(L, 1, method, "cdvr.player");
    lcdvr_method_params(L, 1, method, "cdvr.player", &lp->opts.method_params);
    lcdvr_read_look(L, 1, method, "cdvr.player", &lp->opts.look);
    if (lcdvr_read_annotate(L, 1, "cdvr.player", &lp->annotate, &lp->opts.annotate_time))
        lp->opts.annotate = &lp->annotate; /* its strings stay in the options (UV_OPTS) */
    lp->opts.ctx = lcdvr_render_ctx(L);
    render_options(L, lp, info);
    lcdvr_limits_options(L, 1, "cdvr.player", &lp->limits);
    lp->min_psnr = number_option(L, "min_psnr", NAN, -HUGE_VAL, HUGE_VAL, "a number in dB expected");
    lp->opts.variant = variant_option(L, st);
    lp->variant_why = "best quality (no variant, policy or min_psnr given)";
    lp->capture = capture_options(L, lp, st);
    frame_option(L, ud, lp);
    double target_fps = rate_option(L, "target_fps", 0, 0, CDVR_PLAYER_MIN_FPS, "frames/s");
    lp->target_fps = target_fps;
    if (!lp->capture && lcdvr_optbooleanfield(L, 1, "pace", 1))
        lp->opts.pace_fps = target_fps;
    lp->opts.loop = lcdvr_optbooleanfield(L, 1, "loop", 0);
    lp->has_policy = resolve_policy(L, ud, st, lp->opts.variant);
    if (lp->has_policy || lp->capture) {
        lp->opts.decide = decide_cb;
        lp->opts.decide_ud = lp;
    }
    camera_option(L, ud, lp, info);
    lp->opts.frame_fn = frame_cb; /* Ctrl-C in the console, frame= and out= */
    lp->opts.frame_ud = lp;
    distribute_option(L, lp);
    cdvr_error err;
    cdvr_error_clear(&err);
    if (lp->to_movie && cdvr_dist_size() > 1 && lua_getfield(L, 1, "distribute") != LUA_TNIL &&
        strcmp(lcdvr_optstringfield(L, 1, "distribute", "none"), "time") == 0)
        luaL_error(L, "cdvr.player: a movie out= with distribute='time' over %d ranks: each rank has part of the "
                      "frames; write PNG frames (out='frames/%%04d.png') or use distribute='bricks'", cdvr_dist_size());
    if (lp->to_movie) { /* the options and the path are checked now, not at the first p:run */
        if (open_movie(lp, &err) != CDVR_OK)
            return lcdvr_raise(L, &err);
        cdvr_movie_abort(lp->movie);
        lp->movie = NULL;
    }
    if (cdvr_player_create(&lp->opts, &lp->player, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_settop(L, ud);
    return 1;
}

/* Pushes {read_ms=, ..., frame_ms=, serial_ms=, ..., unzip_cpu_ms=} medians over frames
 * without error. */
static void push_stage_medians(lua_State *L, const cdvr_frame_row *rows, size_t n)
{
    static const char *const names[] = {"read_ms", "unzip_ms", "upload_ms", "decode_ms", "setup_ms", "render_ms", "frame_ms", "serial_ms", "interval_ms", "grid_ms", "unzip_cpu_ms"};
    enum { NSTAGES = sizeof names / sizeof *names };
    double *vals = lua_newuserdatauv(L, (n ? n : 1) * sizeof(double), 0); /* scratch */
    lua_createtable(L, 0, NSTAGES);                                       /* scratch, medians */
    for (int k = 0; k < NSTAGES; k++) {
        size_t m = 0;
        for (size_t i = 0; i < n; i++) {
            const cdvr_frame_row *r = &rows[i];
            if (r->status != CDVR_OK)
                continue;
            double stage[NSTAGES] = {r->read_ms, r->unzip_ms, r->upload_ms, r->decode_ms, r->setup_ms, r->render_ms,
                                     r->frame_ms,
                                     r->read_ms + r->unzip_ms + r->grid_ms + r->upload_ms + r->decode_ms +
                                         r->setup_ms + r->render_ms,
                                     r->interval_ms, r->grid_ms, r->unzip_cpu_ms};
            vals[m++] = stage[k];
        }
        setnum(L, names[k], cdvr_median(vals, m));
    }
    lua_remove(L, -2);                                                    /* medians */
}

/* The failed frames of a run, with the report on the stack: report.failed (their number) and,
 * when one stopped the run, report.error; a strict run with failed frames (on_error="skip":
 * marked frames written) raises instead, naming the count and the first. */
static int run_failures(lua_State *L, lplayer *lp, size_t rows)
{
    if (lp->strict && lp->failed > 0)
        return luaL_error(L, "p:run: %d of %d frames could not be made (marked frames were written in their place, "
                             "on_error=\"skip\"); the first: %s", (int)lp->failed, (int)rows, lp->first_failure);
    lua_pushinteger(L, (lua_Integer)lp->failed);
    lua_setfield(L, -2, "failed");
    if (lp->stopped) {
        lua_pushstring(L, lp->first_failure);
        lua_setfield(L, -2, "error");
    }
    return 1;
}

/* Opens the movie of a movie out= for a run (frames of the camera's size; fps= or the target
 * fps, else 25) where this process shows the frames. */
static cdvr_status open_movie(lplayer *lp, cdvr_error *err)
{
    if (!lp->to_movie || !lp->shows_frames)
        return CDVR_OK;
    cdvr_movie_opts o = lp->movie_opts;
    if (o.fps <= 0)
        o.fps = lp->target_fps > 0 ? lp->target_fps : 25;
    o.width = lp->opts.camera.width;
    o.height = lp->opts.camera.height;
    return cdvr_movie_open(lp->movie_path, &o, &lp->movie, err);
}

/* After the run: commits the movie when the run succeeded (ok), else drops it. */
static cdvr_status finish_movie(lplayer *lp, int ok, cdvr_error *err)
{
    cdvr_movie *m = lp->movie;
    lp->movie = NULL;
    if (!m)
        return CDVR_OK;
    if (!ok) {
        cdvr_movie_abort(m);
        return CDVR_OK;
    }
    return cdvr_movie_close(m, err);
}

static int player_run(lua_State *L)
{
    lplayer *lp = checkidleplayer(L, 1, "run");
    const cdvr_store_info *info = cdvr_store_get_info(lp->opts.store);
    lua_Integer frames = (lua_Integer)info->timesteps, first = 1;
    lp->strict = lp->capture; /* captures never lose a frame silently */
    if (!lua_isnoneornil(L, 2)) {
        static const char *const keys[] = {"frames", "first", "strict", NULL};
        luaL_checktype(L, 2, LUA_TTABLE);
        lcdvr_checkoptions(L, 2, "p:run", keys);
        frames = lcdvr_optintegerfield(L, 2, "frames", frames);
        first = lcdvr_optintegerfield(L, 2, "first", 1);
        lp->strict = lcdvr_optbooleanfield(L, 2, "strict", lp->capture);
    }
    lp->failed = 0;
    lp->stopped = 0;
    lp->first_failure[0] = '\0';
    luaL_argcheck(L, frames >= 1, 2, "frames must be at least 1");
    luaL_argcheck(L, first >= 1 && (size_t)first <= info->timesteps, 2, "first timestep out of range");
    lua_settop(L, 1);                             /* callbacks find the player at index 1 */
    cdvr_error err;
    if (cdvr_dist_play_begin(lp->dist, (size_t)first - 1, (size_t)frames, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);               /* the ranks disagree (cdvr/dist.h) */
    if (open_movie(lp, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lp->run_frames = (size_t)frames;
    lp->run_t0 = cdvr_now_ms();
    lp->progress_shown = 0;
    lp->L = L;
    lp->running = 1;
    double t0 = cdvr_now_ms();
    cdvr_status status = cdvr_player_run(lp->player, (size_t)first - 1, (size_t)frames, &err);
    double wall_ms = cdvr_now_ms() - t0;
    lp->running = 0;
    lp->L = NULL;
    if (lp->progress_shown)
        fputc('\n', stderr);
    cdvr_error movie_err;
    if (finish_movie(lp, status == CDVR_OK, &movie_err) != CDVR_OK)
        return lcdvr_raise(L, &movie_err);
    if (status != CDVR_OK && (lp->strict || !lp->stopped)) /* not strict: a report that says it stopped */
        return lcdvr_raise(L, &err);
    size_t n;
    const cdvr_frame_row *rows;
    double fps;
    if (cdvr_dist_play_gather(lp->dist, lp->player, wall_ms, &rows, &n, &fps, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    int ranks = cdvr_dist_size();
    /* the decision in force on each rank: the reason of its last group start */
    const char **why = lua_newuserdatauv(L, (size_t)ranks * sizeof *why, 0); /* why */
    for (int r = 0; r < ranks; r++)
        why[r] = NULL;
    lua_createtable(L, 0, 10);                    /* why, report */
    if (cdvr_player_stopped_early(lp->player) > 0) { /* reached the last timestep, loop=false */
        lua_pushfstring(L, "stopped at the last timestep %d of %s after %d of %d frames "
                           "(cdvr.player{loop=true} plays on from timestep 1)",
                        (int)info->timesteps, cdvr_store_path(lp->opts.store),
                        (int)(frames - (lua_Integer)cdvr_player_stopped_early(lp->player)),
                        (int)frames);
        lcdvr_warn(L, "%s", lua_tostring(L, -1));
        lua_setfield(L, -2, "stopped");
    }
    setnum(L, "fps", fps);
    setnum(L, "wall_ms", wall_ms);
    lua_pushinteger(L, ranks);
    lua_setfield(L, -2, "ranks");
    lua_createtable(L, (int)n, 0);                /* why, report, frames */
    for (size_t i = 0; i < n; i++) {
        int r = rows[i].rank >= 0 && rows[i].rank < ranks ? rows[i].rank : 0;
        lcdvr_push_frame_row(L, lp->opts.store, &rows[i]);
        if (rows[i].group_start)
            why[r] = rows[i].reason;
        lua_pushstring(L, why[r] ? why[r] : "");
        lua_setfield(L, -2, "why");
        lua_rawseti(L, -2, (lua_Integer)i + 1);
    }
    lua_setfield(L, -2, "frames");
    lua_pushboolean(L, lp->capture);
    lua_setfield(L, -2, "capture");
    push_stage_medians(L, rows, n);
    lua_setfield(L, -2, "median");
    lua_pushboolean(L, lp->opts.pipelined);
    lua_setfield(L, -2, "pipelined");
    lua_pushstring(L, lp->opts.device == CDVR_DEVICE_CL ? "cl" : "cpu");
    lua_setfield(L, -2, "device");
    lua_pushinteger(L, (lua_Integer)cdvr_player_group_length(lp->opts.store));
    lua_setfield(L, -2, "group_length");
    return run_failures(L, lp, n);
}

/* Frees the player and lets go of its store (a deferred st:close() happens now). */
static void release_player(lua_State *L, lplayer *lp)
{
    cdvr_player_free(lp->player);
    lp->player = NULL;
    cdvr_dist_play_free(lp->dist);
    lp->dist = NULL;
    if (lp->holds_store) {
        lp->holds_store = 0;
        lua_getiuservalue(L, 1, UV_STORE);        /* store */
        lcdvr_unuse(L, -1);
        lua_pop(L, 1);
    }
}

/* p:close() and __close: refused while the player runs (from its own callbacks). */
static int player_close(lua_State *L)
{
    lplayer *lp = (lplayer *)luaL_checkudata(L, 1, LCDVR_PLAYER);
    if (lp->running)
        return luaL_error(L, "p:close: player is running (called from its own policy or camera callback?)");
    release_player(L, lp);
    return 0;
}

/* __gc: a running player is still on the stack of p:run, so it is collected only when the state
 * closes inside a callback (os.exit(code, true)): then it is left for the process exit (p:run's
 * frame still points at it), except its distribution, which nothing else points at and which
 * the run, ended by the exit, never uses again. */
static int player_gc(lua_State *L)
{
    lplayer *lp = (lplayer *)luaL_checkudata(L, 1, LCDVR_PLAYER);
    if (!lp->running) {
        release_player(L, lp);
    } else {
        cdvr_dist_play_free(lp->dist);
        lp->dist = NULL;
    }
    return 0;
}

static int player_tostring(lua_State *L)
{
    lplayer *lp = (lplayer *)luaL_checkudata(L, 1, LCDVR_PLAYER);
    if (!lp->player)
        lua_pushliteral(L, "cdvr.Player (closed)");
    else
        lua_pushfstring(L, "cdvr.Player %s on %s (%p)", cdvr_store_path(lp->opts.store),
                        lp->opts.device == CDVR_DEVICE_CL ? "cl" : "cpu", (void *)lp);
    return 1;
}

static const luaL_Reg player_methods[] = {{"run", player_run}, {"close", player_close}, {NULL, NULL}};
static const luaL_Reg player_meta[] = {
    {"__gc", player_gc}, {"__close", player_close}, {"__tostring", player_tostring}, {NULL, NULL}};
static const luaL_Reg player_funcs[] = {{"player", l_player}, {NULL, NULL}};

int lcdvr_open_player(lua_State *L)
{
    lcdvr_open_budget(L);
    lcdvr_newclass(L, LCDVR_PLAYER, player_methods, player_meta);
    lcdvr_setfuncs(L, player_funcs);
    lcdvr_help_add(L, "cdvr.player{store=, tf=, camera=, policy=, ...}",
                   "playback of a store: reader, stage-2 and device threads; camera = cdvr.Camera, path or function(frame, t); "
                   "policy = function(stats) or 'fixed'|'open_loop'|'closed_loop'; target_fps, variant, pipeline, cold, read_mbps, "
                   "out='frames/%04d.png' (capture: deterministic, never adapts; with policy= the policy's capture rule, else variant=, "
                   "min_psnr= or the best quality), or out='movie.mp4'|.webm|.mkv|.gif (one movie per run, cdvr.movie's codecs; "
                   "fps= (default target_fps or 25), crf=, preset=; progress=true: frames, fps and ETA on a terminal), frame=function(row, image), device='cl'|'cpu'|'auto' (default auto: cl when an OpenCL device opens), pace (default true with target_fps); "
                   "variant default: best quality; loop=true wraps past the last timestep (default: playback stops there, report.stopped "
                   "says so); brick_skip (default true: bricks the TF hides or the view misses are not read); "
                   "cache=true (budget_mb=, lod_error=; cl or cpu): through the brick cache, cache_async=true: never waits for a "
                   "brick (coarser resident levels meanwhile; rows bricks_coarser, bricks_pending); "
                   "distribute='time'|'bricks' (mpirun: frames or bricks shared by the ranks)");
    lcdvr_help_add(L, "p:run{frames=N, first=1}",
                   "plays N frames -> {fps=, wall_ms=, ranks=, capture=, frames={rows: frame, t, variant, rank, why (the decision in "
                   "force), read_ms .. render_ms, grid_ms (skip grid from the range tables), samples (cl: samples taken), composite_ms, wait_ms, frame_ms, bricks_read, bricks_skipped, decoded_share, reason (at group "
                   "starts), error}, median={...}} (mpirun: rank 0 gets every rank's rows)");
    lcdvr_help_add(L, "p:close()", "release the player's buffers and its OpenCL stream");
    return 0;
}
