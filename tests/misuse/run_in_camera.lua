-- expect: error player is running
-- issue 11 item 2: p:run from the player's own camera callback (before: NULL dereference).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p
local once
p = c.player(st, {camera = function()
  if not once then once = true; p:run{frames = 1} end
  return c.camera
end})
p:run{frames = 3}
