-- expect: error cam_mem.lua: data file exceeded its memory budget (callback_memory = 256 MB)
-- issue 21 item 3: a camera file that doubles a string without calling anything (before: out of
-- memory).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.camera, c.write("cam_mem.lua", "local s = 'xxxxxxxx' for i = 1, 40 do s = s .. s end return {eye = {1, 2, 3}}"))
