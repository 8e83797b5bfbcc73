-- expect: error player is running
-- issue 11 item 1: p:close() from the player's own policy callback (before: deadlock in
-- pthread_cond_destroy).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p
p = c.player(st, {policy = function() p:close() return 'S4T3' end})
p:run{frames = 6}
