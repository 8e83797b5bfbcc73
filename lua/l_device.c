/* lua/l_device.c - Lua binding of the device module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_device(lua_State *L)
{
    (void)L;
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
