-- expect: ok 6 frames, store closed in the policy
-- issue 11 item 1: st:close() inside a policy callback is deferred until the player lets go.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local calls = 0
local p = c.player(st, {policy = function(stats) calls = calls + 1; st:close(); return 'S4T3' end})
local r = p:run{frames = 6}
assert(#r.frames == 6 and calls == 2, 'played with decisions')
for _, row in ipairs(r.frames) do assert(not row.error, row.error) end
assert(c.closed(st, 'info'))
p:close()
print('6 frames, store closed in the policy')
