-- expect: error player is running
-- issue 11 item 1: the player as a to-be-closed variable inside its own callback.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p
p = c.player(st, {camera = function() local q <close> = p return c.camera end})
p:run{frames = 2}
