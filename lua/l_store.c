/* lua/l_store.c - Lua binding of the store module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_store(lua_State *L)
{
    (void)L;
    return 0;
}
