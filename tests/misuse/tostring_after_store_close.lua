-- expect: ok cdvr.Player
-- issue 11 item 1: tostring(p) after st:close() reads the store the player still holds.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p = c.player(st)
st:close()
collectgarbage() collectgarbage()
print(tostring(p))
