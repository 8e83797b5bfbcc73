-- expect: error tf_io.lua:1: attempt to index a nil value (global 'io')
-- issue 21 item 3: a TF file that reads another file (before: io.open worked).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.tf, c.write("tf_io.lua", "local f = io.open('/etc/passwd') return {{0, 0,0,0, 0}, {255, 1,1,1, 1}}"))
