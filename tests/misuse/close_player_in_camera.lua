-- expect: error player is running
-- issue 11 item 1: p:close() from the player's own camera callback (before: use after free).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p
p = c.player(st, {camera = function(frame, t) p:close() return c.camera end})
p:run{frames = 3}
