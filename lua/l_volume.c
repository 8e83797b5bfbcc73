/* lua/l_volume.c - Lua binding of the volume module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_volume(lua_State *L)
{
    (void)L;
    return 0;
}
