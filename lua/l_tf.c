/* lua/l_tf.c - Lua binding of the tf module (placeholder until the module lands). */
#include "lcdvr.h"

int lcdvr_open_tf(lua_State *L)
{
    (void)L;
    return 0;
}
