-- expect: error tf_table.lua: data file runs too long
-- issue 21 item 3: a TF file that builds a 1e9-entry table (before: 4-6 GB, minutes).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.tf, c.write("tf_table.lua", "local t = {} for i = 1, 1e9 do t[i] = i end return t"))
