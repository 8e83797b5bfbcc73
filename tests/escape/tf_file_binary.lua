-- expect: error tf_binary.lua: a precompiled (binary) chunk is not a data file (text only)
-- issue 21 item 3: a precompiled TF file (bytecode is not checked by Lua: never loaded).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.tf, c.write("tf_binary.lua", string.dump(function() return {{0, 0,0,0, 0}, {255, 1,1,1, 1}} end)))
