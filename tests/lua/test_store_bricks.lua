-- Bricked stores through Lua: st:info() lists the bricks; decode assembles them; a bricked
-- raw store decodes to the input exactly and plays (cpu and cl device) the same frames as the
-- unbricked store; a lossy bricked variant renders close to its unbricked twin.
local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))

local vol = cdvr.generate("ml", {dims = {23, 18, 15}, timesteps = 4})
local plain = assert(cdvr.encode(vol, {path = tmp .. "/plain.cdv", progress = false,
                                       variants = {{codec = "raw"}, {S = 1, T = 3}}}))
local bricked = assert(cdvr.encode(vol, {path = tmp .. "/bricked.cdv", progress = false,
                                         bricks = {3, 2, 2},
                                         variants = {{codec = "raw"}, {S = 1, T = 3}}}))
local info = bricked:info()
assert(#info.bricks == 12 and info.brick_grid[1] == 3 and info.brick_grid[3] == 2)
local b3 = info.bricks[3]
assert(b3.lo[1] == 14 and b3.dims[1] == 9, ("brick 3 x: %d+%d"):format(b3.lo[1], b3.dims[1]))
assert(info.variants[1].chunks == 48 and info.variants[2].chunks == 24)
for t = 1, 4 do
  local d = bricked:decode(t, "raw")
  local c = cdvr.compare(d, vol:frame(t))
  assert(c.maxerr == 0, "raw bricks reassemble exactly")
end

local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(vol, {azimuth = 35, elevation = 25, width = 40, height = 32})
local devices = {"cpu"}
if cdvr.cl_info() then devices[2] = "cl" end
for _, dev in ipairs(devices) do
  local images = {}
  for name, st in pairs{plain = plain, bricked = bricked} do
    local p = cdvr.player{store = st, tf = tf, camera = cam, device = dev, variant = "raw",
                          out = tmp .. "/" .. name .. "_" .. dev .. "_%02d.png"}
    local r = p:run{frames = 4}
    assert(#r.frames == 4)
    for _, row in ipairs(r.frames) do assert(not row.error, row.error) end
  end
  for f = 1, 4 do
    local a = io.open(("%s/plain_%s_%02d.png"):format(tmp, dev, f), "rb"):read("a")
    local b = io.open(("%s/bricked_%s_%02d.png"):format(tmp, dev, f), "rb"):read("a")
    assert(a == b, dev .. ": bricked raw frame " .. f .. " differs")
  end
end
local lossy = cdvr.compare(cdvr.render(bricked, {t = 2, variant = "S1T3", tf = tf, camera = cam}),
                           cdvr.render(plain, {t = 2, variant = "S1T3", tf = tf, camera = cam}))
assert(lossy.psnr > 30, "bricked S1T3 renders like the unbricked one: " .. lossy.psnr)
os.execute(("rm -rf %q"):format(tmp))
print("test_store_bricks: ok")
