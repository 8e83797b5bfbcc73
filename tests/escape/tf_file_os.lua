-- expect: error tf_os.lua:1: attempt to index a nil value (global 'os')
-- issue 21 item 3: a TF file that runs a command (before: os.execute ran, the file was made).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local flag = c.dir .. "/pwned"
local file = c.write("tf_os.lua", "os.execute('touch " .. flag .. "') return {{0, 0,0,0, 0}, {255, 1,1,1, 1}}")
local ok, err = pcall(cdvr.tf, file)
assert(not c.exists(flag), "the TF file ran a command")
error(err, 0)
