/* lua/l_player.c - Lua binding of the player module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_player(lua_State *L)
{
    (void)L;
    return 0;
}
