-- expect: error path_loop.lua: data file runs too long
-- issue 21 item 3: a camera-path file that loops.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.path.load, c.write("path_loop.lua", "while 1 do end"))
