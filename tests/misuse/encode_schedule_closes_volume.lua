-- expect: ok encoded while closed
-- issue 11 item 1: a schedule that closes the volume being encoded; the close waits for the
-- encoder, which reads intact data (the store equals one encoded without the close).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local function series() return cdvr.generate('sphere', {dims = {12, 12, 12}, timesteps = 6}) end
local v = series()
local st = assert(cdvr.encode(v, {path = c.dir .. '/e.cdv', progress = false,
  schedule = function(t) do local x <close> = v end return {S = 4, T = 3} end}))
assert(c.closed(v, 'dims'), 'the volume is closed after the encode')
local ref = assert(cdvr.encode(series(), {path = c.dir .. '/ref.cdv', progress = false}))
for t = 1, 6 do
  assert(cdvr.compare(st:decode(t), ref:decode(t)).maxerr == 0, 'timestep ' .. t .. ' differs')
end
print('encoded while closed')
