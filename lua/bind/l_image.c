/* lua/bind/l_image.c - cdvr.Image: rendered images in Lua (img:size(), img:pixel(), img:save()). */
#include <limits.h>

#include "lcdvr.h"

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

/* 1 if path ends in .png (any case). */
static int png_extension(const char *path)
{
    size_t n = strlen(path);
    return n >= 4 && path[n - 4] == '.' && (path[n - 3] | 32) == 'p' && (path[n - 2] | 32) == 'n' &&
           (path[n - 1] | 32) == 'g';
}

static int image_save(lua_State *L)
{
    const cdvr_image *img = lcdvr_checkimage(L, 1);
    const char *path = luaL_checkstring(L, 2);
    int alpha = 0;
    if (!lua_isnoneornil(L, 3)) {
        static const char *const keys[] = {"alpha", NULL};
        luaL_checktype(L, 3, LUA_TTABLE);
        lcdvr_checkoptions(L, 3, "img:save", keys);
        alpha = lcdvr_optbooleanfield(L, 3, "alpha", 0);
    }
    if (!png_extension(path))
        return luaL_error(L, "img:save: cannot write '%s': only PNG is written (name it .png)", path);
    cdvr_error err;
    cdvr_status st = alpha ? cdvr_image_save_png_rgba(img, path, &err) : cdvr_image_save_png(img, path, &err);
    if (st != CDVR_OK)
        return lcdvr_fail(L, &err);
    lua_pushboolean(L, 1);
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
    lcdvr_help_add(L, "img:size()", "width, height of an image in pixels");
    lcdvr_help_add(L, "img:pixel(x, y)",
                   "r, g, b, a in [0,1], premultiplied, before the background (x, y from 0, y down)");
    lcdvr_help_add(L, "img:stats()",
                   "what the renderer reported: ms, method, device, samples (ray casting), "
                   "texture_bytes, full_bytes, axis, levels (slicing); {} for other images");
    lcdvr_help_add(L, "img:save(path.png [, {alpha=true}])",
                   "write an RGB PNG composited over the background (RGBA with alpha=true); other extensions "
                   "are errors; true or nil, msg on I/O failure");
    return 0;
}
