/* lua/l_compare.c - Lua binding of the compare module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_compare(lua_State *L)
{
    (void)L;
    return 0;
}
