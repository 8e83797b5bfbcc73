-- tests/lua/test_cpu_ranges.lua - the CPU ray caster keeps the brick ranges of the script's own
-- volume between renders (the render context holds it; cdvr_cpu_skip_cache_hold) and makes
-- them again when the volume is edited in place (v:set: its revision), when another volume
-- is rendered, and when the held volume was dropped and another made (maybe at its address).
-- Every image equals the render with skip=false (every sample taken), bit for bit: stale
-- ranges would skip the edited bricks.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check = checks.check

local dims = {24, 20, 16}
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {100, 0, 0, 0, 0}, {255, 1, .8, .4, .9}}
local cam = cdvr.camera{eye = {11.5, -60, 7.5}, center = {11.5, 9.5, 7.5}, up = {0, 0, 1},
                        fov = 30, width = 48, height = 32}
local opts = {tf = tf, camera = cam, device = "cpu"}
local exact = {tf = tf, camera = cam, device = "cpu", skip = false}

local function same_as_every_sample(v, what)
  local img = cdvr.render(v, opts)
  check(cdvr.compare(img, cdvr.render(v, exact)).maxerr == 0, what .. ": equals skip=false")
  return img
end

local v = cdvr.volume{dims = dims}
local empty = same_as_every_sample(v, "empty volume")
same_as_every_sample(v, "empty volume again")
v:set(12, 10, 8, 255) -- one bright voxel in a brick that was empty
local edited = same_as_every_sample(v, "one voxel set")
check(cdvr.compare(edited, empty).maxerr > 0.1, "the voxel set shows")
same_as_every_sample(v, "one voxel set, again")
v:set(12, 10, 8, 0)
check(cdvr.compare(same_as_every_sample(v, "voxel cleared"), empty).maxerr == 0,
      "the voxel cleared: the empty image")

-- another volume of the same dims, then v again
local w = cdvr.volume{dims = dims}
for x = 3, 5 do for y = 4, 6 do for z = 5, 7 do w:set(x, y, z, 200) end end end
same_as_every_sample(w, "another volume")
same_as_every_sample(v, "v after another volume")

-- the held volume dropped and a new one made (maybe at its address), with other voxels
v, w = nil, nil
collectgarbage()
collectgarbage()
local u = cdvr.volume{dims = dims}
for x = 19, 21 do for y = 14, 16 do for z = 9, 11 do u:set(x, y, z, 255) end end end
check(cdvr.compare(same_as_every_sample(u, "a new volume after the held one was dropped"),
                   empty).maxerr > 0.1, "the new volume's voxel shows")
checks.finish()
