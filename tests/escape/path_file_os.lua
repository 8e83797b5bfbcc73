-- expect: error path_os.lua:1: attempt to index a nil value (global 'os')
-- issue 21 item 3: a camera-path file that touches os.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.path.load, c.write("path_os.lua", "os.remove('x') return {kind = 'orbit', center = {0, 0, 0}, distance = 3}"))
