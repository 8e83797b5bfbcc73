/* lua/bind/l_device.c - the OpenCL device in Lua: cdvr.render{device="cl"}, st:decode(t, v,
 * {device="cl"}) and cdvr.cl_info(). The device is opened lazily on first use and kept in the
 * Lua registry (one per Lua state, closed by its __gc), never in a C global. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cdvr/timing.h"
#include "lcdvr.h"

#if CDVR_HAVE_OPENCL

#include "cdvr/device.h"
#include "cdvr/render.h"

#define LCDVR_CLDEVICE "cdvr.CLDevice"
#define REGISTRY_KEY "cdvr.cl_device" /* the open device (the metatable is LCDVR_CLDEVICE) */

typedef struct ldevice {
    cdvr_cl *cl;             /* NULL until opened, and once closed */
    cdvr_cl_stream *stream;  /* reused while the dims stay the same */
    size_t stream_dims[3];
    uint8_t *frame_copy;     /* host copy of the voxels in the stream's frame 0, or NULL */
    size_t frame_bytes;
} ldevice;

static ldevice *toldevice(lua_State *L, int idx)
{
    return (ldevice *)luaL_checkudata(L, idx, LCDVR_CLDEVICE);
}

static void forget_frame(ldevice *d)
{
    free(d->frame_copy);
    d->frame_copy = NULL;
    d->frame_bytes = 0;
}

static int device_gc(lua_State *L)
{
    ldevice *d = toldevice(L, 1);
    cdvr_cl_stream_free(d->stream);
    cdvr_cl_close(d->cl);
    forget_frame(d);
    d->stream = NULL;
    d->cl = NULL;
    return 0;
}

static int device_tostring(lua_State *L)
{
    ldevice *d = toldevice(L, 1);
    if (d->cl)
        lua_pushfstring(L, "cdvr.CLDevice %s (%p)", cdvr_cl_device_name(d->cl), (void *)d);
    else
        lua_pushliteral(L, "cdvr.CLDevice (closed)");
    return 1;
}

/* The registry's open device; on failure pushes nothing, fills err and returns NULL. */
static ldevice *get_device(lua_State *L, cdvr_error *err)
{
    if (lua_getfield(L, LUA_REGISTRYINDEX, REGISTRY_KEY) == LUA_TUSERDATA) {
        ldevice *d = toldevice(L, -1);
        lua_pop(L, 1);
        if (d->cl)
            return d;
    } else {
        lua_pop(L, 1);
    }
    cdvr_cl *cl;
    if (cdvr_cl_open(&cl, err) != CDVR_OK)
        return NULL;
    ldevice *d = (ldevice *)lua_newuserdatauv(L, sizeof *d, 0);
    memset(d, 0, sizeof *d);
    d->cl = cl;
    luaL_setmetatable(L, LCDVR_CLDEVICE);
    lua_setfield(L, LUA_REGISTRYINDEX, REGISTRY_KEY);
    return d;
}

int lcdvr_cl_available(lua_State *L)
{
    cdvr_error err;
    return get_device(L, &err) != NULL;
}

static ldevice *check_device(lua_State *L, const char *what)
{
    cdvr_error err;
    ldevice *d = get_device(L, &err);
    if (!d)
        luaL_error(L, "%s: %s", what, err.msg);
    return d;
}

static cdvr_cl_stream *device_stream(lua_State *L, ldevice *d, const size_t dims[3])
{
    if (d->stream && !memcmp(d->stream_dims, dims, sizeof d->stream_dims))
        return d->stream;
    cdvr_cl_stream_free(d->stream);
    d->stream = NULL;
    forget_frame(d);
    cdvr_error err;
    if (cdvr_cl_stream_create(d->cl, dims, &d->stream, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    memcpy(d->stream_dims, dims, sizeof d->stream_dims);
    return d->stream;
}

/* Makes the stream's frame 0 hold frame t of vol, uploading only if it changed: a volume may
 * be edited in place (v:set) between renders, so the voxels are compared with a host copy of
 * what was uploaded (memcmp is exact and faster than hashing the frame). */
static cdvr_status upload_frame(ldevice *d, cdvr_cl_stream *s, const cdvr_volume *vol, size_t t,
                                cdvr_error *err)
{
    const uint8_t *voxels = cdvr_volume_frame(vol, t);
    size_t bytes = cdvr_volume_voxels(vol);
    if (d->frame_copy && d->frame_bytes == bytes && !memcmp(d->frame_copy, voxels, bytes))
        return CDVR_OK;
    forget_frame(d);
    cdvr_status st = cdvr_cl_upload_frames(s, voxels, 1, err);
    if (st)
        return st;
    d->frame_copy = malloc(bytes ? bytes : 1);
    if (d->frame_copy) { /* without a copy the next render uploads again */
        memcpy(d->frame_copy, voxels, bytes);
        d->frame_bytes = bytes;
    }
    return CDVR_OK;
}

/* Pushes the stats table of a device render. */
static void push_cl_stats(lua_State *L, ldevice *d, cdvr_cl_stream *s, double ms)
{
    lua_createtable(L, 0, 6);
    lua_pushinteger(L, (lua_Integer)cdvr_cl_last_samples(s));
    lua_setfield(L, -2, "samples");
    lua_pushnumber(L, ms);
    lua_setfield(L, -2, "ms");
    lua_pushstring(L, cdvr_cl_device_name(d->cl));
    lua_setfield(L, -2, "device");
    size_t visible, total;
    cdvr_cl_brick_counts(s, &visible, &total);
    lua_pushnumber(L, total ? (double)visible / (double)total : 0.0);
    lua_setfield(L, -2, "bricks_visible");
    lua_pushinteger(L, (lua_Integer)cdvr_cl_stream_bytes(s));
    lua_setfield(L, -2, "device_bytes");
    lua_pushinteger(L, (lua_Integer)cdvr_cl_volume_bytes(s));
    lua_setfield(L, -2, "volume_bytes");
}

/* Setup and ray cast of the stream's frame `frame`; pushes image and stats. */
static int render_frame(lua_State *L, ldevice *d, cdvr_cl_stream *s, size_t frame,
                        const cdvr_render_opts *opts, const double spacing[3],
                        const double origin[3], const double direction[9], double start)
{
    cdvr_image *img;
    cdvr_error err;
    if (cdvr_image_create(opts->camera->width, opts->camera->height, &img, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lcdvr_pushimage(L, img); /* owned by Lua from here, so an error cannot leak it */
    cdvr_status st = cdvr_cl_setup(s, frame, opts->tf, &err);
    if (!st)
        st = cdvr_cl_render(s, frame, opts, spacing, origin, direction, img, &err);
    if (st)
        return lcdvr_raise(L, &err);
    push_cl_stats(L, d, s, cdvr_now_ms() - start);
    return 2;
}

int lcdvr_render_cl(lua_State *L, const cdvr_volume *vol, size_t t, void *render_opts)
{
    const cdvr_render_opts *opts = render_opts;
    /* the options table of cdvr.render is argument 2: skip=false turns empty-space skipping off */
    int skipping = lua_istable(L, 2) ? lcdvr_optbooleanfield(L, 2, "skip", 1) : 1;
    if (vol->type != CDVR_TYPE_U8 || t >= vol->timesteps)
        return luaL_error(L, "cdvr.render{device=\"cl\"}: needs frame of a u8 volume");
    ldevice *d = check_device(L, "cdvr.render{device=\"cl\"}");
    cdvr_cl_stream *s = device_stream(L, d, vol->dims);
    double start = cdvr_now_ms();
    cdvr_cl_set_skipping(s, skipping);
    cdvr_error err;
    if (upload_frame(d, s, vol, t, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    return render_frame(L, d, s, 0, opts, vol->spacing, vol->origin, vol->direction, start);
}

/* Uploads chunk c of variant v and makes the stream's frames from it: the codec's decode
 * kernel, its fetch mode (frames stay compressed), or a host decode + upload for codecs
 * without device code and for bricked stores. Returns the frame of timestep t. */
static size_t load_chunk(lua_State *L, cdvr_cl_stream *s, const cdvr_store *st, size_t v,
                         size_t t)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    size_t c = cdvr_store_chunk_for_time(st, v, t);
    const cdvr_chunk_info *chunk = c != (size_t)-1 ? cdvr_store_chunk(st, v, c) : NULL;
    if (!chunk)
        luaL_error(L, "%s: no variant %d timestep %d", cdvr_store_path(st), (int)v + 1, (int)t + 1);
    const cdvr_codec *codec;
    cdvr_error err;
    if (cdvr_store_variant_codec(st, v, &codec, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    cdvr_status status;
    if (info->nbricks > 1 || codec->cl_mode == CDVR_CODEC_CL_NONE) {
        cdvr_volume *vol;
        if (cdvr_store_decode(st, v, t, &vol, &err) != CDVR_OK)
            lcdvr_raise(L, &err);
        status = cdvr_cl_upload_frames(s, vol->data, 1, &err);
        cdvr_volume_free(vol);
        if (status)
            lcdvr_raise(L, &err);
        return 0;
    }
    uint8_t *payload;
    if (cdvr_store_load_payload(st, v, c, &payload, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    status = cdvr_cl_upload(s, payload, (size_t)chunk->payload_bytes, &err);
    free(payload);
    if (!status)
        status = cdvr_cl_decode(s, chunk->codec, &chunk->params, chunk->count, &err);
    if (status)
        luaL_error(L, "%s: variant %s chunk %d: %s", cdvr_store_path(st),
                   cdvr_store_variant(st, v)->name, (int)c + 1, err.msg);
    return t - chunk->t0;
}

int lcdvr_render_cl_store(lua_State *L, const cdvr_store *st, size_t v, size_t t,
                          void *render_opts)
{
    const cdvr_render_opts *opts = render_opts;
    int skipping = lua_istable(L, 2) ? lcdvr_optbooleanfield(L, 2, "skip", 1) : 1;
    ldevice *d = check_device(L, "cdvr.render{device=\"cl\"}");
    const cdvr_store_info *info = cdvr_store_get_info(st);
    cdvr_cl_stream *s = device_stream(L, d, info->dims);
    forget_frame(d); /* the stream's frames are about to be replaced */
    double start = cdvr_now_ms();
    cdvr_cl_set_skipping(s, skipping);
    size_t frame = load_chunk(L, s, st, v, t);
    return render_frame(L, d, s, frame, opts, info->spacing, info->origin, info->direction, start);
}

int lcdvr_decode_cl(lua_State *L, const cdvr_store *st, size_t v, size_t t)
{
    if (!cdvr_store_variant(st, v))
        return luaL_error(L, "%s: no variant %d", cdvr_store_path(st), (int)v + 1);
    ldevice *d = check_device(L, "st:decode{device=\"cl\"}");
    const cdvr_store_info *info = cdvr_store_get_info(st);
    cdvr_cl_stream *s = device_stream(L, d, info->dims);
    cdvr_volume *vol;
    cdvr_error err;
    if (cdvr_volume_create(info->dims, 1, CDVR_TYPE_U8, &vol, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    memcpy(vol->spacing, info->spacing, sizeof vol->spacing);
    memcpy(vol->origin, info->origin, sizeof vol->origin);
    memcpy(vol->direction, info->direction, sizeof vol->direction);
    vol->window[0] = info->qlo; /* the codes 0..255 stand for the store's value window */
    vol->window[1] = info->qhi;
    lcdvr_pushvolume(L, vol); /* owned by Lua from here */
    forget_frame(d);         /* the stream's frames are about to be replaced */
    size_t frame = load_chunk(L, s, st, v, t);
    if (cdvr_cl_download(s, frame, vol->data, &err) != CDVR_OK)
        return luaL_error(L, "%s: variant %s: %s", cdvr_store_path(st),
                          cdvr_store_variant(st, v)->name, err.msg);
    return 1;
}

static void set_string(lua_State *L, const char *key, const char *value)
{
    lua_pushstring(L, value);
    lua_setfield(L, -2, key);
}

static void set_number(lua_State *L, const char *key, double value)
{
    lua_pushnumber(L, value);
    lua_setfield(L, -2, key);
}

static int l_cl_info(lua_State *L)
{
    cdvr_error err;
    ldevice *d = get_device(L, &err);
    if (!d)
        return lcdvr_fail(L, &err);
    const cdvr_cl_info *info = cdvr_cl_get_info(d->cl);
    lua_createtable(L, 0, 12);
    set_string(L, "platform", info->platform);
    set_string(L, "device", info->device);
    set_string(L, "type", info->is_gpu ? "gpu" : "cpu");
    set_string(L, "version", info->device_version);
    set_string(L, "driver", info->driver_version);
    set_number(L, "compute_units", info->compute_units);
    set_number(L, "global_mem_bytes", (double)info->global_mem_bytes);
    set_number(L, "max_alloc_bytes", (double)info->max_alloc_bytes);
    lua_pushfstring(L, "%d:%d", info->platform_index, info->device_index);
    lua_setfield(L, -2, "index");
    set_number(L, "build_seconds", info->build_seconds);
    lua_pushboolean(L, info->from_cache);
    lua_setfield(L, -2, "from_cache");
    set_string(L, "cache", info->cache_path);
    return 1;
}

int lcdvr_open_device(lua_State *L)
{
    static const luaL_Reg meta[] = {
        {"__gc", device_gc}, {"__close", device_gc}, {"__tostring", device_tostring}, {NULL, NULL}};
    static const luaL_Reg methods[] = {{NULL, NULL}};
    static const luaL_Reg funcs[] = {{"cl_info", l_cl_info}, {NULL, NULL}};
    lcdvr_newclass(L, LCDVR_CLDEVICE, methods, meta);
    lcdvr_setfuncs(L, funcs);
    lcdvr_help_add(L, "cdvr.cl_info()",
                   "OpenCL device in use {platform=, device=, type=\"cpu\"|\"gpu\", version=, driver=, "
                   "compute_units=, build_seconds=, from_cache=, ...}, or nil, message "
                   "(CDVR_CL_DEVICE=gpu|cpu|none|P:D|name picks the device)");
    lcdvr_help_add(L, "cdvr.render(v, {device=\"cl\", skip=true, ...})",
                   "ray cast on the OpenCL device (same image as the CPU within 50 dB PSNR); "
                   "skip=false turns empty-space skipping off; stats add device=, bricks_visible=");
    lcdvr_help_add(L, "st:decode(t, variant, {device=\"cl\"})",
                   "decode timestep t with the codec's OpenCL decode kernel (bit-exact with the "
                   "CPU); codecs without one decode on the CPU; fetch-mode codecs (hvq) stay "
                   "compressed on the device and raise");
    return 0;
}

#else /* no OpenCL in this build */

int lcdvr_cl_available(lua_State *L)
{
    (void)L;
    return 0;
}

static int l_cl_info(lua_State *L)
{
    lua_pushnil(L);
    lua_pushliteral(L, "OpenCL support is not built into this cdvr (CDVR_WITH_OPENCL off or no OpenCL found)");
    return 2;
}

int lcdvr_open_device(lua_State *L)
{
    static const luaL_Reg funcs[] = {{"cl_info", l_cl_info}, {NULL, NULL}};
    lcdvr_setfuncs(L, funcs);
    lcdvr_help_add(L, "cdvr.cl_info()", "OpenCL device info, or nil, message (not built in here)");
    return 0;
}

int lcdvr_render_cl(lua_State *L, const cdvr_volume *vol, size_t t, void *render_opts)
{
    (void)vol; (void)t; (void)render_opts;
    return luaL_error(L, "device='cl': OpenCL support is not built into this cdvr");
}

int lcdvr_decode_cl(lua_State *L, const cdvr_store *st, size_t v, size_t t)
{
    (void)st; (void)v; (void)t;
    return luaL_error(L, "device='cl': OpenCL support is not built into this cdvr");
}

int lcdvr_render_cl_store(lua_State *L, const cdvr_store *st, size_t v, size_t t,
                          void *render_opts)
{
    (void)st; (void)v; (void)t; (void)render_opts;
    return luaL_error(L, "device='cl': OpenCL support is not built into this cdvr");
}

#endif
