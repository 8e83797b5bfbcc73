-- tests/lua/test_cl_reupload.lua - cdvr.render{device="cl"} keeps the frame on the device
-- between renders but must upload it again when the volume is edited in place (v:set), even
-- by a single voxel, and when a different volume of the same dims is rendered.
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
check(cdvr.compare(empty, cdvr.render(v, {tf = tf, camera = cam})).maxerr <= 0.5, "empty volume")

-- one bright voxel in the middle of a volume already on the device
v:set(12, 10, 8, 255)
local edited = cdvr.render(v, opts)
local cpu = cdvr.render(v, {tf = tf, camera = cam})
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
check(cdvr.compare(cdvr.render(w, opts), cdvr.render(w, {tf = tf, camera = cam})).psnr >= 50,
      "second volume of the same dims")

if failed > 0 then
  io.stderr:write(failed, " check(s) failed\n")
  os.exit(1)
end
print("ok")
