/* lua/l_image.c - Lua binding of the image module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_image(lua_State *L)
{
    (void)L;
    return 0;
}
