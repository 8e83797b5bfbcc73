-- scripts/bench/render_digest.lua OUTDIR - renders the engine CT (../shared/data) with every method and
-- device, fixed camera and TF, and writes OUTDIR/digest.txt: an exact float digest per image. Two
-- binaries give the same digest when their images are bit-identical (used for issue 20).
local out = assert(arg[1], "usage: cdvr scripts/bench/render_digest.lua OUTDIR")
local v = cdvr.load((os.getenv("CDVR_SHARED_DATA") or (cdvr.share_dir .. "/../../shared/data")) .. "/ct/engine_256x256x128_u8.nrrd")
local cam = cdvr.camera{eye={520, -300, 260}, center={127.5, 127.5, 63.5}, up={0, 0, 1}, fov=30, width=256, height=256}
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {80, 0.5, 0.3, 0.2, 0}, {140, 0.9, 0.7, 0.5, 0.3}, {255, 1, 1, 0.95, 0.9}}
local function digest(img)
  local w, h = img:size()
  local s, s2 = 0, 0
  for y = 0, h - 1 do for x = 0, w - 1 do
    local r, g, b, a = img:pixel(x, y)
    s = s + r + 2*g + 3*b + 4*a
    s2 = s2 + (r*r + g*g + b*b + a*a) * ((x * 7 + y * 13) % 17)
  end end
  return string.format("%.17g %.17g", s, s2)
end
local f = io.open(out .. "/digest.txt", "w")
local function one(name, opts)
  opts.tf = tf; opts.camera = cam
  local img = cdvr.render(v, opts)
  img:save(out .. "/" .. name .. ".png")
  f:write(name, " ", digest(img), "\n")
end
one("raycast_cpu", {method="raycast", device="cpu"})
one("raycast_cl", {method="raycast", device="cl"})
one("raycast_cl_noskip", {method="raycast", device="cl", skip=false})
one("raycast_cpu_step1", {method="raycast", device="cpu", step=1.0, term=0.95})
one("slice", {method="slice"})
one("slice_nolod", {method="slice", lod=false})
one("splat", {method="splat", threshold=40})
one("splat_axis", {method="splat", order="axis", threshold=40})
-- a store, cl render from the chunk and cpu decode
local st = cdvr.encode(v, {variants={{S=4,T=3}, {codec="raw"}}, path=out .. "/engine.cdv"})
for _, dev in ipairs{"cpu", "cl"} do
  for _, var in ipairs{"S4T3", "raw"} do
    local img = cdvr.render(st, {tf=tf, camera=cam, device=dev, variant=var})
    f:write("store_" .. dev .. "_" .. var, " ", digest(img), "\n")
  end
end
-- player frames (cpu and cl)
for _, dev in ipairs{"cpu", "cl"} do
  local p = cdvr.player{store=st, tf=tf, camera=cam, device=dev, variant="S4T3",
                        frame=function(row, img) f:write("player_" .. dev, " ", digest(img), "\n") end}
  p:run{frames=1}
end
f:close()
