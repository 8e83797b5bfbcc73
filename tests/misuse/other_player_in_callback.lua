-- expect: ok nested run of another player
-- issue 11 item 2: another player may run from a callback (its own budget and stack).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local q = c.player(st)
local nested = 0
local p = c.player(st, {camera = function() nested = nested + #q:run{frames = 1}.frames return c.camera end})
local r = p:run{frames = 3}
assert(#r.frames == 3 and nested == 3)
print('nested run of another player')
