/* lua/l_camera.c - Lua binding of the camera module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_camera(lua_State *L)
{
    (void)L;
    return 0;
}
