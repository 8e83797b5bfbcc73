/* lua/bind/l_device.c - the OpenCL device in Lua: st:decode(t, v, {device="cl"}) and
 * cdvr.cl_info(). The device is the state's render context's (l_method.c: opened on first use,
 * kept in the Lua registry, never in a C global); cdvr.render on it goes through the method
 * table (l_render.c). */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cdvr/timing.h"
#include "lcdvr.h"

#if CDVR_HAVE_OPENCL

#include "cdvr/device.h"
#include "cdvr/method.h"
#include "cdvr/render.h"

/* The state's OpenCL device (the render context's, l_method.c); raises naming `what`. */
static cdvr_cl *check_device(lua_State *L, const char *what)
{
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_render_ctx_cl(lcdvr_render_ctx(L), &cl, &err) != CDVR_OK)
        luaL_error(L, "%s: %s", what, err.msg);
    return cl;
}

int lcdvr_decode_cl(lua_State *L, const cdvr_store *st, size_t v, size_t t)
{
    if (!cdvr_store_variant(st, v))
        return luaL_error(L, "%s: no variant %d", cdvr_store_path(st), (int)v + 1);
    check_device(L, "st:decode{device=\"cl\"}");
    const cdvr_store_info *info = cdvr_store_get_info(st);
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
    cdvr_cl_stream *s;
    size_t frame;
    if (cdvr_render_ctx_load_chunk(lcdvr_render_ctx(L), st, v, t, &s, &frame, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
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
    cdvr_cl *cl;
    if (cdvr_render_ctx_cl(lcdvr_render_ctx(L), &cl, &err) != CDVR_OK)
        return lcdvr_fail(L, &err);
    const cdvr_cl_info *info = cdvr_cl_get_info(cl);
    lua_createtable(L, 0, 15);
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
    set_string(L, "frames", info->dense_frames ? "dense" : "tiled");
    set_number(L, "layout_dense_ms", info->layout_dense_ms);
    set_number(L, "layout_tiled_ms", info->layout_tiled_ms);
    set_number(L, "quads_max_bytes", (double)info->quads_max_bytes);
    lua_pushboolean(L, info->still_quads);
    lua_setfield(L, -2, "still_quads");
    set_number(L, "quads_base_ms", info->quads_base_ms);
    set_number(L, "quads_ms", info->quads_ms);
    return 1;
}

int lcdvr_open_device(lua_State *L)
{
    static const luaL_Reg funcs[] = {{"cl_info", l_cl_info}, {NULL, NULL}};
    lcdvr_setfuncs(L, funcs);
    lcdvr_help_add(L, "cdvr.cl_info()",
                   "OpenCL device in use {platform=, device=, type=\"cpu\"|\"gpu\", version=, driver=, "
                   "compute_units=, build_seconds=, from_cache=, frames=\"dense\"|\"tiled\" (the layout "
                   "casts read: measured once per CPU device, CDVR_CL_TILES=0|1 overrides), "
                   "layout_dense_ms=, layout_tiled_ms=, quads_max_bytes= (the largest quad copy "
                   "made by default: measured once per CPU device, quads_ms= against quads_base_ms=, "
                   "the tiled copy or dense frames; still_quads=true: frames stay dense but one "
                   "rendered again gets the copies), ...}, or nil, message "
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

int lcdvr_decode_cl(lua_State *L, const cdvr_store *st, size_t v, size_t t)
{
    (void)st; (void)v; (void)t;
    return luaL_error(L, "device='cl': OpenCL support is not built into this cdvr");
}

#endif
