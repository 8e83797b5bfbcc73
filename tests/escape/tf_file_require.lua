-- expect: error tf_require.lua:1: attempt to call a nil value (global 'require')
-- issue 21 item 3: require, load and dofile are not there in a TF file.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local ok, e1 = pcall(cdvr.tf, c.write("tf_load.lua", "return load('return 1')()"))
assert(not ok and e1:find("global 'load'"), e1)
local ok2, e2 = pcall(cdvr.tf, c.write("tf_dofile.lua", "return dofile('x')"))
assert(not ok2 and e2:find("global 'dofile'"), e2)
c.refuse(cdvr.tf, c.write("tf_require.lua", "return require('os')"))
