-- expect: error tf_loop.lua: data file runs too long
-- issue 21 item 3: a TF file that loops (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.tf, c.write("tf_loop.lua", "while true do end"))
