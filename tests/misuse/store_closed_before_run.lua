-- expect: ok played 3 frames after st:close()
-- issue 11 item 1: st:close() before p:run is deferred while the player holds the store.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p = c.player(st)
st:close()
assert(c.closed(st, 'info'), 'the store is closed for Lua')
assert(tostring(st):find('closed'))
local r = p:run{frames = 3}
assert(#r.frames == 3 and not r.frames[1].error, 'played')
assert(tostring(p):find('s.cdv', 1, true), tostring(p))
p:close()
print('played 3 frames after st:close()')
