-- expect: error cam_cb.lua: data file runs too long
-- issue 21 item 3: a looping camera file loaded from inside a camera callback: its own data
-- budget, inside the callback's.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local file = c.write("cam_cb.lua", "while true do end")
c.play(nil, function() return cdvr.camera(file) end)
