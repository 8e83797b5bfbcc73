-- expect: error tf_rep.lua:1: data file calls a function (not plain data)
-- issue 21 item 3: a string.rep bomb in a TF file (before: 1 GiB allocated).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.tf, c.write("tf_rep.lua", "return {{0, 0,0,0, 0}, {255, 1,1,1, 1}, name = ('x'):rep(1 << 30)}"))
