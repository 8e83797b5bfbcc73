-- scripts/regress.lua [--update] [--reference FILE]
-- Runs a fixed set of encodes and renders on deterministic inputs (synthetic fields, plus the
-- real viscous-fingers series when ../shared/data is present), and compares each figure with
-- the reference stored in share/regress/reference.lua. Exits 1 naming every check that moved
-- beyond its tolerance (or has no reference); --update rewrites the reference file instead.
local update = false
local ref_path = cdvr.share_dir .. "/regress/reference.lua"
for i = 1, #arg do
  if arg[i] == "--update" then update = true
  elseif arg[i] == "--reference" then ref_path = arg[i + 1] end
end

local results = {}   -- name -> {value=, tol=}
local function record(name, value, tol) results[name] = {value = value, tol = tol} end

local variants = {{S = 1, T = 3}, {S = 4, T = 3}, {S = 1, T = 2, pack = "space"}, {S = 4, T = 2},
                  {S = 1, T = 3, encoder = "bbox", name = "S1T3bbox"}}
local tmp = os.tmpname()

local function check_series(label, q, tf, cam)
  local st = assert(cdvr.encode(q, {variants = variants, stage2 = "lzo", path = tmp}))
  local info = st:info()
  local ref_img = cdvr.render(q, {tf = tf, camera = cam, t = 1, device = "cpu"})
  for _, var in ipairs(info.variants) do
    record(("%s/%s/volume_psnr"):format(label, var.name), var.psnr, 0.02)
    record(("%s/%s/bytes"):format(label, var.name), var.bytes, math.max(64, 0.01 * var.bytes))
    local img = cdvr.render(st:decode(1, var.name), {tf = tf, camera = cam, device = "cpu"})
    record(("%s/%s/image_psnr"):format(label, var.name), cdvr.compare(img, ref_img).psnr, 0.1)
  end
  st:close()
  os.remove(tmp)
end

-- Synthetic: Marschner-Lobb (static) and a moving sphere (time series), odd dims.
local ml = cdvr.generate("ml", {dims = {41, 41, 41}})
local sphere = cdvr.generate("sphere", {dims = {33, 29, 31}, timesteps = 6})
local tf = cdvr.tf("hot")
local function cam_for(v) return cdvr.orbit_camera(v, {azimuth = 35, elevation = 25, width = 128, height = 128}) end
check_series("ml", ml, tf, cam_for(ml))
check_series("sphere", sphere, tf, cam_for(sphere))

-- Reference renderer against itself at another step: a fixed image figure.
local img_a = cdvr.render(ml, {tf = tf, camera = cam_for(ml), step = 0.25, device = "cpu"})
local img_b = cdvr.render(ml, {tf = tf, camera = cam_for(ml), step = 1.0, device = "cpu"})
record("render/ml/step1_vs_step025_psnr", cdvr.compare(img_a, img_b).psnr, 0.1)

-- Real series, when the shared data is there.
local shared = os.getenv("CDVR_SHARED_DATA")
if shared and io.open(shared .. "/series/viscousfingers/vf_t040.nrrd") then
  local vf = assert(cdvr.load_series(shared .. "/series/viscousfingers/vf_t%03d.nrrd", {first = 40, count = 6}))
  local q = vf:quantize{lo = 0, hi = 120}
  check_series("viscousfingers6", q, tf, cam_for(q))
end

local names = {}
for k in pairs(results) do names[#names + 1] = k end
table.sort(names)

if update then
  local f = assert(io.open(ref_path, "w"))
  f:write("-- Reference figures for scripts/regress.lua (written by --update; review diffs).\nreturn {\n")
  for _, k in ipairs(names) do
    local r = results[k]
    f:write(("  [%q] = {value = %.17g, tol = %.17g},\n"):format(k, r.value == math.huge and 1e308 or r.value, r.tol))
  end
  f:write("}\n")
  f:close()
  print(("regress: wrote %d reference figures to %s"):format(#names, ref_path))
  return
end

local ref = assert(dofile(ref_path))
local failed, passed = {}, 0
for _, k in ipairs(names) do
  local r, want = results[k], ref[k]
  local value = r.value == math.huge and 1e308 or r.value
  if not want then
    failed[#failed + 1] = ("%s: no reference figure (got %.6g; run with --update)"):format(k, value)
  elseif math.abs(value - want.value) > want.tol then
    failed[#failed + 1] = ("%s: %.6g, reference %.6g +- %.3g"):format(k, value, want.value, want.tol)
  else
    passed = passed + 1
  end
end
for _, msg in ipairs(failed) do io.stderr:write("regress: MOVED " .. msg .. "\n") end
print(("%d passed, %d failed"):format(passed, #failed))
if #failed > 0 then os.exit(1) end
