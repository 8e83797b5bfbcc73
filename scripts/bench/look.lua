-- scripts/bench/look.lua - the cost of the look (issue 22): frame time per blend mode and with
-- shading on and off, on the CPU reference and on OpenCL, at 512x512 on the engine CT and
-- Colin27 (../shared/data), each as a ratio to the unshaded composite frame of the same device
-- and volume measured in the same run. The cases are interleaved (A B C ... A B C ...: one
-- render of each case per round, `--repeats` rounds), so a load change on the machine touches
-- every case alike; the median of the rounds is reported. /proc/loadavg is recorded before and
-- after each volume. CSV on stdout, progress on stderr when it is a terminal.
--   build/cdvr scripts/bench/look.lua [--repeats 5] [--size 512] [--devices cpu,cl]
--                                     [--volumes engine,colin27] [--step 0.5]
-- Columns: volume, device, blend, shade, size, step, repeats, median_ms, min_ms, ratio (to the
-- unshaded composite of that device and volume), psnr_vs_cpu (this image against the CPU image
-- of the same case; "inf" when identical), samples (ray samples of the last frame),
-- load_before, load_after (1-minute load averages).
-- Targets (issue 22): shaded composite on cl at most 2x the unshaded one; max no slower than
-- composite.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"
local _, opt = common.parse_args(arg, {repeats = "5", size = "512", devices = "cpu,cl",
                                       volumes = "engine,colin27", step = "0.5"})
local repeats, size, step = tonumber(opt.repeats), tonumber(opt.size), tonumber(opt.step)
local data = common.shared_data()

-- The volumes, each with a TF in its own units (the one of vs_vtk.py for the engine), the
-- iso-surface value and a camera (orbit_camera's framing).
local VOLUMES = {
  engine = {path = data .. "/ct/engine_256x256x128_u8.nrrd", iso = 180,
            tf = {{0, 0, 0, 0, 0}, {80, 0.6, 0.3, 0.1, 0.0}, {120, 0.8, 0.5, 0.2, 0.02},
                  {180, 0.9, 0.9, 0.9, 0.3}, {255, 1.0, 1.0, 1.0, 0.9}}},
  colin27 = {path = data .. "/mri/colin27_t1_301x370x316_u8.nii.gz", iso = 75,
             tf = {{0, 0, 0, 0, 0}, {35, 0, 0, 0, 0}, {60, 0.8, 0.45, 0.35, 0.03},
                   {90, 1.0, 0.85, 0.7, 0.3}, {130, 1, 1, 1, 0.8}}},
}
-- VTK's volume-property defaults (ambient 0.1, diffuse 0.7, specular 0.2, power 10), headlight.
local SHADE = {shade = true, ambient = 0.1, diffuse = 0.7, specular = 0.2, specular_power = 10}
local CASES = {
  {blend = "composite", shade = false}, {blend = "composite", shade = true},
  {blend = "max"}, {blend = "min"}, {blend = "average"},
  {blend = "iso", shade = false}, {blend = "iso", shade = true},
}

local function split(s)
  local out = {}
  for w in s:gmatch("[^,]+") do out[#out + 1] = w end
  return out
end

local function loadavg()
  local f = io.open("/proc/loadavg")
  if not f then return "nan" end
  local l = f:read("l")
  f:close()
  return l:match("^(%S+)")
end

local devices = split(opt.devices)
for _, d in ipairs(devices) do
  if d == "cl" and not cdvr.cl_info() then
    local _, msg = cdvr.cl_info()
    error("look.lua: no OpenCL device (" .. tostring(msg) .. "); pass --devices cpu")
  end
end

print("volume,device,blend,shade,size,step,repeats,median_ms,min_ms,ratio,psnr_vs_cpu,samples,"
      .. "load_before,load_after")
for _, vname in ipairs(split(opt.volumes)) do
  local spec = VOLUMES[vname] or error("look.lua: unknown volume '" .. vname .. "' (engine, colin27)")
  local v = assert(cdvr.load(spec.path))
  local tf = cdvr.tf(spec.tf)
  local cam = cdvr.orbit_camera(v, {azimuth = 45, elevation = 25, width = size, height = size})
  -- every (device, case) pair, with its render options
  local runs = {}
  for _, dev in ipairs(devices) do
    for _, c in ipairs(CASES) do
      local o = {tf = tf, camera = cam, step = step, device = dev, blend = c.blend,
                 background = {0, 0, 0, 1}}
      if c.blend == "iso" then o.iso = {value = spec.iso, color = {0.9, 0.85, 0.75}} end
      if c.shade then for k, x in pairs(SHADE) do o[k] = x end
      elseif c.shade == false then o.shade = false end -- (iso shades unless told not to)
      runs[#runs + 1] = {dev = dev, case = c, opts = o, ms = {}}
    end
  end
  for _, r in ipairs(runs) do cdvr.render(v, r.opts) end -- warm-up: kernels, uploads, tables
  local load_before = loadavg()
  for round = 1, repeats do
    for _, r in ipairs(runs) do
      common.progress("%s round %d/%d: %s %s%s", vname, round, repeats, r.dev, r.case.blend,
                      r.case.shade and " shaded" or "")
      local t0 = cdvr.clock()
      local img, stats = cdvr.render(v, r.opts)
      r.ms[round] = (cdvr.clock() - t0) * 1e3
      if round == repeats then r.img, r.samples = img, stats and stats.samples end
    end
  end
  common.progress_done()
  local load_after = loadavg()
  local base, cpu_img = {}, {}
  for _, r in ipairs(runs) do
    r.median = common.median(r.ms)
    local key = r.case.blend .. tostring(r.case.shade)
    if r.case.blend == "composite" and not r.case.shade then base[r.dev] = r.median end
    if r.dev == "cpu" then cpu_img[key] = r.img end
  end
  for _, r in ipairs(runs) do
    local key = r.case.blend .. tostring(r.case.shade)
    local psnr = cpu_img[key] and cdvr.compare(r.img, cpu_img[key]).psnr or 0 / 0
    local mn = math.huge
    for _, x in ipairs(r.ms) do mn = math.min(mn, x) end
    local shade = r.case.shade and "on" or "off" -- max, min and average ignore shading
    if r.case.blend == "max" or r.case.blend == "min" or r.case.blend == "average" then shade = "n/a" end
    print(("%s,%s,%s,%s,%d,%g,%d,%.2f,%.2f,%.3f,%s,%s,%s,%s"):format(vname, r.dev, r.case.blend,
      shade, size, step, repeats, r.median, mn, r.median / base[r.dev],
      psnr == math.huge and "inf" or ("%.2f"):format(psnr), tostring(r.samples or ""),
      load_before, load_after))
    io.stdout:flush()
  end
  if opt.images then -- --images DIR: the last frame of each case, for looking at
    os.execute(('mkdir -p "%s"'):format(opt.images))
    for _, r in ipairs(runs) do
      r.img:save(("%s/%s_%s_%s%s.png"):format(opt.images, vname, r.dev, r.case.blend,
                                             r.case.shade and "_shaded" or ""))
    end
  end
end
