/* lua/bind/l_compare.c - cdvr.compare(a, b) for two volumes or two images. */
#include "cdvr/compare.h"
#include "lcdvr.h"

static void push_result(lua_State *L, const cdvr_compare_result *res)
{
    lua_createtable(L, 0, 3);
    lua_pushnumber(L, res->psnr);
    lua_setfield(L, -2, "psnr");
    lua_pushnumber(L, res->mse);
    lua_setfield(L, -2, "mse");
    lua_pushnumber(L, res->maxerr);
    lua_setfield(L, -2, "maxerr");
}

static int l_compare(lua_State *L)
{
    cdvr_compare_result res;
    cdvr_error err;
    cdvr_status st;
    if (luaL_testudata(L, 1, LCDVR_VOLUME)) {
        const cdvr_volume *a = lcdvr_checkvolume(L, 1);
        if (!luaL_testudata(L, 2, LCDVR_VOLUME))
            return luaL_typeerror(L, 2, LCDVR_VOLUME);
        st = cdvr_compare_volumes(a, lcdvr_checkvolume(L, 2), &res, &err);
    } else if (luaL_testudata(L, 1, LCDVR_IMAGE)) {
        const cdvr_image *a = lcdvr_checkimage(L, 1);
        if (!luaL_testudata(L, 2, LCDVR_IMAGE))
            return luaL_typeerror(L, 2, LCDVR_IMAGE);
        st = cdvr_compare_images(a, lcdvr_checkimage(L, 2), &res, &err);
    } else {
        return luaL_typeerror(L, 1, "cdvr.Volume or cdvr.Image");
    }
    if (st != CDVR_OK)
        return lcdvr_raise(L, &err);
    push_result(L, &res);
    return 1;
}

int lcdvr_open_compare(lua_State *L)
{
    lua_pushcfunction(L, l_compare);
    lua_setfield(L, -2, "compare");
    lcdvr_help_add(L, "cdvr.compare(a, b)",
                   "{psnr=, mse=, maxerr=} between two volumes or two images (psnr = math.huge if identical)");
    return 0;
}
