-- expect: ok round trip ok
-- issue 21 item 3: what tf:save, cam:save and cdvr.path.save write loads back through the data
-- loader; code files still run through dofile (cdvr.tf(dofile(path))).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {60, .9, .6, .4, .05}, {255, 1, 1, 1, .8}, unit = 2}
local tfile = c.dir .. "/tf_saved.lua"
assert(tf:save(tfile))
local tf2 = cdvr.tf(tfile)
assert(#tf2:points() == 3 and tf2:unit() == 2)
local cam = cdvr.camera{eye = {40, 5, 5}, center = {5, 5, 5}, up = {0, 0, 1}, fov = 35, width = 64, height = 48}
local cfile = c.dir .. "/cam_saved.lua"
assert(cam:save(cfile))
local cam2 = cdvr.camera(cfile)
assert(cam2.fov == 35 and cam2.width == 64)
local p = cdvr.path.orbit{center = {5, 5, 5}, distance = 30, period = 10}
local pfile = c.dir .. "/path_saved.lua"
assert(cdvr.path.save(p, pfile))
local p2 = cdvr.path.load(pfile)
assert(math.abs(p2(3).eye[1] - p(3).eye[1]) < 1e-9)
local code = c.write("tf_code.lua", "local pts = {} for i = 0, 4 do pts[#pts + 1] = {i * 60, 1, 1, 1, i / 4} end return pts")
assert(#cdvr.tf(dofile(code)):points() == 5)
print("round trip ok")
