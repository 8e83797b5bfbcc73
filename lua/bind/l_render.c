/* lua/bind/l_render.c - cdvr.render(volume or store, {...}): reads the scene (TF over the
 * frame's value window, camera, common options), then renders through the method table
 * (cdvr/method.h, l_method.c): the method named by method= on its device, never a branch on
 * which method it is. */
#include "cdvr/method.h"
#include "cdvr/render.h"
#include "lcdvr.h"

#include <string.h>
#include <time.h>

/* Frame t (from 0) of vol as a u8 volume, and the value window its codes span (volume.h):
 * vol itself when it is u8, else that one frame quantized over the series' window, which is
 * computed once and cached in vol (pushed as a Lua volume so an error cannot leak it). */
static const cdvr_volume *u8_frame(lua_State *L, cdvr_volume *vol, size_t *t, double window[2])
{
    cdvr_volume_window(vol, window);
    if (vol->type == CDVR_TYPE_U8)
        return vol;
    cdvr_volume *frame = NULL, *q = NULL;
    cdvr_error err;
    if (cdvr_volume_slice_time(vol, *t, 1, &frame, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    cdvr_status st = cdvr_volume_quantize(frame, window[0], window[1], &q, NULL, &err);
    cdvr_volume_free(frame);
    if (st != CDVR_OK)
        lcdvr_raise(L, &err);
    lcdvr_pushvolume(L, q);
    *t = 0;
    return q;
}

/* One warning per preset, data range and Lua state when an absolute preset shows nothing of the data's
 * range (tf.h: cdvr_tf_misses_window): the min..max of frame t of u8 when given, else the
 * window. */
static void warn_if_preset_misses(lua_State *L, const cdvr_tf *tf, const double window[2],
                                  const cdvr_volume *u8, size_t t)
{
    if (!tf->name[0] || tf->normalized)
        return;
    double range[2] = {window[0], window[1]};
    cdvr_error err;
    if (u8 && cdvr_tf_percentile_window(u8, t, window, 0.0, 1.0, range, &err) != CDVR_OK)
        range[0] = window[0], range[1] = window[1];
    if (!cdvr_tf_misses_window(tf, range[0], range[1]))
        return;
    if (lua_getfield(L, LUA_REGISTRYINDEX, "cdvr.preset_warned") != LUA_TTABLE) {
        lua_pop(L, 1);
        lua_newtable(L);
        lua_pushvalue(L, -1);
        lua_setfield(L, LUA_REGISTRYINDEX, "cdvr.preset_warned");
    }
    const char *key = lua_pushfstring(L, "%s %f %f", tf->name, range[0], range[1]);
    if (lua_getfield(L, -2, key) == LUA_TNIL) {
        lcdvr_warn(L, "cdvr.render: preset '%s' (%f .. %f) shows nothing of the data's range "
                      "%f .. %f: the image is empty",
                   tf->name, tf->points[0].value, tf->points[tf->npoints - 1].value, range[0],
                   range[1]);
        lua_pushboolean(L, 1);
        lua_setfield(L, -4, key);
    }
    lua_pop(L, 3);
}

/* The TF in opts->tf with its table built over window (tf.h), pushed as a new cdvr.TF that
 * replaces the caller's in stack slot `slot`; u8 (frame t) is the data for range="auto" (may
 * be NULL when the TF is not auto_range). */
static void window_tf(lua_State *L, cdvr_render_opts *o, const double window[2], int slot,
                      const cdvr_volume *u8, size_t t)
{
    cdvr_tf *tf = lcdvr_pushtf(L, o->tf);
    cdvr_error err;
    if (cdvr_tf_apply_window(tf, window, u8, t, NULL, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    warn_if_preset_misses(L, tf, window, u8, t);
    lua_replace(L, slot);
    o->tf = tf;
}

static void read_background(lua_State *L, int idx, float bg[4])
{
    bg[0] = bg[1] = bg[2] = 0.0f;
    bg[3] = 1.0f;
    if (lua_getfield(L, idx, "background") == LUA_TNIL) {
        lua_pop(L, 1);
        return;
    }
    lua_Integer n = lua_istable(L, -1) ? luaL_len(L, -1) : 0;
    if (n != 3 && n != 4)
        luaL_error(L, "cdvr.render: option 'background': {r, g, b [, a]} expected");
    for (lua_Integer i = 1; i <= n; i++) {
        lua_geti(L, -1, i);
        int ok;
        lua_Number c = lua_tonumberx(L, -1, &ok);
        if (!ok || !(c >= 0.0 && c <= 1.0))
            luaL_error(L, "cdvr.render: option 'background': entries must be numbers in [0, 1]");
        bg[i - 1] = (float)c;
        lua_pop(L, 1);
    }
    lua_pop(L, 1);
}

/* A TF from opts.tf: a cdvr.TF, a preset name or a points table. */
static const cdvr_tf *read_tf(lua_State *L, int idx)
{
    int type = lua_getfield(L, idx, "tf");
    if (type == LUA_TNIL)
        luaL_error(L, "cdvr.render: option 'tf' (a cdvr.TF) is required");
    if (type == LUA_TSTRING || type == LUA_TTABLE) {
        lua_getfield(L, lua_upvalueindex(1), "tf");
        lua_insert(L, -2);
        if (lua_pcall(L, 1, 1, 0) != LUA_OK) /* name the option, then cdvr.tf's reason */
            luaL_error(L, "cdvr.render: option 'tf': %s", lua_tostring(L, -1));
        if (lua_isnil(L, -1))
            luaL_error(L, "cdvr.render: option 'tf': cannot load transfer function");
    }
    lcdvr_checkoption(L, -1, "cdvr.render", "tf", LCDVR_TF);
    const cdvr_tf *tf = lcdvr_checktf(L, -1);
    lua_replace(L, idx + 1); /* keep it referenced in a stack slot reserved by the caller */
    return tf;
}

/* opts.camera, or cdvr.orbit_camera(box) with box the value at stack index `box` (a volume
 * or a table with dims, spacing and origin). */
static const cdvr_camera *read_camera(lua_State *L, int idx, int box)
{
    if (lua_getfield(L, idx, "camera") == LUA_TNIL) {
        lua_pop(L, 1);
        lua_getfield(L, lua_upvalueindex(1), "orbit_camera");
        lua_pushvalue(L, box);
        lua_call(L, 1, 1);
    }
    lcdvr_checkoption(L, -1, "cdvr.render", "camera", LCDVR_CAMERA);
    const cdvr_camera *cam = lcdvr_checkcamera(L, -1);
    lua_replace(L, idx + 2);
    return cam;
}

static void read_options(lua_State *L, cdvr_render_opts *o, int box)
{
    o->tf = read_tf(L, 2);
    o->camera = read_camera(L, 2, box);
    o->step = lcdvr_optnumberfield(L, 2, "step", 0.0);
    o->unit = lcdvr_optnumberfield(L, 2, "unit", 0.0);
    o->term_alpha = lcdvr_optnumberfield(L, 2, "term", 0.0);
    lua_Integer threads = lcdvr_optintegerfield(L, 2, "threads", 0);
    if (threads < 0 || threads > 256)
        luaL_error(L, "cdvr.render: threads must be 0..256 (0 = all cores), got %I",
                   (LUAI_UACINT)threads);
    o->threads = (int)threads;
    if (!(o->step >= 0.0) || !(o->unit >= 0.0) || !(o->term_alpha >= 0.0))
        luaL_error(L, "cdvr.render: step, unit and term must be >= 0");
    read_background(L, 2, o->background);
    o->cancel = lcdvr_interrupt_flag(L);
}

/* The image and stats table on top: the stats become the image's img:stats() as well. */
static int finish(lua_State *L, int nres)
{
    lua_pushvalue(L, -1);
    lcdvr_setimagestats(L, -3);
    return nres;
}

/* Every method takes these; the scene keys and the method's own options come from its table. */
static const char *const base_keys[] = {"tf", "camera", "device", "method", "t", "variant",
                                        "background", NULL};

/* One warning line when no pixel's ray hits the box of vol (render.h). */
static void warn_if_missed(lua_State *L, const cdvr_volume *vol, const cdvr_camera *cam)
{
    if (!cdvr_render_view_hits(vol, cam))
        lcdvr_warn(L, "cdvr.render: the camera's view misses the volume (eye %f %f %f, looking at %f %f %f): "
                      "the image is only background",
                   cam->eye[0], cam->eye[1], cam->eye[2], cam->center[0], cam->center[1],
                   cam->center[2]);
}

/* What cdvr.render was asked: the method, its device and options (read from argument 2). */
typedef struct render_call {
    const cdvr_render_method *method;
    cdvr_device_kind device;
    cdvr_method_params params;
    cdvr_look look;
    cdvr_render_ctx *ctx;
    size_t t, timesteps;        /* the timestep rendered (from 0) of how many */
} render_call;

/* Pushes the image and its stats (also img:stats()) of a render that filled img and stats. */
static int push_result(lua_State *L, const render_call *c, cdvr_status status, cdvr_image *img,
                       const cdvr_render_stats *stats, const cdvr_error *err,
                       const cdvr_render_opts *o)
{
    if (status != CDVR_OK)
        return lcdvr_raise(L, err);
    lcdvr_pushimage(L, img);                      /* Lua owns it: an error cannot leak it */
    cdvr_annotate_opts ao;
    int time;
    if (lcdvr_read_annotate(L, 2, "cdvr.render", &ao, &time)) {
        char text[64];
        snprintf(text, sizeof text, "t = %zu / %zu", c->t + 1, c->timesteps);
        ao.tf = o->tf;
        ao.camera = o->camera;
        ao.time = time ? text : NULL;
        cdvr_error aerr;
        if (cdvr_annotate(img, &ao, &aerr) != CDVR_OK)
            luaL_error(L, "cdvr.render: option 'annotate': %s", aerr.msg);
    }
    lcdvr_push_render_stats(L, c->method, c->device, stats);
    return finish(L, 2);
}

/* cdvr.render(st, {t=, variant=, ...}) by a method that renders a stored chunk on its device
 * (the chunk goes to the device as it is: decode kernel, or the compressed domain for
 * fetch-mode codecs). Stack: st, opts. */
static int render_store_direct(lua_State *L, render_call *c, const cdvr_store *st, size_t v,
                               size_t t)
{
    lua_settop(L, 4); /* st, opts, (tf), (camera) */
    cdvr_render_opts o = {0};
    read_options(L, &o, 1); /* the default camera frames st's box (not st:info(), whose
                             * details read every chunk) */
    o.look = c->look;
    const cdvr_store_info *info = cdvr_store_get_info(st);
    const double window[2] = {info->qlo, info->qhi};
    cdvr_volume *frame = NULL; /* range="auto": its percentiles from the frame decoded here */
    if (o.tf->auto_range) {
        cdvr_error derr;
        if (cdvr_store_decode(st, v, t, &frame, &derr) != CDVR_OK)
            return lcdvr_raise(L, &derr);
        lcdvr_pushvolume(L, frame); /* collected with the call */
    }
    window_tf(L, &o, window, 3, frame, 0);
    cdvr_volume box = {.timesteps = 1}; /* the store's geometry, for the view check */
    memcpy(box.dims, info->dims, sizeof box.dims);
    memcpy(box.spacing, info->spacing, sizeof box.spacing);
    memcpy(box.origin, info->origin, sizeof box.origin);
    memcpy(box.direction, info->direction, sizeof box.direction);
    warn_if_missed(L, &box, o.camera);
    cdvr_render_stats stats = {0};
    cdvr_image *img = NULL;
    cdvr_error err;
    cdvr_status s = c->method->render_store(c->ctx, c->device, st, v, t, &o, &c->params, &stats,
                                            &img, &err);
    return push_result(L, c, s, img, &stats, &err, &o);
}

/* Variant of opts.variant (name or 1-based index; default the first). */
static size_t store_variant(lua_State *L, const cdvr_store *st)
{
    size_t n = cdvr_store_get_info(st)->nvariants;
    int type = lua_getfield(L, 2, "variant");
    size_t v = 0;
    if (type == LUA_TSTRING) {
        int found = lcdvr_find_variant(L, -1, st);
        if (found < 0)
            luaL_error(L, "cdvr.render: %s has no variant %s", cdvr_store_path(st),
                       lcdvr_push_quoted(L, -1));
        v = (size_t)found;
    } else if (type != LUA_TNIL) {
        lua_Integer i = lua_tointeger(L, -1);
        if (!lua_isinteger(L, -1) || i < 1 || (size_t)i > n)
            luaL_error(L, "cdvr.render: option 'variant': a name or 1..%d expected", (int)n);
        v = (size_t)i - 1;
    }
    lua_pop(L, 1);
    return v;
}

/* The method, device and options of argument 2, checked against the method's table. */
static void read_call(lua_State *L, render_call *c)
{
    c->method = lcdvr_method_option(L, 2, "cdvr.render");
    lcdvr_method_checkoptions(L, 2, c->method, "cdvr.render", base_keys);
    c->device = lcdvr_method_device(L, 2, c->method, "cdvr.render");
    lcdvr_method_params(L, 2, c->method, "cdvr.render", &c->params);
    lcdvr_read_look(L, 2, c->method, "cdvr.render", &c->look);
    c->ctx = lcdvr_render_ctx(L);
}

static int l_render(lua_State *L)
{
    const cdvr_store *st = luaL_testudata(L, 1, LCDVR_STORE) ? lcdvr_checkstore(L, 1) : NULL;
    const cdvr_volume *head = st ? NULL : lcdvr_volume_header(L, 1);
    cdvr_volume *vol = NULL;
    int lazy = 0;
    luaL_checktype(L, 2, LUA_TTABLE);
    render_call c;
    read_call(L, &c);
    size_t timesteps = st ? cdvr_store_get_info(st)->timesteps : head->timesteps;
    lua_Integer t = lcdvr_optintegerfield(L, 2, "t", 1);
    if (t < 1 || (size_t)t > timesteps)
        return luaL_error(L, "cdvr.render: t = %I outside 1..%I", (LUAI_UACINT)t,
                          (LUAI_UACINT)timesteps);
    size_t frame = (size_t)t - 1;
    c.t = frame;
    c.timesteps = timesteps;
    if (st) {
        size_t v = store_variant(L, st);
        int cached = lua_getfield(L, 2, "cache") != LUA_TNIL && lua_toboolean(L, -1);
        lua_pop(L, 1); /* cache=true on the cpu: the method's store path (its brick cache) */
        lcdvr_render_ctx_hold(L, 0, NULL); /* a store renders no volume: release the last */
        if (c.method->render_store && (c.device == CDVR_DEVICE_CL || cached))
            return render_store_direct(L, &c, st, v, frame);
        cdvr_volume *decoded; /* decode the timestep on the host, then render it as a volume */
        cdvr_error err;
        if (cdvr_store_decode(st, v, frame, &decoded, &err) != CDVR_OK)
            return lcdvr_raise(L, &err);
        lcdvr_pushvolume(L, decoded);
        lua_replace(L, 1);
        vol = decoded;
        frame = 0;
    } else if ((lazy = lcdvr_volume_lazy(L, 1))) { /* a series read as needed: timestep t only */
        vol = lcdvr_volume_read(L, 1, frame, 1);
        lua_replace(L, 1);
        frame = 0;
    } else {
        vol = lcdvr_checkvolume(L, 1);
    }
    lua_settop(L, 4); /* slots 3, 4 hold the TF and camera while rendering */
    cdvr_render_opts o = {0};
    read_options(L, &o, 1);
    o.look = c.look;
    double window[2];
    const cdvr_volume *u8 = u8_frame(L, vol, &frame, window);
    window_tf(L, &o, window, 3, u8, frame);
    warn_if_missed(L, u8, o.camera);
    cdvr_render_stats stats = {0};
    cdvr_image *img = NULL;
    cdvr_error err;
    /* The context holds the script's own u8 volume it renders (cdvr/method.h: on cl its frames
     * are known on the device by identity and revision, no per-render compare; on the cpu the
     * skip cache keeps its brick ranges); a decoded, lazily read or quantized frame is new
     * each time and compared as before. Any other render releases the volume held. */
    int own = u8 == vol && !st && !lazy;
    lcdvr_render_ctx_hold(L, own ? 1 : 0, own ? vol : NULL);
    cdvr_status s = c.method->render(c.ctx, c.device, u8, frame, &o, &c.params, &stats, &img, &err);
    return push_result(L, &c, s, img, &stats, &err, &o);
}

int lcdvr_open_render(lua_State *L)
{
    lua_pushvalue(L, -1); /* the cdvr table: cdvr.tf and cdvr.orbit_camera for defaults */
    lua_pushcclosure(L, l_render, 1);
    lua_setfield(L, -2, "render");
    lcdvr_help_add(L, "cdvr.render(volume, {tf=, camera=, method=, device=, t=, background=, step=, unit=, term=, threads=, ...})",
                   "image and stats (also img:stats()); method \"raycast\" (default), \"slice\" or \"splat\" "
                   "(cdvr.methods() lists each with its devices and options); device defaults to cl when "
                   "the method has it and an OpenCL device opens, else cpu (gl for slice); camera defaults "
                   "to cdvr.orbit_camera(volume); the TF is classified over the volume's value window "
                   "(v:window(): the series' range, or the quantize/store window), non-u8 frames are "
                   "quantized over it; term = early-termination alpha (0.99, >= 1 off)");
    lcdvr_help_add(L, "cdvr.render(store, {t=, variant=, device=, ...})",
                   "render timestep t of a store variant: device \"cl\" renders the chunk on the "
                   "device (in the compressed domain for fetch-mode codecs such as hvq), \"cpu\" "
                   "decodes it first; stats add device_bytes= and volume_bytes= on the device; "
                   "the TF is classified over the store's window");
    return 0;
}
