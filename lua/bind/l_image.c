/* lua/bind/l_image.c - cdvr.Image: rendered images in Lua (img:size(), img:pixel(), img:save()). */
#include <limits.h>

#include "cdvr/annotate.h"
#include "lcdvr.h"

#include <math.h>
#include <string.h>

typedef struct limage {
    cdvr_image *img; /* NULL once closed */
} limage;

static limage *tolimage(lua_State *L, int idx)
{
    return (limage *)luaL_checkudata(L, idx, LCDVR_IMAGE);
}

cdvr_image *lcdvr_checkimage(lua_State *L, int idx)
{
    limage *ud = tolimage(L, idx);
    if (!ud->img)
        luaL_error(L, "attempt to use a closed image");
    return ud->img;
}

void lcdvr_pushimage(lua_State *L, cdvr_image *img)
{
    /* The pixels live outside Lua's heap, so the collector does not see them: step it as if
     * they were allocated here, so that render loops recycle the images they drop instead of
     * growing (fresh pages cost a page fault each, about 11 ms for 512x512). */
    size_t pixel_kb = (size_t)img->width * (size_t)img->height * 4 * sizeof(float) / 1024;
    lua_gc(L, LUA_GCSTEP, pixel_kb > INT_MAX ? INT_MAX : (int)pixel_kb);
    limage *ud = (limage *)lua_newuserdatauv(L, sizeof *ud, 1); /* user value 1: stats */
    ud->img = img;
    luaL_setmetatable(L, LCDVR_IMAGE);
}

void lcdvr_setimagestats(lua_State *L, int idx)
{
    idx = lua_absindex(L, idx);
    tolimage(L, idx);
    luaL_checktype(L, -1, LUA_TTABLE);
    lua_setiuservalue(L, idx, 1);                 /* pops the stats table */
}

/* img:stats(): what the renderer reported (ms, samples, method, texture_bytes, ...). */
static int image_stats(lua_State *L)
{
    lcdvr_checkimage(L, 1);
    if (lua_getiuservalue(L, 1, 1) != LUA_TTABLE) {
        lua_pop(L, 1);
        lua_newtable(L);
    }
    return 1;
}

static int image_gc(lua_State *L)
{
    limage *ud = tolimage(L, 1);
    cdvr_image_free(ud->img);
    ud->img = NULL;
    return 0;
}

static int image_tostring(lua_State *L)
{
    limage *ud = tolimage(L, 1);
    if (!ud->img)
        lua_pushliteral(L, "cdvr.Image (closed)");
    else
        lua_pushfstring(L, "cdvr.Image %dx%d (%p)", ud->img->width, ud->img->height,
                        (void *)ud);
    return 1;
}

static int image_size(lua_State *L)
{
    const cdvr_image *img = lcdvr_checkimage(L, 1);
    lua_pushinteger(L, img->width);
    lua_pushinteger(L, img->height);
    return 2;
}

static int image_pixel(lua_State *L)
{
    const cdvr_image *img = lcdvr_checkimage(L, 1);
    lua_Integer x = luaL_checkinteger(L, 2), y = luaL_checkinteger(L, 3);
    luaL_argcheck(L, x >= 0 && x < img->width, 2, "x outside the image (from 0)");
    luaL_argcheck(L, y >= 0 && y < img->height, 3, "y outside the image (from 0)");
    const float *p = cdvr_image_pixel(img, (int)x, (int)y);
    for (int c = 0; c < 4; c++)
        lua_pushnumber(L, p[c]);
    return 4;
}

/* 1 if path ends in ext (".png", any case). */
static int has_extension(const char *path, const char *ext)
{
    size_t n = strlen(path), m = strlen(ext);
    if (n < m)
        return 0;
    for (size_t i = 0; i < m; i++)
        if ((path[n - m + i] | 32) != ext[i])
            return 0;
    return 1;
}

static int image_save(lua_State *L)
{
    const cdvr_image *img = lcdvr_checkimage(L, 1);
    const char *path = luaL_checkstring(L, 2);
    int alpha = 0;
    lua_Integer quality = 90;
    if (!lua_isnoneornil(L, 3)) {
        static const char *const keys[] = {"alpha", "quality", NULL};
        luaL_checktype(L, 3, LUA_TTABLE);
        lcdvr_checkoptions(L, 3, "img:save", keys);
        alpha = lcdvr_optbooleanfield(L, 3, "alpha", 0);
        quality = lcdvr_optintegerfield(L, 3, "quality", 90);
    }
    int png = has_extension(path, ".png");
    int jpeg = has_extension(path, ".jpg") || has_extension(path, ".jpeg");
    if (!png && !jpeg)
        return luaL_error(L, "img:save: cannot write '%s': the extension chooses the format: "
                             ".png (PNG) or .jpg/.jpeg (JPEG)", path);
    if (jpeg && alpha)
        return luaL_error(L, "img:save: '%s': JPEG has no alpha channel (alpha=true needs .png)",
                          path);
    if (jpeg && (quality < 1 || quality > 100))
        return luaL_error(L, "img:save: quality must be 1..100, got %I", (LUAI_UACINT)quality);
    if (png && !lua_isnoneornil(L, 3) && lua_getfield(L, 3, "quality") != LUA_TNIL)
        return luaL_error(L, "img:save: quality= applies to JPEG, not to '%s'", path);
    cdvr_error err;
    cdvr_status st = jpeg    ? cdvr_image_save_jpeg(img, path, (int)quality, &err)
                     : alpha ? cdvr_image_save_png_rgba(img, path, &err)
                             : cdvr_image_save_png(img, path, &err);
    if (st != CDVR_OK)
        return lcdvr_fail(L, &err);
    lua_pushboolean(L, 1);
    return 1;
}

/* ---- img:annotate ------------------------------------------------------------------------ */

/* The data window of opts.volume or opts.store (1 when one is given; its timesteps in *n). */
static int annotate_window(lua_State *L, int opts, double w[2], size_t *n)
{
    if (lua_getfield(L, opts, "volume") != LUA_TNIL) {
        lcdvr_checkoption(L, -1, "img:annotate", "volume", LCDVR_VOLUME);
        const cdvr_volume *h = lcdvr_volume_header(L, -1);
        *n = h->timesteps;
        w[0] = h->window[0], w[1] = h->window[1];
        if (!isfinite(w[0]) || !isfinite(w[1]))
            cdvr_volume_window(lcdvr_checkvolume(L, -1), w);
        lua_pop(L, 1);
        return 1;
    }
    lua_pop(L, 1);
    if (lua_getfield(L, opts, "store") != LUA_TNIL) {
        lcdvr_checkoption(L, -1, "img:annotate", "store", LCDVR_STORE);
        const cdvr_store_info *info = cdvr_store_get_info(lcdvr_checkstore(L, -1));
        *n = info->timesteps;
        w[0] = info->qlo, w[1] = info->qhi;
        lua_pop(L, 1);
        return 1;
    }
    lua_pop(L, 1);
    return 0;
}

/* opts.tf (a cdvr.TF or a name / points table through cdvr.tf) as a copy on the stack, its
 * table built over the data's window w (when has_w) or range. */
static const cdvr_tf *annotate_tf(lua_State *L, int opts, int has_w, const double w[2],
                                  const double range[2], int has_range)
{
    int type = lua_getfield(L, opts, "tf");
    if (type == LUA_TNIL)
        luaL_error(L, "img:annotate: colorbar=true needs tf= (the TF the image was rendered with)");
    if (type == LUA_TSTRING || type == LUA_TTABLE) {
        lua_getfield(L, lua_upvalueindex(1), "tf");
        lua_insert(L, -2);
        if (lua_pcall(L, 1, 1, 0) != LUA_OK)
            luaL_error(L, "img:annotate: option 'tf': %s", luaL_tolstring(L, -1, NULL));
    }
    lcdvr_checkoption(L, -1, "img:annotate", "tf", LCDVR_TF);
    cdvr_tf *tf = lcdvr_pushtf(L, lcdvr_checktf(L, -1));
    lua_replace(L, -2);
    cdvr_error err;
    const double *win = has_w ? w : has_range ? range : tf->window;
    const cdvr_volume *u8 = NULL;
    if (tf->auto_range) {
        if (lua_getfield(L, opts, "volume") != LUA_TNIL && !lcdvr_volume_lazy(L, -1) &&
            lcdvr_checkvolume(L, -1)->type == CDVR_TYPE_U8)
            u8 = lcdvr_checkvolume(L, -1);
        lua_pop(L, 1);
        if (!u8)
            luaL_error(L, "img:annotate: a range=\"auto\" TF needs volume= a u8 volume (its "
                          "percentiles), or give the TF pinned to data values");
    }
    if (cdvr_tf_apply_window(tf, win, u8, 0, NULL, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
    return tf;
}

static const char *opt_string(lua_State *L, int opts, const char *key)
{
    int type = lua_getfield(L, opts, key);
    const char *s = NULL;
    if (type == LUA_TSTRING || type == LUA_TNUMBER)
        s = lua_tostring(L, -1); /* stays referenced by the options table (or its copy) */
    else if (type != LUA_TNIL)
        luaL_error(L, "img:annotate: option '%s' must be a string, got %s", key,
                   luaL_typename(L, -1));
    lua_pop(L, 1);
    return s;
}

/* img:annotate{colorbar=, tf=, range=, unit=, axes=, camera=, space=, title=, time=,
 * volume= | store=}: draws onto the image (cdvr/annotate.h) and returns it. */
static int image_annotate(lua_State *L)
{
    static const char *const keys[] = {"colorbar", "tf", "range", "unit", "axes", "camera",
                                       "space", "title", "time", "volume", "store", "color",
                                       NULL};
    cdvr_image *img = lcdvr_checkimage(L, 1);
    luaL_checktype(L, 2, LUA_TTABLE);
    lua_settop(L, 2);
    lcdvr_checkoptions(L, 2, "img:annotate", keys);
    cdvr_annotate_opts o = {0};
    double w[2] = {0, 0}, range[2] = {0, 0};
    size_t n = 0;
    int has_w = annotate_window(L, 2, w, &n);
    int has_range = lcdvr_numberarrayfield(L, 2, "range", range, 2);
    o.colorbar = lcdvr_optbooleanfield(L, 2, "colorbar", 0);
    if (o.colorbar) {
        o.tf = annotate_tf(L, 2, has_w, w, range, has_range); /* stack slot 3 */
        if (has_range)
            o.range[0] = range[0], o.range[1] = range[1];
    }
    o.axes = lcdvr_optbooleanfield(L, 2, "axes", 0);
    if (o.axes) {
        if (lua_getfield(L, 2, "camera") == LUA_TNIL)
            luaL_error(L, "img:annotate: option 'axes': axes=true needs camera= (the camera the "
                          "image was rendered with)");
        lcdvr_checkoption(L, -1, "img:annotate", "camera", LCDVR_CAMERA);
        o.camera = lcdvr_checkcamera(L, -1); /* stays on the stack */
    }
    o.unit = opt_string(L, 2, "unit");
    o.space = opt_string(L, 2, "space");
    o.title = opt_string(L, 2, "title");
    char time[64] = "";
    if (lua_getfield(L, 2, "time") == LUA_TNUMBER) {
        if (n)
            snprintf(time, sizeof time, "t = %g / %zu", lua_tonumber(L, -1), n);
        else
            snprintf(time, sizeof time, "t = %g", lua_tonumber(L, -1));
    } else if (lua_type(L, -1) == LUA_TSTRING) {
        snprintf(time, sizeof time, "%s", lua_tostring(L, -1));
    } else if (!lua_isnil(L, -1)) {
        luaL_error(L, "img:annotate: option 'time' must be a number (the timestep) or a string");
    }
    lua_pop(L, 1);
    o.time = time;
    double color[3];
    if (lcdvr_numberarrayfield(L, 2, "color", color, 3))
        for (int i = 0; i < 3; i++)
            o.color[i] = (float)(color[i] < 0 ? 0 : color[i] > 1 ? 1 : color[i]);
    cdvr_error err;
    if (cdvr_annotate(img, &o, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_pushvalue(L, 1);
    return 1;
}

static const luaL_Reg image_methods[] = {
    {"size", image_size}, {"pixel", image_pixel}, {"save", image_save}, {"stats", image_stats},
    {NULL, NULL}};

static const luaL_Reg image_meta[] = {
    {"__gc", image_gc}, {"__close", image_gc}, {"__tostring", image_tostring}, {NULL, NULL}};

int lcdvr_open_image(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_IMAGE, image_methods, image_meta);
    lua_getfield(L, LUA_REGISTRYINDEX, LCDVR_IMAGE); /* annotate= needs cdvr.tf: a closure */
    lua_getfield(L, -1, "__index");
    lua_pushvalue(L, -3); /* the cdvr table */
    lua_pushcclosure(L, image_annotate, 1);
    lua_setfield(L, -2, "annotate");
    lua_pop(L, 2);
    lcdvr_help_add(L, "img:annotate{colorbar=, tf=, unit=, range=, axes=, camera=, space=, title=, time=, volume=|store=}",
                   "draw onto the image: a scalar bar of the TF (colour, opacity, ticks in data units "
                   "over the volume's or store's window, or range=), orientation letters from the camera "
                   "(world = patient LPS, or space=\"RAS\" for NIfTI), a title and the timestep; returns img");
    lcdvr_help_add(L, "img:size()", "width, height of an image in pixels");
    lcdvr_help_add(L, "img:pixel(x, y)",
                   "r, g, b, a in [0,1], premultiplied, before the background (x, y from 0, y down)");
    lcdvr_help_add(L, "img:stats()",
                   "what the renderer reported: ms, method, device, samples (ray casting), "
                   "texture_bytes, full_bytes, axis, levels (slicing); {} for other images");
    lcdvr_help_add(L, "img:save(path.png | path.jpg [, {alpha=true} | {quality=90}])",
                   "write an RGB PNG composited over the background (RGBA with alpha=true) or a JPEG "
                   "(quality 1..100, default 90); the extension chooses, others are errors; true or nil, "
                   "msg on I/O failure");
    return 0;
}
