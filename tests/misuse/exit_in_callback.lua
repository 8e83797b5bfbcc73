-- expect: ok leaving from the callback
-- issue 11 item 1: os.exit(0, true) inside a callback closes the state while the player runs.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p = c.player(st, {camera = function()
  print('leaving from the callback')
  io.stdout:flush()
  os.exit(0, true)
end})
p:run{frames = 3}
