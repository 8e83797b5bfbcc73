-- expect: error cam_os.lua:1: attempt to index a nil value (global 'os')
-- issue 21 item 3: a camera file that runs a command (before: os.execute ran).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local flag = c.dir .. "/pwned"
local ok, err = pcall(cdvr.camera, c.write("cam_os.lua", "os.execute('touch " .. flag .. "') return {eye = {1, 2, 3}}"))
assert(not c.exists(flag), "the camera file ran a command")
error(err, 0)
