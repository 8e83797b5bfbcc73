-- expect: error cam_loop.lua: data file runs too long
-- issue 21 item 3: a camera file that loops (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.camera, c.write("cam_loop.lua", "local x = 0 repeat x = x + 1 until false"))
