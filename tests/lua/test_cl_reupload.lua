-- tests/lua/test_cl_reupload.lua - cdvr.render{device="cl"} keeps the frame on the device
-- between renders (the render context holds the volume: stat uploaded_bytes 0) but must upload
-- it again when the volume is edited in place (v:set), even by a single voxel, when a
-- different volume of the same dims is rendered, and when the held volume was dropped or
-- closed and another made (maybe at its address); two volumes rendered in turn keep a stream
-- each and upload nothing on the second round.
local info, msg = cdvr.cl_info()
if not info then
  print("skip: no OpenCL device: " .. tostring(msg))
  os.exit(77)
end
local failed = 0
local function check(cond, what)
  if not cond then
    failed = failed + 1
    io.stderr:write("check failed: ", what, "\n")
  end
end

local dims = {24, 20, 16}
local v = cdvr.volume{dims = dims}
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {100, 0, 0, 0, 0}, {255, 1, .8, .4, .9}}
local cam = cdvr.camera{eye = {11.5, -60, 7.5}, center = {11.5, 9.5, 7.5}, up = {0, 0, 1},
                        fov = 30, width = 48, height = 32}
local opts = {tf = tf, camera = cam, device = "cl"}
local empty = cdvr.render(v, opts)
check(cdvr.compare(empty, cdvr.render(v, {tf = tf, camera = cam, device = "cpu"})).maxerr <= 0.5, "empty volume")

-- the script's own volume is held by the render context: a second render uploads nothing
local again = cdvr.render(v, opts)
check(again:stats().uploaded_bytes == 0, "second render uploaded " ..
      tostring(again:stats().uploaded_bytes) .. " bytes")

-- one bright voxel in the middle of a volume already on the device
v:set(12, 10, 8, 255)
local edited = cdvr.render(v, opts)
check(edited:stats().uploaded_bytes == 24 * 20 * 16, "v:set: uploaded " ..
      tostring(edited:stats().uploaded_bytes) .. " bytes")
local cpu = cdvr.render(v, {tf = tf, camera = cam, device = "cpu"})
local r = cdvr.compare(edited, cpu)
print(("one voxel set: psnr vs cpu %.1f dB, maxerr vs before %.3f"):format(
  r.psnr, cdvr.compare(edited, empty).maxerr))
check(r.psnr >= 50, "edited volume: cl vs cpu psnr " .. r.psnr)
check(cdvr.compare(edited, empty).maxerr > 0.5, "the edit did not reach the device")

-- setting it back restores the first image
v:set(12, 10, 8, 0)
check(cdvr.compare(cdvr.render(v, opts), empty).maxerr <= 0.5, "undoing the edit")

-- another volume of the same dims
local w = cdvr.volume{dims = dims}
w:set(5, 5, 5, 255)
check(cdvr.compare(cdvr.render(w, opts), cdvr.render(w, {tf = tf, camera = cam, device = "cpu"})).psnr >= 50,
      "second volume of the same dims")

-- two volumes rendered in turn (an original beside its edited copy): the context holds both
-- and keeps a device stream for each, so the second round uploads nothing, and each image
-- stays its own
local p, q = cdvr.volume{dims = dims}, cdvr.volume{dims = dims}
p:set(3, 3, 3, 255)
q:set(20, 15, 12, 255)
local first = {cdvr.render(p, opts), cdvr.render(q, opts)}
for round = 1, 2 do
  for i, vol in ipairs({p, q}) do
    local img = cdvr.render(vol, opts)
    check(img:stats().uploaded_bytes == 0, ("in turn, round %d, volume %d: uploaded %s bytes"):format(
          round, i, tostring(img:stats().uploaded_bytes)))
    check(cdvr.compare(img, first[i]).maxerr == 0, ("in turn, round %d, volume %d: image"):format(round, i))
  end
end
check(cdvr.compare(first[1], first[2]).maxerr > 0.5, "the two volumes render differently")
-- a third volume of other dims takes the place of the one rendered least recently (p)
local wide = cdvr.volume{dims = {30, 12, 10}}
wide:set(15, 6, 5, 255)
cdvr.render(wide, opts)
check(cdvr.render(q, opts):stats().uploaded_bytes == 0, "q kept its stream beside the third volume")
check(cdvr.render(p, opts):stats().uploaded_bytes == 24 * 20 * 16, "p was uploaded again")

-- a held volume dropped and another loaded (maybe where it lay): the new one's image
local function block_volume(x)
  local b = cdvr.volume{dims = dims}
  for z = 6, 9 do for y = 6, 9 do b:set(x, y, z, 255) end end
  return b
end
local a = block_volume(4)
local ia = cdvr.render(a, opts)
local dropped = setmetatable({a}, {__mode = "v"})
a = nil
cdvr.render(p, opts) -- two other volumes take the context's holds: a is released
cdvr.render(q, opts)
collectgarbage()
check(dropped[1] == nil, "a dropped volume the context no longer holds is collected")
collectgarbage()
local b = block_volume(18)
local ib = cdvr.render(b, opts)
check(cdvr.compare(ia, ib).maxerr > 0.5, "the volume loaded after a dropped one renders as that")
check(cdvr.compare(ib, cdvr.render(b, {tf = tf, camera = cam, device = "cpu"})).psnr >= 50,
      "a volume loaded after a held one was dropped: cl vs cpu")

-- a held volume closed (<close>) while the context holds it, then another rendered
do
  local c <close> = block_volume(10)
  cdvr.render(c, opts)
end
collectgarbage()
local d = block_volume(14)
check(cdvr.compare(cdvr.render(d, opts), cdvr.render(d, {tf = tf, camera = cam, device = "cpu"})).psnr >= 50,
      "a volume rendered after the held one was closed")

-- the edit of a 2-timestep volume between renders of each timestep
local s2 = cdvr.volume{dims = dims, timesteps = 2}
local before = {}
for t = 1, 2 do before[t] = cdvr.render(s2, {tf = tf, camera = cam, device = "cl", t = t}) end
for z = 6, 9 do for y = 6, 9 do s2:set(12, y, z, 2, 255) end end -- timestep 2 only
for t = 1, 2 do
  local img = cdvr.render(s2, {tf = tf, camera = cam, device = "cl", t = t})
  check(cdvr.compare(img, cdvr.render(s2, {tf = tf, camera = cam, t = t, device = "cpu"})).psnr >= 50,
        "timestep " .. t .. " after an edit of timestep 2: cl vs cpu")
  check((cdvr.compare(img, before[t]).maxerr > 0.5) == (t == 2),
        "timestep " .. t .. " changed only where edited")
end

if failed > 0 then
  io.stderr:write(failed, " check(s) failed\n")
  os.exit(1)
end
print("ok")
