/* lua/bind/l_window.c - cdvr.window{...}: a GLFW window that shows a scene (a volume or a store,
 * a transfer function, a camera, a method and device, a timestep) and re-renders it when any of
 * them changes (DESIGN.md section 11). It is a viewer: every frame is rendered by cdvr.render
 * (the CPU or OpenCL ray caster, or the EGL slicer) exactly as a script would, then shown as
 * pixels; the window only adds the overlay. Mouse drag orbits, the wheel zooms, left/right
 * step timesteps (home/end: first/last), up/down step variants, space plays and pauses, r
 * resets the view, m starts and stops recording the frames drawn to a movie (mp4, cdvr/movie.h),
 * p saves the next frame as a PNG (both without the overlay, at the window's size, named
 * cdvr-movie-/cdvr-shot-DATE-TIME in the working directory, the path printed), Esc or q
 * closes. What it shares with the player (policy stats, callback
 * budget, default variant and device) is the scene contract of l_scene.c.
 *
 * A window holds references (user values) to the volume, store, TF, camera and policy it
 * shows, so they live as long as it does. Open windows are kept in the registry until closed
 * (a window on screen does not vanish with its last Lua reference); the console drives them
 * between input lines with lcdvr_window_tick, a script with w:frame().
 */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>

#include "cdvr/gl.h"
#include "cdvr/movie.h"
#include "cdvr/player.h"
#include "cdvr/refine.h"
#include "cdvr/timing.h"
#include "lcdvr.h"

#define LCDVR_WINDOW "cdvr.Window"
#define WINDOWS_KEY "cdvr.windows" /* registry: {window = true} for every open window */
#define MAX_EVENTS 64
#define SHOT_SCALE_MAX 8 /* screenshots: at most 8 times the window's size */

/* User values of the window userdata. */
/* UV_RENDER: the render options set for the method (its own options, the scene keys it
 * honours, the look), handed to cdvr.render as they are. */
enum { UV_VOLUME = 1, UV_STORE, UV_TF, UV_CAMERA, UV_FRAME, UV_POLICY, UV_CAMERA_FN, UV_RENDER,
       UV_COUNT = UV_RENDER };

/* The box of a scene (dims and index-to-world geometry): a new scene with another box
 * re-frames the camera. */
typedef struct scene_box {
    int set;
    size_t dims[3];
    double spacing[3], origin[3], direction[9];
} scene_box;

typedef struct lwindow {
    cdvr_window *win;          /* NULL once closed */
    int overlay, playing, dirty;
    const cdvr_render_method *method; /* renders the scene (cdvr/method.h) */
    int device;                /* cdvr_device_kind; -1: the method's default device */
    int quit;                  /* Esc or q pressed: closes like the close button */
    long t;                    /* timestep shown, from 1 */
    int variant;               /* store scenes: variant shown, from 0 */
    long frame_t;              /* store scenes: first timestep (from 1) of the chunk group
                                  decoded into UV_FRAME, 0 for none */
    long frame_count;          /* its timesteps */
    int frame_variant;
    cdvr_frame_row frame_share;/* each frame's share of that group's read, unzip and decode */
    double fps;                /* playback pace in timesteps per second, 0: as fast as it renders */
    double last_step_ms;
    double last_frame_ms, last_render_ms; /* the last frame drawn: its whole time, its render */
    lcdvr_limits limits;       /* budget of the policy and camera callbacks: callback_limit,
                                  callback_memory */
    double min_psnr;           /* the policy's quality floor (stats.min_psnr), NaN: none */
    size_t frames;             /* frames drawn (the camera callback's frame number) */
    int decided;               /* the policy chose the variant for the next frame's group */
    scene_box box;             /* of the scene shown */
    cdvr_frame_row rows[LCDVR_POLICY_ROWS]; /* store scenes: the last frames, oldest first */
    int nrows;
    char reason[160];          /* why the variant shown was chosen */
    char error[CDVR_ERRMSG_MAX]; /* the last frame's error, reported once */
    /* 'm' records the frames drawn (without the overlay) to a movie, 'p' saves the next one as
     * a PNG; both in the working directory, their paths printed (cdvr/movie.h) */
    cdvr_movie *movie;
    char movie_path[64], shot_path[64];
    int shot_pending, shots;
    int shot_scale;            /* screenshot_scale=: 'p' renders the shot at this many times the
                                  window's size (1: the frame shown) */
    /* a store scene with cache=true renders through the brick cache, coarse first while the
     * camera moves (cdvr/refine.h) */
    cdvr_refine refine;
    double moving_lod;         /* moving_lod=: lod_error while moving, -1: 4 * max(lod_error, 1) */
    double settle_ms;          /* settle_ms=: still this long, then refine */
    int cached_frame;          /* the last frame rendered the store through the cache */
    double frame_lod;          /* its lod_error (what render_scene passes) */
} lwindow;

static lwindow *towindow(lua_State *L, int idx)
{
    return (lwindow *)luaL_checkudata(L, idx, LCDVR_WINDOW);
}

static lwindow *checkwindow(lua_State *L, int idx)
{
    lwindow *w = towindow(L, idx);
    if (!w->win)
        luaL_error(L, "attempt to use a closed window");
    return w;
}

/* Pushes field `name` of the cdvr table. */
static void push_cdvr_function(lua_State *L, const char *name)
{
    luaL_getsubtable(L, LUA_REGISTRYINDEX, LUA_LOADED_TABLE);
    lua_getfield(L, -1, "cdvr");
    lua_getfield(L, -1, name);                    /* loaded, cdvr, fn */
    lua_replace(L, -3);
    lua_pop(L, 1);
}

/* ---- the scene ------------------------------------------------------------------------- */

static const cdvr_store *scene_store(lua_State *L, int w_idx)
{
    const cdvr_store *st = NULL;
    if (lua_getiuservalue(L, w_idx, UV_STORE) == LUA_TUSERDATA)
        st = lcdvr_checkstore(L, -1);
    lua_pop(L, 1);
    return st;
}

/* Timesteps of the scene (0: no scene). */
static size_t scene_timesteps(lua_State *L, int w_idx)
{
    size_t n = 0;
    if (lua_getiuservalue(L, w_idx, UV_VOLUME) == LUA_TUSERDATA)
        n = lcdvr_checkvolume(L, -1)->timesteps;
    lua_pop(L, 1);
    const cdvr_store *st = scene_store(L, w_idx);
    return n ? n : st ? cdvr_store_get_info(st)->timesteps : 0;
}

static void push_render_options(lua_State *L, int w_idx);

/* A store scene whose render options ask for the brick cache (cache=true) with a method that
 * renders stores: the window renders the store itself (cdvr.render(st, ...)), coarse first
 * while the camera moves, instead of decoding chunk groups. */
static int scene_cached(lua_State *L, int w_idx, const lwindow *w)
{
    int volume = lua_getiuservalue(L, w_idx, UV_VOLUME) == LUA_TUSERDATA;
    lua_pop(L, 1);
    if (volume || !w->method->render_store || !scene_store(L, w_idx))
        return 0;
    push_render_options(L, w_idx);
    lua_getfield(L, -1, "cache");
    int on = lua_toboolean(L, -1);
    lua_pop(L, 2);
    return on;
}

/* The lod_error the render options ask for (the method's default 1 when not set). */
static double requested_lod(lua_State *L, int w_idx)
{
    push_render_options(L, w_idx);
    lua_getfield(L, -1, "lod_error");
    double lod = lua_isnumber(L, -1) ? lua_tonumber(L, -1) : 1.0;
    lua_pop(L, 2);
    return lod;
}

/* Pushes the volume to render and sets *t (from 1) to its frame: the scene's volume at w->t,
 * or, for a store, the chunk group of the variant shown that holds timestep w->t, decoded
 * once for all its timesteps (lcdvr_store_decode_group: read, unzip and decode timed apart;
 * *share gets this frame's share of them, as the player's rows). Pushes nil when there is no
 * scene. */
static void push_scene_volume(lua_State *L, int w_idx, lwindow *w, long *t, cdvr_frame_row *share)
{
    memset(share, 0, sizeof *share);
    *t = 1;
    if (lua_getiuservalue(L, w_idx, UV_VOLUME) == LUA_TUSERDATA) {
        *t = w->t;
        return;
    }
    lua_pop(L, 1);
    const cdvr_store *st = scene_store(L, w_idx);
    if (!st) {
        lua_pushnil(L);
        return;
    }
    if (scene_cached(L, w_idx, w)) { /* the store itself, timestep w->t */
        *t = w->t;
        lua_getiuservalue(L, w_idx, UV_STORE);
        return;
    }
    if (w->frame_t == 0 || w->t < w->frame_t || w->t >= w->frame_t + w->frame_count ||
        w->frame_variant != w->variant) {
        cdvr_volume *vol;
        cdvr_error err;
        size_t t0;
        if (lcdvr_store_decode_group(st, (size_t)w->variant, (size_t)w->t - 1, &vol, &t0,
                                     &w->frame_share, &err) != CDVR_OK)
            lcdvr_raise(L, &err);
        lcdvr_pushvolume(L, vol);
        lua_setiuservalue(L, w_idx, UV_FRAME);
        w->frame_t = (long)t0 + 1;
        w->frame_count = (long)vol->timesteps;
        w->frame_variant = w->variant;
    }
    *share = w->frame_share;
    *t = w->t - w->frame_t + 1;
    lua_getiuservalue(L, w_idx, UV_FRAME);
}

/* Calls the camera function (camera=function(frame, t)) for the frame about to be drawn under
 * the callback budget and applies its result to cam; raises its error. */
static void call_camera_fn(lua_State *L, int w_idx, lwindow *w, cdvr_camera *cam)
{
    if (lua_getiuservalue(L, w_idx, UV_CAMERA_FN) == LUA_TNIL) {
        lua_pop(L, 1);
        return;
    }
    lua_pushinteger(L, (lua_Integer)w->frames + 1);
    lua_pushinteger(L, w->t);
    cdvr_error err;
    cdvr_status s = lcdvr_call_callback(L, 2, 1, &w->limits, "window: camera", &err);
    if (s == CDVR_OK) {
        cdvr_camera next = *cam;
        s = lcdvr_camera_result(L, -1, &next, &err);
        lua_pop(L, 1);
        if (s == CDVR_OK)
            *cam = next;
    }
    if (s != CDVR_OK) {
        w->playing = 0;
        lcdvr_raise(L, &err);
    }
}

/* The window's camera, sized to the framebuffer: the one set, else cdvr.orbit_camera of the
 * volume at vol_idx, moved by the camera function when there is one. Returns it (owned by the
 * window's user value). */
static cdvr_camera *scene_camera(lua_State *L, int w_idx, lwindow *w, int vol_idx, int width,
                                 int height)
{
    if (lua_getiuservalue(L, w_idx, UV_CAMERA) != LUA_TUSERDATA) {
        lua_pop(L, 1);
        push_cdvr_function(L, "orbit_camera");
        lua_pushvalue(L, vol_idx);
        lua_createtable(L, 0, 2);
        lua_pushinteger(L, width);
        lua_setfield(L, -2, "width");
        lua_pushinteger(L, height);
        lua_setfield(L, -2, "height");
        lua_call(L, 2, 1);                        /* camera */
        lua_pushvalue(L, -1);
        lua_setiuservalue(L, w_idx, UV_CAMERA);
    }
    cdvr_camera *cam = lcdvr_checkcamera(L, -1);
    lua_pop(L, 1);
    cam->width = width;
    cam->height = height;
    call_camera_fn(L, w_idx, w, cam);
    return cam;
}

/* ---- options (cdvr.window{...} and w:set{...}) ------------------------------------------ */

/* Who reads the options table at idx, for messages: cdvr.window{...} (idx 1) or w:set{...}. */
static const char *opts_what(int idx)
{
    return idx == 1 ? "cdvr.window" : "w:set";
}

/* The window's own keys; the method's options, the scene keys it honours and the look keys
 * come from the method table (lcdvr_method_checkoptions). */
static const char *const window_keys[] = {"volume", "store", "tf", "camera", "method", "device",
                                          "overlay", "t", "variant", "playing", "fps", "policy",
                                          "min_psnr", "callback_limit", "callback_memory", "width", "height", "title",
                                          "screenshot_scale", "moving_lod", "settle_ms", NULL};

/* The device the window renders on: the one set, else the method's default (the scene
 * contract's rule, cdvr_render_method_default_device). */
static cdvr_device_kind window_device(lua_State *L, const lwindow *w)
{
    if (w->device >= 0)
        return (cdvr_device_kind)w->device;
    return cdvr_render_method_default_device(w->method, lcdvr_render_ctx(L));
}

/* The render-options table (UV_RENDER) pushed; made empty on first use. */
static void push_render_options(lua_State *L, int w_idx)
{
    if (lua_getiuservalue(L, w_idx, UV_RENDER) == LUA_TTABLE)
        return;
    lua_pop(L, 1);
    lua_newtable(L);
    lua_pushvalue(L, -1);
    lua_setiuservalue(L, w_idx, UV_RENDER);
}

/* method= and device=, then every option of the table at idx that the method takes into the
 * render options; a new method drops the options it does not take and a device it lacks. The
 * result is checked now (params and look), so a bad value raises here, not at the next frame. */
static void set_render(lua_State *L, int w_idx, int idx, lwindow *w, const cdvr_render_method *m)
{
    push_render_options(L, w_idx);                /* render */
    int render = lua_gettop(L);
    if (m != w->method) {
        lua_pushnil(L);
        while (lua_next(L, render)) {             /* render, key, value */
            lua_pop(L, 1);
            if (lua_type(L, -1) == LUA_TSTRING && !lcdvr_method_takes(m, lua_tostring(L, -1))) {
                lua_pushvalue(L, -1);
                lua_pushnil(L);
                lua_rawset(L, render);            /* clearing a field during lua_next is allowed */
            }
        }
        if (w->device >= 0 && !cdvr_render_method_supports(m, (cdvr_device_kind)w->device))
            w->device = -1;
        w->method = m;
    }
    if (lua_getfield(L, idx, "device") != LUA_TNIL)
        w->device = (int)lcdvr_method_device(L, idx, m, opts_what(idx));
    lua_pop(L, 1);
    lua_pushnil(L);
    while (lua_next(L, idx)) {                    /* render, key, value */
        if (lua_type(L, -2) == LUA_TSTRING && lcdvr_method_takes(m, lua_tostring(L, -2))) {
            lua_pushvalue(L, -2);
            lua_insert(L, -2);                    /* render, key, key, value */
            lua_rawset(L, render);
        } else {
            lua_pop(L, 1);
        }
    }
    cdvr_method_params params;
    cdvr_look look;
    lcdvr_method_params(L, render, m, opts_what(idx), &params);
    lcdvr_read_look(L, render, m, opts_what(idx), &look);
    lua_pop(L, 1);
}

/* Turns annotation `what` (colorbar, axes) of the render options' annotate= on or off. */
static void toggle_annotation(lua_State *L, int w_idx, lwindow *w, const char *what)
{
    push_render_options(L, w_idx);                /* render */
    int type = lua_getfield(L, -1, "annotate");   /* render, annotate */
    if (type != LUA_TTABLE) {
        int all = type == LUA_TBOOLEAN && lua_toboolean(L, -1);
        lua_pop(L, 1);
        lua_createtable(L, 0, 2);
        lua_pushboolean(L, all);
        lua_setfield(L, -2, "colorbar");
        lua_pushboolean(L, all);
        lua_setfield(L, -2, "axes");
        lua_pushvalue(L, -1);
        lua_setfield(L, -3, "annotate");
    }
    lua_getfield(L, -1, what);                    /* render, annotate, on */
    int on = lua_toboolean(L, -1);
    lua_pop(L, 1);
    lua_pushboolean(L, !on);
    lua_setfield(L, -2, what);
    lua_pop(L, 2);
    w->dirty = 1;
}

/* A key for the method (its window_key hook): sets the option it names. */
static void method_key(lua_State *L, int w_idx, lwindow *w, int key)
{
    const cdvr_render_method *m = w->method;
    if (!m->window_key)
        return;
    push_render_options(L, w_idx);
    cdvr_method_params params;
    lcdvr_method_params(L, -1, m, "window", &params);
    const char *option;
    char value[64];
    if (m->window_key(&params, key, &option, value, sizeof value)) {
        if (strcmp(value, "true") == 0 || strcmp(value, "false") == 0)
            lua_pushboolean(L, value[0] == 't');
        else
            lua_pushstring(L, value);
        lua_setfield(L, -2, option);
        w->dirty = 1;
    }
    lua_pop(L, 1);
}

static void set_variant(lua_State *L, int idx, lwindow *w, const cdvr_store *st)
{
    int type = lua_getfield(L, idx, "variant");
    if (type == LUA_TNIL) {
        lua_pop(L, 1);
        return;
    }
    if (!st)
        lcdvr_error(L, "option 'variant' needs a store scene");
    size_t n = cdvr_store_get_info(st)->nvariants;
    int v = -1;
    if (type == LUA_TSTRING) {
        v = lcdvr_find_variant(L, -1, st);
        if (v < 0)
            lcdvr_error(L, "store %s has no variant %s", cdvr_store_path(st),
                        lcdvr_push_quoted(L, -1));
    } else if (lua_isinteger(L, -1)) {
        lua_Integer i = lua_tointeger(L, -1);
        if (i < 1 || (size_t)i > n)
            lcdvr_error(L, "variant %I outside 1..%I", (LUAI_UACINT)i, (LUAI_UACINT)n);
        v = (int)i - 1;
    } else {
        lcdvr_error(L, "option 'variant': name or index expected");
    }
    lua_pop(L, 1);
    w->variant = v;
    snprintf(w->reason, sizeof w->reason, "fixed: %s set by the user",
             cdvr_store_variant(st, (size_t)v)->name);
}

/* Records the box of the new scene; 1 when it differs from the one shown before. */
static int new_box(lwindow *w, const size_t dims[3], const double spacing[3],
                   const double origin[3], const double direction[9])
{
    scene_box *b = &w->box;
    int changed = !b->set || memcmp(b->dims, dims, sizeof b->dims) != 0 ||
                  memcmp(b->spacing, spacing, sizeof b->spacing) != 0 ||
                  memcmp(b->origin, origin, sizeof b->origin) != 0 ||
                  memcmp(b->direction, direction, sizeof b->direction) != 0;
    b->set = 1;
    memcpy(b->dims, dims, sizeof b->dims);
    memcpy(b->spacing, spacing, sizeof b->spacing);
    memcpy(b->origin, origin, sizeof b->origin);
    memcpy(b->direction, direction, sizeof b->direction);
    return changed;
}

/* volume= / store= (one replaces the other). A scene of another box (dims, spacing, origin,
 * direction) drops the camera, so the next frame frames it (cdvr.orbit_camera), unless the
 * same call sets camera= (applied after this). A store shows its best variant
 * (cdvr_store_best_variant, the player's default too) until variant= or a policy says.
 * Returns 1 when the call named a scene. */
static int set_scene(lua_State *L, int w_idx, int idx, lwindow *w)
{
    int reframe = 0, named = 0;
    if (lua_getfield(L, idx, "volume") != LUA_TNIL) {
        lcdvr_checkoption(L, -1, NULL, "volume", LCDVR_VOLUME);
        const cdvr_volume *vol = lcdvr_volume_header(L, -1);
        reframe = new_box(w, vol->dims, vol->spacing, vol->origin, vol->direction);
        named = 1;
        lcdvr_checkvolume(L, -1);
        lua_setiuservalue(L, w_idx, UV_VOLUME);
        lua_pushnil(L);
        lua_setiuservalue(L, w_idx, UV_STORE);
        w->frame_t = 0;
        w->nrows = 0;
        snprintf(w->reason, sizeof w->reason, "-");
    } else {
        lua_pop(L, 1);
    }
    if (lua_getfield(L, idx, "store") != LUA_TNIL) {
        lcdvr_checkoption(L, -1, NULL, "store", LCDVR_STORE);
        const cdvr_store *st = lcdvr_checkstore(L, -1);
        const cdvr_store_info *info = cdvr_store_get_info(st);
        reframe = new_box(w, info->dims, info->spacing, info->origin, info->direction);
        named = 1;
        lua_setiuservalue(L, w_idx, UV_STORE);
        lua_pushnil(L);
        lua_setiuservalue(L, w_idx, UV_VOLUME);
        w->frame_t = 0;
        w->nrows = 0;
        w->variant = cdvr_store_best_variant(st);
        snprintf(w->reason, sizeof w->reason, "best quality");
    } else {
        lua_pop(L, 1);
    }
    if (reframe) {
        lua_pushnil(L);
        lua_setiuservalue(L, w_idx, UV_CAMERA);
    }
    return named;
}

/* tf= a cdvr.TF, a preset name or a points table (through cdvr.tf) */
static void set_tf(lua_State *L, int w_idx, int idx)
{
    int type = lua_getfield(L, idx, "tf");
    if (type == LUA_TNIL) {
        lua_pop(L, 1);
        return;
    }
    if (type == LUA_TSTRING || type == LUA_TTABLE) {
        push_cdvr_function(L, "tf");
        lua_insert(L, -2);
        if (lua_pcall(L, 1, 1, 0) != LUA_OK)
            lcdvr_error(L, "option 'tf': %s", luaL_tolstring(L, -1, NULL));
    }
    lcdvr_checkoption(L, -1, NULL, "tf", LCDVR_TF);
    lua_setiuservalue(L, w_idx, UV_TF);
}

/* camera= a cdvr.Camera (copied: dragging in the window does not move the script's camera),
 * false for cdvr.orbit_camera of the scene, or a function(frame, t) (or a callable, such as a
 * cdvr.path) called before each frame as the player's camera callback, under the budget */
static void set_camera(lua_State *L, int w_idx, int idx)
{
    int type = lua_getfield(L, idx, "camera");
    if (type == LUA_TNIL) {
        lua_pop(L, 1);
        return;
    }
    int callable = type == LUA_TFUNCTION;
    if (!callable && type != LUA_TBOOLEAN && !luaL_testudata(L, -1, LCDVR_CAMERA) &&
        luaL_getmetafield(L, -1, "__call") != LUA_TNIL) {
        lua_pop(L, 1);
        callable = 1;
    }
    if (callable) {
        lua_setiuservalue(L, w_idx, UV_CAMERA_FN);
        return;
    }
    if (type == LUA_TBOOLEAN && !lua_toboolean(L, -1)) {
        lua_pushnil(L);
    } else {
        lcdvr_checkoption(L, -1, NULL, "camera", LCDVR_CAMERA);
        lcdvr_pushcamera(L, lcdvr_checkcamera(L, -1));
    }
    lua_setiuservalue(L, w_idx, UV_CAMERA);
    lua_pop(L, 1);
    lua_pushnil(L);
    lua_setiuservalue(L, w_idx, UV_CAMERA_FN);
}

/* policy= a function, a cdvr.policy name (through cdvr.policy.get), or false for none */
static void set_policy(lua_State *L, int w_idx, int idx)
{
    int type = lua_getfield(L, idx, "policy");
    if (type == LUA_TNIL) {
        lua_pop(L, 1);
        return;
    }
    if (type == LUA_TBOOLEAN && !lua_toboolean(L, -1)) {
        lua_pop(L, 1);
        lua_pushnil(L);
    }
    if (type == LUA_TSTRING) {
        push_cdvr_function(L, "policy");
        lua_getfield(L, -1, "get");
        lua_remove(L, -2);
        lua_insert(L, -2);
        if (lua_pcall(L, 1, 1, 0) != LUA_OK)
            lcdvr_error(L, "option 'policy': %s", luaL_tolstring(L, -1, NULL));
    }
    if (!lua_isfunction(L, -1) && !lua_isnil(L, -1))
        lcdvr_error(L, "option 'policy': policy function, name or false expected, got %s",
                   luaL_typename(L, -1));
    lua_setiuservalue(L, w_idx, UV_POLICY);
}

static void run_policy(lua_State *L, int w_idx, lwindow *w);

static void apply_options(lua_State *L, int w_idx, int idx, lwindow *w)
{
    const char *name = lcdvr_optstringfield(L, idx, "method", NULL);
    const cdvr_render_method *m = name ? lcdvr_method_lookup(L, name, opts_what(idx)) : w->method;
    lcdvr_method_checkoptions(L, idx, m, opts_what(idx), window_keys);
    int new_scene = set_scene(L, w_idx, idx, w);
    set_tf(L, w_idx, idx);
    set_camera(L, w_idx, idx);
    set_policy(L, w_idx, idx);
    set_render(L, w_idx, idx, w, m);
    lua_Integer limit = lcdvr_optintegerfield(L, idx, "callback_limit", w->limits.instructions);
    if (limit < 1 || limit > INT_MAX)
        lcdvr_error(L, "option 'callback_limit' = %I: must be 1..%d", (LUAI_UACINT)limit, INT_MAX);
    w->limits.instructions = limit;
    lua_Number mb = lcdvr_optnumberfield(L, idx, "callback_memory",
                                         (lua_Number)(w->limits.memory >> 20));
    if (!(mb >= 1 && mb <= 1 << 20))
        lcdvr_error(L, "option 'callback_memory' must be 1 .. %d MB", 1 << 20);
    w->limits.memory = (size_t)(mb * 1048576.0);
    int floor_type = lua_getfield(L, idx, "min_psnr"); /* a number, or false for none */
    if (floor_type == LUA_TBOOLEAN && !lua_toboolean(L, -1))
        w->min_psnr = NAN;
    else if (floor_type != LUA_TNIL && (!lua_isnumber(L, -1) || isnan(lua_tonumber(L, -1))))
        lcdvr_error(L, "option 'min_psnr': a number in dB or false expected");
    else if (floor_type != LUA_TNIL)
        w->min_psnr = lua_tonumber(L, -1);
    lua_pop(L, 1);
    lua_Integer shot_scale = lcdvr_optintegerfield(L, idx, "screenshot_scale", w->shot_scale);
    if (shot_scale < 1 || shot_scale > SHOT_SCALE_MAX)
        lcdvr_error(L, "option 'screenshot_scale' = %I: must be 1..%d", (LUAI_UACINT)shot_scale,
                    SHOT_SCALE_MAX);
    w->shot_scale = (int)shot_scale;
    double moving = lcdvr_optnumberfield(L, idx, "moving_lod", w->moving_lod);
    if (!(moving >= 0 || moving == -1) || moving > 1e12)
        lcdvr_error(L, "option 'moving_lod' = %f: pixels 0 .. 1e12 expected", moving);
    w->moving_lod = moving;
    double settle = lcdvr_optnumberfield(L, idx, "settle_ms", w->settle_ms);
    if (!(settle >= 0) || settle > 1e9)
        lcdvr_error(L, "option 'settle_ms' = %f: 0 .. 1e9 ms expected", settle);
    w->settle_ms = settle;
    w->overlay = lcdvr_optbooleanfield(L, idx, "overlay", w->overlay);
    w->playing = lcdvr_optbooleanfield(L, idx, "playing", w->playing);
    double fps = lcdvr_optnumberfield(L, idx, "fps", w->fps);
    if (!(fps >= 0.0) || !isfinite(fps))
        lcdvr_error(L, "option 'fps' = %f must be finite and >= 0", fps);
    w->fps = fps;
    set_variant(L, idx, w, scene_store(L, w_idx));
    size_t n = scene_timesteps(L, w_idx);
    /* a new scene keeps the timestep shown where it has it, else shows its last */
    lua_Integer t = lcdvr_optintegerfield(L, idx, "t", new_scene && n && (size_t)w->t > n ? (long)n : w->t);
    if (n && (t < 1 || (size_t)t > n))
        lcdvr_error(L, "option 't' = %I outside 1..%I", (LUAI_UACINT)t, (LUAI_UACINT)n);
    w->t = n ? (long)t : 1;
    w->dirty = 1;
    /* a new store or policy: the policy chooses the first group's variant, as in the player
     * (unless variant= says which) */
    int asked = 0;
    static const char *const decide_keys[] = {"store", "policy", "variant"};
    for (int i = 0; i < 3; i++) {
        int present = lua_getfield(L, idx, decide_keys[i]) != LUA_TNIL;
        lua_pop(L, 1);
        if (present)
            asked = i < 2 ? 1 : -1;
        if (asked < 0)
            break;
    }
    if (asked > 0)
        run_policy(L, w_idx, w);
}

/* ---- interaction ------------------------------------------------------------------------- */

/* v rotated by angle (radians) around the unit axis k (Rodrigues). */
static void rotate(double v[3], const double k[3], double angle)
{
    double c = cos(angle), s = sin(angle), kv = k[0] * v[0] + k[1] * v[1] + k[2] * v[2];
    double cross[3] = {k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2],
                       k[0] * v[1] - k[1] * v[0]};
    for (int i = 0; i < 3; i++)
        v[i] = v[i] * c + cross[i] * s + k[i] * kv * (1.0 - c);
}

/* Drag: turn the eye around the centre, dx around the up vector, dy around the right vector
 * (0.4 degrees per pixel), never over the poles. */
static void orbit(cdvr_camera *cam, double dx, double dy)
{
    const double per_pixel = 0.4 * 3.14159265358979323846 / 180.0;
    double f[3], u[3], r[3], up[3] = {cam->up[0], cam->up[1], cam->up[2]}, off[3];
    cdvr_camera_basis(cam, f, u, r);
    double len = sqrt(up[0] * up[0] + up[1] * up[1] + up[2] * up[2]);
    for (int i = 0; i < 3; i++) {
        up[i] /= len;
        off[i] = cam->eye[i] - cam->center[i];
    }
    rotate(off, up, -dx * per_pixel);
    rotate(r, up, -dx * per_pixel);
    double tilted[3] = {off[0], off[1], off[2]};
    rotate(tilted, r, -dy * per_pixel);
    double dist = sqrt(tilted[0] * tilted[0] + tilted[1] * tilted[1] + tilted[2] * tilted[2]);
    double along_up = (tilted[0] * up[0] + tilted[1] * up[1] + tilted[2] * up[2]) / dist;
    if (fabs(along_up) < 0.995)
        memcpy(off, tilted, sizeof off);
    for (int i = 0; i < 3; i++)
        cam->eye[i] = cam->center[i] + off[i];
}

static void zoom(cdvr_camera *cam, double steps)
{
    double scale = pow(0.9, steps);
    if (cam->orthographic) {
        cam->ortho_height *= scale;
        return;
    }
    for (int i = 0; i < 3; i++)
        cam->eye[i] = cam->center[i] + (cam->eye[i] - cam->center[i]) * scale;
}

static void step_time(lwindow *w, long delta, size_t n)
{
    if (!n)
        return;
    long t = w->t + delta;
    w->t = t < 1 ? 1 : (size_t)t > n ? (long)n : t;
    w->dirty = 1;
}

static int access_exists(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (f)
        fclose(f);
    return f != NULL;
}

/* "cdvr-KIND-YYYYmmdd-HHMMSS[-N].EXT" in the working directory. */
static void stamped_name(char *buf, size_t size, const char *kind, int n, const char *ext)
{
    char stamp[32];
    time_t now = time(NULL);
    struct tm tm;
    strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", localtime_r(&now, &tm));
    if (n > 0)
        snprintf(buf, size, "cdvr-%s-%s-%d.%s", kind, stamp, n, ext);
    else
        snprintf(buf, size, "cdvr-%s-%s.%s", kind, stamp, ext);
}

/* Stops a recording: the movie is committed and its path printed (or the failure). */
static void stop_recording(lwindow *w)
{
    if (!w->movie)
        return;
    long long n = (long long)cdvr_movie_frames(w->movie);
    cdvr_error err;
    if (cdvr_movie_close(w->movie, &err) == CDVR_OK)
        printf("cdvr: movie %s written (%lld frames)\n", w->movie_path, n);
    else
        fprintf(stderr, "cdvr: window: recording failed: %s\n", err.msg);
    fflush(stdout);
    w->movie = NULL;
}

/* 'm': starts recording to a new movie (mp4, at the playback fps or 25), or stops it. */
static void toggle_recording(lwindow *w)
{
    if (w->movie) {
        stop_recording(w);
        return;
    }
    stamped_name(w->movie_path, sizeof w->movie_path, "movie", 0, "mp4");
    for (int n = 1; n < 100 && access_exists(w->movie_path); n++)
        stamped_name(w->movie_path, sizeof w->movie_path, "movie", n, "mp4");
    cdvr_movie_opts o = cdvr_movie_defaults();
    o.fps = w->fps > 0 ? w->fps : 25;
    cdvr_error err;
    if (cdvr_movie_open(w->movie_path, &o, &w->movie, &err) != CDVR_OK) {
        fprintf(stderr, "cdvr: window: cannot record: %s\n", err.msg);
        w->movie = NULL;
        return;
    }
    printf("cdvr: recording to %s (m stops)\n", w->movie_path);
    fflush(stdout);
    w->dirty = 1;
}

/* Saves img as a screenshot: to path, or to a new cdvr-shot-... .png in the working directory
 * when path is NULL (w->shot_path then names it); the suffix chooses PNG or JPEG. */
static cdvr_status save_shot(lwindow *w, const cdvr_image *img, const char *path, cdvr_error *err)
{
    if (!path) {
        stamped_name(w->shot_path, sizeof w->shot_path, "shot", ++w->shots, "png");
        path = w->shot_path;
    }
    size_t n = strlen(path);
    int jpeg = (n > 4 && strcasecmp(path + n - 4, ".jpg") == 0) ||
               (n > 5 && strcasecmp(path + n - 5, ".jpeg") == 0);
    return jpeg ? cdvr_image_save_jpeg(img, path, 92, err) : cdvr_image_save_png(img, path, err);
}

/* The frame just rendered (img: without the overlay) into the recording and, at scale 1, the
 * screenshot ('p'; a larger scale is rendered again by draw). */
static void capture_frame(lwindow *w, const cdvr_image *img)
{
    cdvr_error err;
    if (w->movie && cdvr_movie_add_image(w->movie, img, &err) != CDVR_OK) {
        fprintf(stderr, "cdvr: window: recording stopped: %s\n", err.msg);
        cdvr_movie_abort(w->movie);
        w->movie = NULL;
    }
    if (!w->shot_pending || w->shot_scale > 1)
        return;
    w->shot_pending = 0;
    if (save_shot(w, img, NULL, &err) == CDVR_OK)
        printf("cdvr: screenshot %s\n", w->shot_path);
    else
        fprintf(stderr, "cdvr: window: screenshot failed: %s\n", err.msg);
    fflush(stdout);
}

static void handle_key(lua_State *L, int w_idx, lwindow *w, int key)
{
    size_t n = scene_timesteps(L, w_idx);
    const cdvr_store *st = scene_store(L, w_idx);
    switch (key) {
    case CDVR_KEY_LEFT: step_time(w, -1, n); w->playing = 0; break;
    case CDVR_KEY_RIGHT: step_time(w, 1, n); w->playing = 0; break;
    case CDVR_KEY_HOME: step_time(w, -(long)n, n); break;
    case CDVR_KEY_END: step_time(w, (long)n, n); break;
    case CDVR_KEY_SPACE: w->playing = !w->playing; w->last_step_ms = cdvr_now_ms(); break;
    case CDVR_KEY_ESCAPE:
    case CDVR_KEY_Q: w->quit = 1; break;
    case CDVR_KEY_R: /* the scene's default view (cdvr.orbit_camera) again */
        lua_pushnil(L);
        lua_setiuservalue(L, w_idx, UV_CAMERA);
        w->dirty = 1;
        break;
    case CDVR_KEY_UP:
    case CDVR_KEY_DOWN:
        if (st) {
            int nv = (int)cdvr_store_get_info(st)->nvariants;
            w->variant = (w->variant + (key == CDVR_KEY_UP ? nv - 1 : 1)) % nv;
            snprintf(w->reason, sizeof w->reason, "fixed: %s chosen with the arrow keys",
                     cdvr_store_variant(st, (size_t)w->variant)->name);
            lua_pushnil(L);
            lua_setiuservalue(L, w_idx, UV_POLICY); /* the user's choice overrides a policy */
            w->dirty = 1;
        }
        break;
    case 'm': /* start or stop recording */
        toggle_recording(w);
        break;
    case 'p': /* a screenshot of the next frame */
        w->shot_pending = 1;
        w->dirty = 1;
        break;
    case 'b': /* the colour bar, and 'a' the orientation letters, on and off */
    case 'a':
        toggle_annotation(L, w_idx, w, key == 'b' ? "colorbar" : "axes");
        break;
    default: /* other letters: the method's keys ('l' lod for slice, 'o' order for splat) */
        if (key >= 'a' && key <= 'z')
            method_key(L, w_idx, w, key);
        break;
    }
}

static void handle_events(lua_State *L, int w_idx, lwindow *w)
{
    cdvr_window_event ev[MAX_EVENTS];
    size_t n = cdvr_window_poll(w->win, ev, MAX_EVENTS);
    for (size_t i = 0; i < n; i++) {
        if (ev[i].type == CDVR_WINDOW_KEY) {
            handle_key(L, w_idx, w, ev[i].key);
            continue;
        }
        w->dirty = 1;
        if (ev[i].type == CDVR_WINDOW_RESIZE)
            continue;
        if (lua_getiuservalue(L, w_idx, UV_CAMERA) == LUA_TUSERDATA) {
            cdvr_camera *cam = lcdvr_checkcamera(L, -1);
            if (ev[i].type == CDVR_WINDOW_DRAG)
                orbit(cam, ev[i].dx, ev[i].dy);
            else
                zoom(cam, ev[i].dy);
        }
        lua_pop(L, 1);
    }
}

/* ---- playback and the policy ------------------------------------------------------------- */

/* At a group boundary of a store scene with a policy: the policy picks the variant. It gets
 * the player's stats (lcdvr_push_policy_stats, from the window's frame rows) and runs under
 * the same budget; an error stops playback and raises. */
static void run_policy(lua_State *L, int w_idx, lwindow *w)
{
    const cdvr_store *st = scene_store(L, w_idx);
    if (!st)
        return;
    size_t group = cdvr_player_group_length(st);
    if (group == 0 || (size_t)(w->t - 1) % group != 0)
        return;
    if (lua_getiuservalue(L, w_idx, UV_POLICY) != LUA_TFUNCTION) {
        lua_pop(L, 1);
        return;
    }
    lcdvr_policy_view view = {.t = (size_t)w->t - 1, .group = (size_t)(w->t - 1) / group,
                              .target_fps = w->fps, .min_psnr = w->min_psnr};
    lcdvr_push_policy_stats(L, st, &view, w->rows, (size_t)w->nrows);
    cdvr_error err;
    cdvr_status s = lcdvr_call_callback(L, 1, 2, &w->limits, "window: policy", &err);
    if (s == CDVR_OK)
        s = lcdvr_policy_result(L, st, &w->variant, w->reason, sizeof w->reason, &err);
    if (s != CDVR_OK) {
        w->playing = 0;
        lcdvr_raise(L, &err);
    }
    w->decided = 1;
}

/* Playing: the next timestep when its time has come (fps pacing, or every frame), looping. */
static void advance(lua_State *L, int w_idx, lwindow *w)
{
    size_t n = scene_timesteps(L, w_idx);
    if (!w->playing || n == 0)
        return;
    double now = cdvr_now_ms();
    if (w->fps > 0.0 && now - w->last_step_ms < 1000.0 / w->fps)
        return;
    w->last_step_ms = now;
    w->t = (size_t)w->t >= n ? 1 : w->t + 1;
    w->dirty = 1;
    run_policy(L, w_idx, w);
}

/* ---- drawing ------------------------------------------------------------------------------ */

/* The overlay: what is shown and how, with the last frame's time (ms) and the rate that time
 * gives (not the time since the frame before: an idle window keeps its figure), wrapped to
 * the window's width. */
static void overlay(lua_State *L, int w_idx, lwindow *w, uint8_t *rgba, int width, int height)
{
    static const uint8_t white[3] = {255, 255, 255};
    char line[400], timing[64];
    const cdvr_store *st = scene_store(L, w_idx);
    size_t n = scene_timesteps(L, w_idx);
    char how[96], state[48] = "";
    if (w->method->describe) {
        push_render_options(L, w_idx);
        cdvr_method_params params;
        lcdvr_method_params(L, -1, w->method, "window", &params);
        lua_pop(L, 1);
        state[0] = ' ';
        w->method->describe(&params, state + 1, sizeof state - 1);
    }
    snprintf(how, sizeof how, "%s (%s)%s", w->method->name,
             cdvr_device_name(window_device(L, w)), state);
    if (w->cached_frame) {
        size_t used = strlen(how);
        snprintf(how + used, sizeof how - used, " lod %g%s", w->frame_lod,
                 w->frame_lod != w->refine.lod_error ? " moving" : "");
    }
    double ms = w->last_frame_ms;
    snprintf(timing, sizeof timing, "%.1f ms = %.0f fps", ms, ms > 0.0 ? 1000.0 / ms : 0.0);
    if (!n)
        snprintf(line, sizeof line, "no scene: window:set{volume=v, tf=...} or window:set{store=st}");
    else if (st)
        snprintf(line, sizeof line, "t %ld/%zu%s  %s  %s  %s  %s", w->t, n,
                 w->playing ? " playing" : "", cdvr_store_variant(st, (size_t)w->variant)->name,
                 w->reason, how, timing);
    else
        snprintf(line, sizeof line, "t %ld/%zu%s  volume  %s  %s", w->t, n,
                 w->playing ? " playing" : "", how, timing);
    cdvr_overlay_lines(rgba, width, height, 6, 6, 2, line, white);
}

/* Records the frame just drawn: its time for the overlay and w:state(), and, for a store
 * scene, its row for the policy (cdvr_frame_row, as the player's: share holds its part of
 * the group's read, unzip and decode). */
static void note_frame(lwindow *w, int store_scene, const cdvr_frame_row *share,
                       double render_ms, double start)
{
    double now = cdvr_now_ms();
    w->last_frame_ms = now - start;
    w->last_render_ms = render_ms;
    size_t frame = w->frames++;
    if (!store_scene)
        return;
    if (w->nrows == LCDVR_POLICY_ROWS) {
        memmove(w->rows, w->rows + 1, (LCDVR_POLICY_ROWS - 1) * sizeof *w->rows);
        w->nrows--;
    }
    cdvr_frame_row *r = &w->rows[w->nrows++];
    *r = *share;
    r->frame = frame;
    r->t = (size_t)w->t - 1;
    r->variant = w->variant;
    r->render_ms = render_ms;
    r->frame_ms = now - start;
    r->interval_ms = r->frame_ms;
    r->status = CDVR_OK;
    r->group_start = w->decided;
    if (w->decided)
        snprintf(r->reason, sizeof r->reason, "%s", w->reason);
    w->decided = 0;
}

/* Renders the scene through cdvr.render and shows it (with the overlay); raises on error.
 * Stack: the window at w_idx; leaves the stack as it found it. */
/* cdvr.render of the scene's volume (at vol_idx; timestep t of it) with the window's TF, method,
 * device and render options through camera cam; pushes the image. */
static void render_scene(lua_State *L, int w_idx, lwindow *w, int vol_idx, long t,
                         const cdvr_camera *cam)
{
    push_cdvr_function(L, "render");
    lua_pushvalue(L, vol_idx);
    lua_createtable(L, 0, 8);                     /* render, volume, opts */
    if (lua_getiuservalue(L, w_idx, UV_TF) != LUA_TUSERDATA) {
        lua_pop(L, 1);
        lua_pushliteral(L, "grayscale");
    }
    lua_setfield(L, -2, "tf");
    lcdvr_pushcamera(L, cam);
    lua_setfield(L, -2, "camera");
    lua_pushstring(L, w->method->name);
    lua_setfield(L, -2, "method");
    lua_pushinteger(L, t);
    lua_setfield(L, -2, "t");
    lua_pushstring(L, cdvr_device_name(window_device(L, w)));
    lua_setfield(L, -2, "device");
    int opts = lua_gettop(L);
    push_render_options(L, w_idx);                /* ..., opts, render */
    lua_pushnil(L);
    while (lua_next(L, -2)) {                     /* ..., opts, render, key, value */
        lua_pushvalue(L, -2);
        lua_insert(L, -2);
        lua_rawset(L, opts);
    }
    lua_pop(L, 1);                                /* render, volume, opts */
    const cdvr_store *st = luaL_testudata(L, vol_idx, LCDVR_STORE) ? scene_store(L, w_idx) : NULL;
    if (st) { /* the store through the cache (scene_cached) */
        lua_pushstring(L, cdvr_store_variant(st, (size_t)w->variant)->name);
        lua_setfield(L, opts, "variant");
        lua_pushnumber(L, w->frame_lod);
        lua_setfield(L, opts, "lod_error");
    }
    lua_call(L, 2, 1);                            /* image */
}

/* The lod_error of the frame of camera cam drawn now (cdvr/refine.h): moving_lod while the
 * camera moves, the requested one once it is still. */
static double refine_lod(lua_State *L, int w_idx, lwindow *w, const cdvr_camera *cam)
{
    double lod = requested_lod(L, w_idx);
    double moving = w->moving_lod >= 0 ? w->moving_lod : 4.0 * (lod > 1.0 ? lod : 1.0);
    cdvr_error err;
    if (cdvr_refine_configure(&w->refine, lod, moving < lod ? lod : moving, w->settle_ms,
                              &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    return cdvr_refine_frame(&w->refine, cam, cdvr_now_ms());
}

/* The scene through cam at scale times its size (no overlay), pushed as an image. */
static const cdvr_image *render_scaled(lua_State *L, int w_idx, lwindow *w, int vol_idx, long t,
                                       const cdvr_camera *cam, int scale)
{
    cdvr_camera big = *cam;
    big.width = cam->width * scale;
    big.height = cam->height * scale;
    render_scene(L, w_idx, w, vol_idx, t, &big);
    return lcdvr_checkimage(L, -1);
}

static void draw(lua_State *L, int w_idx, lwindow *w)
{
    int top = lua_gettop(L);
    double start = cdvr_now_ms(), render_ms = 0.0;
    int width, height;
    cdvr_window_size(w->win, &width, &height);
    if (width <= 0 || height <= 0)
        return;
    long t;
    cdvr_frame_row share;
    push_scene_volume(L, w_idx, w, &t, &share); /* volume or nil */
    int vol_idx = lua_gettop(L);
    int store_scene = scene_store(L, w_idx) != NULL;
    uint8_t *rgba = NULL;
    if (lua_isnil(L, vol_idx)) {
        rgba = lua_newuserdatauv(L, (size_t)width * (size_t)height * 4, 0);
        for (size_t i = 0; i < (size_t)width * (size_t)height; i++) {
            rgba[4 * i] = rgba[4 * i + 1] = rgba[4 * i + 2] = 24;
            rgba[4 * i + 3] = 255;
        }
        w->shot_pending = 0; /* nothing to shoot */
    } else {
        cdvr_camera *cam = scene_camera(L, w_idx, w, vol_idx, width, height);
        w->cached_frame = scene_cached(L, w_idx, w);
        if (w->cached_frame)
            w->frame_lod = refine_lod(L, w_idx, w, cam);
        double render_start = cdvr_now_ms();
        render_scene(L, w_idx, w, vol_idx, t, cam); /* ..., image */
        render_ms = cdvr_now_ms() - render_start;
        const cdvr_image *img = lcdvr_checkimage(L, -1);
        capture_frame(w, img);
        rgba = lua_newuserdatauv(L, (size_t)img->width * (size_t)img->height * 4, 0);
        cdvr_image_to_rgba8(img, rgba);
        if (w->shot_pending) { /* 'p' with screenshot_scale > 1 */
            cdvr_error err;
            w->shot_pending = 0;
            w->frame_lod = w->refine.lod_error; /* a shot is never coarse */
            const cdvr_image *shot = render_scaled(L, w_idx, w, vol_idx, t, cam, w->shot_scale);
            if (save_shot(w, shot, NULL, &err) == CDVR_OK)
                printf("cdvr: screenshot %s (%dx%d)\n", w->shot_path, shot->width, shot->height);
            else
                fprintf(stderr, "cdvr: window: screenshot failed: %s\n", err.msg);
            fflush(stdout);
        }
    }
    note_frame(w, store_scene, &share, render_ms, start);
    if (w->overlay)
        overlay(L, w_idx, w, rgba, width, height);
    cdvr_error err;
    if (cdvr_window_show(w->win, rgba, width, height, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    w->dirty = 0;
    lua_settop(L, top);
}

/* The user closed the window: its close button, Esc or q. */
static int wants_close(const lwindow *w)
{
    return w->quit || cdvr_window_should_close(w->win);
}

/* One frame: events, playback, and a redraw if anything changed (force: always). */
static void frame(lua_State *L, int w_idx, lwindow *w, int force)
{
    handle_events(L, w_idx, w);
    if (wants_close(w))
        return;
    advance(L, w_idx, w);
    if (w->cached_frame && cdvr_refine_due(&w->refine, cdvr_now_ms()))
        w->dirty = 1; /* the camera stopped: the frame at the requested lod_error */
    if (force || w->dirty)
        draw(L, w_idx, w);
}

/* ---- open windows ------------------------------------------------------------------------ */

static void forget_window(lua_State *L, int w_idx)
{
    w_idx = lua_absindex(L, w_idx);
    lua_getfield(L, LUA_REGISTRYINDEX, WINDOWS_KEY);
    if (lua_istable(L, -1)) {
        lua_pushvalue(L, w_idx);
        lua_pushnil(L);
        lua_rawset(L, -3);
    }
    lua_pop(L, 1);
}

static int window_close(lua_State *L)
{
    lwindow *w = towindow(L, 1);
    stop_recording(w); /* closing the window ends a recording: the movie is kept */
    if (w->win) {
        cdvr_window_close(w->win);
        w->win = NULL;
        forget_window(L, 1);
    }
    for (int uv = 1; uv <= UV_COUNT; uv++) { /* let go of the scene */
        lua_pushnil(L);
        lua_setiuservalue(L, 1, uv);
    }
    return 0;
}

static int l_window(lua_State *L)
{
    if (lua_isnoneornil(L, 1)) {
        lua_settop(L, 0);
        lua_newtable(L);
    }
    luaL_checktype(L, 1, LUA_TTABLE);
    lcdvr_checkoptions(L, 1, "cdvr.window", window_keys);
    lua_Integer width = lcdvr_optintegerfield(L, 1, "width", 512);
    lua_Integer height = lcdvr_optintegerfield(L, 1, "height", 512);
    luaL_argcheck(L, width >= 1 && width <= 16384 && height >= 1 && height <= 16384, 1,
                  "width and height must be 1..16384");
    const char *title = lcdvr_optstringfield(L, 1, "title", "cdvr");
    lwindow *w = (lwindow *)lua_newuserdatauv(L, sizeof *w, UV_COUNT);
    memset(w, 0, sizeof *w);
    w->overlay = 1;
    w->shot_scale = 1;
    w->t = 1;
    w->method = cdvr_render_method_find("raycast");
    w->device = -1;
    w->limits.instructions = LCDVR_CALLBACK_LIMIT;
    w->limits.memory = (size_t)LCDVR_CALLBACK_MEMORY_MB << 20;
    w->min_psnr = NAN;
    w->moving_lod = -1;
    w->settle_ms = 250;
    cdvr_refine_init(&w->refine, 1, 4, w->settle_ms, NULL);
    snprintf(w->reason, sizeof w->reason, "-");
    luaL_setmetatable(L, LCDVR_WINDOW);
    int w_idx = lua_gettop(L);
    apply_options(L, w_idx, 1, w); /* before opening: bad options leave no window behind */
    w->device = (int)window_device(L, w); /* the scene contract's rule, as the player's */
    cdvr_error err;
    if (cdvr_window_open((int)width, (int)height, title, &w->win, &err) != CDVR_OK)
        return luaL_error(L, "cdvr.window: %s", err.msg);
    luaL_getsubtable(L, LUA_REGISTRYINDEX, WINDOWS_KEY);
    lua_pushvalue(L, w_idx);
    lua_pushboolean(L, 1);
    lua_rawset(L, -3);
    lua_pop(L, 1);
    frame(L, w_idx, w, 1);
    lua_settop(L, w_idx);
    return 1;
}

static int window_set(lua_State *L)
{
    lwindow *w = checkwindow(L, 1);
    luaL_checktype(L, 2, LUA_TTABLE);
    static const char *const not_here[] = {"width", "height", "title"};
    for (size_t i = 0; i < sizeof not_here / sizeof not_here[0]; i++)
        if (lua_getfield(L, 2, not_here[i]) != LUA_TNIL)
            luaL_error(L, "w:set: '%s' is fixed when the window opens (resize the window instead)",
                       not_here[i]);
        else
            lua_pop(L, 1);
    apply_options(L, 1, 2, w);
    return 0;
}

/* w:frame() -> true, or false once the user closed the window (it is then closed). */
static int window_frame(lua_State *L)
{
    lwindow *w = checkwindow(L, 1);
    lua_settop(L, 1);
    frame(L, 1, w, 1);
    if (wants_close(w)) {
        window_close(L);
        lua_pushboolean(L, 0);
        return 1;
    }
    lua_pushboolean(L, 1);
    return 1;
}

/* w:read() -> the framebuffer shown last, as an opaque image. */
static int window_read(lua_State *L)
{
    lwindow *w = checkwindow(L, 1);
    int width, height;
    const uint8_t *px = cdvr_window_pixels(w->win, &width, &height);
    if (!px)
        return luaL_error(L, "w:read: nothing shown yet (call w:frame())");
    cdvr_image *img;
    cdvr_error err;
    if (cdvr_image_create(width, height, &img, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    size_t n = (size_t)width * (size_t)height;
    for (size_t i = 0; i < n; i++) {
        for (int c = 0; c < 3; c++)
            img->rgba[4 * i + c] = (float)px[4 * i + c] / 255.0f;
        img->rgba[4 * i + 3] = 1.0f;
    }
    lcdvr_pushimage(L, img);
    return 1;
}

/* w:screenshot([path] [, {scale=}]) -> path: the scene shown (the timestep, camera, TF and
 * annotations of the window, without the overlay) rendered at scale (1..SHOT_SCALE_MAX,
 * default screenshot_scale=) times the window's size and saved as PNG, or JPEG for .jpg; path
 * defaults to a new cdvr-shot-... .png in the working directory. */
static int window_screenshot(lua_State *L)
{
    static const char *const keys[] = {"scale", NULL};
    lwindow *w = checkwindow(L, 1);
    if (lua_istable(L, 2)) { /* w:screenshot{scale=}: no path */
        lua_settop(L, 2);
        lua_pushnil(L);
        lua_insert(L, 2);                        /* w, nil, opts */
    }
    const char *path = luaL_optstring(L, 2, NULL);
    lcdvr_checkoptions(L, 3, "w:screenshot", keys);
    lua_Integer scale = w->shot_scale;
    if (lua_istable(L, 3))
        scale = lcdvr_optintegerfield(L, 3, "scale", scale);
    if (scale < 1 || scale > SHOT_SCALE_MAX)
        return luaL_error(L, "w:screenshot: scale = %I: must be 1..%d", (LUAI_UACINT)scale,
                          SHOT_SCALE_MAX);
    lua_settop(L, 3);
    int width, height;
    cdvr_window_size(w->win, &width, &height);
    long t;
    cdvr_frame_row share;
    push_scene_volume(L, 1, w, &t, &share);      /* w, path, opts, volume or nil */
    if (lua_isnil(L, 4))
        return luaL_error(L, "w:screenshot: the window shows no volume or store (w:set{volume=})");
    if (width <= 0 || height <= 0)
        return luaL_error(L, "w:screenshot: the window has no size (minimised?)");
    cdvr_camera *cam = scene_camera(L, 1, w, 4, width, height);
    w->frame_lod = requested_lod(L, 1); /* a shot is never coarse */
    const cdvr_image *shot = render_scaled(L, 1, w, 4, t, cam, (int)scale);
    cdvr_error err;
    if (save_shot(w, shot, path, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_pushstring(L, path ? path : w->shot_path);
    return 1;
}

/* w:camera() -> a copy of the camera the window shows (after dragging and zooming). */
static int window_camera(lua_State *L)
{
    checkwindow(L, 1);
    if (lua_getiuservalue(L, 1, UV_CAMERA) != LUA_TUSERDATA)
        return 1; /* nil: no frame drawn yet */
    lcdvr_pushcamera(L, lcdvr_checkcamera(L, -1));
    return 1;
}

/* w:state() -> {t=, variant=, playing=, method=, device=, reason=, fps=, frame_ms=,
 * render_ms=, width=, height=}: fps is the last frame's rate (1000 / frame_ms). */
static int window_state(lua_State *L)
{
    lwindow *w = checkwindow(L, 1);
    const cdvr_store *st = scene_store(L, 1);
    int width, height;
    cdvr_window_size(w->win, &width, &height);
    lua_createtable(L, 0, 9);
    lua_pushinteger(L, w->t);
    lua_setfield(L, -2, "t");
    if (st) {
        lua_pushstring(L, cdvr_store_variant(st, (size_t)w->variant)->name);
        lua_setfield(L, -2, "variant");
    }
    lua_pushboolean(L, w->playing);
    lua_setfield(L, -2, "playing");
    lua_pushstring(L, w->method->name);
    lua_setfield(L, -2, "method");
    lua_pushstring(L, cdvr_device_name(window_device(L, w)));
    lua_setfield(L, -2, "device");
    lua_newtable(L);                              /* state, options: a copy of the render options */
    push_render_options(L, 1);
    lua_pushnil(L);
    while (lua_next(L, -2)) {                     /* state, options, render, key, value */
        lua_pushvalue(L, -2);
        lua_insert(L, -2);
        lua_rawset(L, -5);
    }
    lua_pop(L, 1);
    lua_setfield(L, -2, "options");
    lua_pushstring(L, w->reason);
    lua_setfield(L, -2, "reason");
    if (w->cached_frame) { /* the store through the brick cache: the last frame's lod_error */
        lua_pushnumber(L, w->frame_lod);
        lua_setfield(L, -2, "lod_error");
    }
    if (w->movie) {
        lua_pushstring(L, w->movie_path);
        lua_setfield(L, -2, "recording");
    }
    if (w->shot_path[0]) {
        lua_pushstring(L, w->shot_path);
        lua_setfield(L, -2, "screenshot");
    }
    lua_pushnumber(L, w->last_frame_ms > 0.0 ? 1000.0 / w->last_frame_ms : 0.0);
    lua_setfield(L, -2, "fps");
    lua_pushnumber(L, w->last_frame_ms);
    lua_setfield(L, -2, "frame_ms");
    lua_pushnumber(L, w->last_render_ms);
    lua_setfield(L, -2, "render_ms");
    lua_pushinteger(L, width);
    lua_setfield(L, -2, "width");
    lua_pushinteger(L, height);
    lua_setfield(L, -2, "height");
    return 1;
}

static int window_tostring(lua_State *L)
{
    lwindow *w = towindow(L, 1);
    if (!w->win) {
        lua_pushliteral(L, "cdvr.Window (closed)");
        return 1;
    }
    int width, height;
    cdvr_window_size(w->win, &width, &height);
    lua_pushfstring(L, "cdvr.Window %dx%d t %d (%p)", width, height, (int)w->t, (void *)w);
    return 1;
}

/* ---- the console's driver ----------------------------------------------------------------- */

static int tick_one(lua_State *L)
{
    lwindow *w = towindow(L, 1);
    int changed = lua_toboolean(L, 2);
    lua_settop(L, 1);
    if (!w->win)
        return 0;
    if (changed)
        w->dirty = 1;
    frame(L, 1, w, 0);
    if (wants_close(w))
        window_close(L);
    return 0;
}

int lcdvr_window_tick(lua_State *L, int changed, int *printed)
{
    int top = lua_gettop(L);
    if (lua_getfield(L, LUA_REGISTRYINDEX, WINDOWS_KEY) != LUA_TTABLE) {
        lua_settop(L, top);
        return -1;
    }
    int list = lua_gettop(L), n = 0;
    lua_newtable(L);                              /* windows, snapshot */
    lua_pushnil(L);
    while (lua_next(L, list)) {
        lua_pop(L, 1);
        lua_pushvalue(L, -1);
        lua_rawseti(L, list + 1, ++n);
    }
    int wait = n ? 30 : -1;
    for (int i = 1; i <= n; i++) {
        lua_pushcfunction(L, tick_one);
        lua_rawgeti(L, list + 1, i);
        lwindow *w = towindow(L, -1);
        lua_pushboolean(L, changed);
        if (lua_pcall(L, 2, 0, 0) != LUA_OK) {
            const char *msg = lua_tostring(L, -1);
            if (msg && strcmp(msg, w->error) != 0) {
                fprintf(stderr, "\ncdvr: window: %s\n", msg);
                *printed = 1;
            }
            snprintf(w->error, sizeof w->error, "%s", msg ? msg : "error");
            w->dirty = 0;   /* shown once; the next change tries again */
            w->playing = 0;
            lua_pop(L, 1);
        } else {
            w->error[0] = '\0';
        }
        if (w->win && w->playing)
            wait = 1;
    }
    lua_settop(L, top);
    return wait;
}

int lcdvr_window_console(lua_State *L)
{
    cdvr_error err;
    if (!cdvr_window_available(&err)) {
        fprintf(stderr, "cdvr: %s: console only\n", err.msg);
        return 0;
    }
    lua_pushcfunction(L, l_window);
    lua_createtable(L, 0, 1);
    lua_pushliteral(L, "cdvr console");
    lua_setfield(L, -2, "title");
    if (lua_pcall(L, 1, 1, 0) != LUA_OK) {
        fprintf(stderr, "cdvr: no window (%s): console only\n", lua_tostring(L, -1));
        lua_pop(L, 1);
        return 0;
    }
    lua_setglobal(L, "window");
    fprintf(stderr, "cdvr: window open as `window`: window:set{volume=v, tf=\"ct_bone\"} shows a scene\n");
    return 1;
}

static const luaL_Reg window_methods[] = {
    {"set", window_set},       {"frame", window_frame}, {"read", window_read},
    {"camera", window_camera}, {"state", window_state}, {"close", window_close},
    {"screenshot", window_screenshot},
    {NULL, NULL}};

static const luaL_Reg window_meta[] = {
    {"__gc", window_close}, {"__close", window_close}, {"__tostring", window_tostring},
    {NULL, NULL}};

static const luaL_Reg window_funcs[] = {{"window", l_window}, {NULL, NULL}};

int lcdvr_open_window(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_WINDOW, window_methods, window_meta);
    lcdvr_setfuncs(L, window_funcs);
    lcdvr_help_add(L, "cdvr.window{volume= | store=, tf=, camera=, method=, device=, overlay=, t=, variant=, ...}",
                   "open a window showing the scene (needs a display and GL); more keys: lod, step, "
                   "playing, fps, policy, min_psnr, callback_limit, callback_memory, screenshot_scale, width, height, title, "
                   "moving_lod, settle_ms (a store with cache=true: coarse while the camera moves); camera = cdvr.Camera, false "
                   "(frame the scene) or function(frame, t); defaults as cdvr.player: the store's best "
                   "variant, device cl when OpenCL has a device; drag orbits, wheel zooms, left/right "
                   "step t, up/down step variants, space plays, r resets the view, m records a movie (again: stops; the path is printed), "
                   "p saves a screenshot PNG (both without the overlay; screenshot_scale= renders it larger), Esc or q closes");
    lcdvr_help_add(L, "w:screenshot([path] [, {scale=}])",
                   "render the scene shown (no overlay) at scale (1..8) times the window's size to a PNG (.jpg: JPEG); returns the path");
    lcdvr_help_add(L, "w:set{...}", "change the window's scene (any cdvr.window key but width, height, title)");
    lcdvr_help_add(L, "w:frame()", "process events and draw one frame now; false once the user closed it");
    lcdvr_help_add(L, "w:read()", "the window's framebuffer (last frame shown) as an image");
    lcdvr_help_add(L, "w:camera()", "a copy of the camera the window shows (after dragging and zooming)");
    lcdvr_help_add(L, "w:state()", "{t=, variant=, playing=, method=, device=, reason=, fps=, width=, height=}");
    lcdvr_help_add(L, "w:close()", "close the window");
    return 0;
}
