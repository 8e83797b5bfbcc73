/* lua/l_render.c - Lua binding of the render module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_render(lua_State *L)
{
    (void)L;
    return 0;
}
