-- scripts/report.lua DATASET... [--out DIR] [--frames N] [--width W] [--device cl|cpu|auto]
--                   [--zfp RATES] [--timesteps N] [--first I] [--count N] [--read-mbps M]
--                   [--stage2 none|lzo|lz4|zstd|auto]
-- Speed against error (DESIGN.md §8). For each dataset (a directory of NRRD files, a printf
-- pattern, a 4D NIfTI or a single volume): encode every PVTC variant (S 1/4, T 2/3, time and
-- space packing), raw, and, when the zfp plugin is loaded, zfp at each rate of --zfp (bits per
-- voxel, default 0.5,1,2,4; "none" leaves zfp out), play each back along the same orbit path,
-- and measure
--   fps / frame_ms : median over the played frames (pipelined player);
--   image_psnr     : mean over the path's frames of the PSNR of the render of the decoded
--                    variant against the render of the uncompressed data (same camera);
--   volume_psnr, maxerr : measured at encode time over all timesteps;
--   stage2         : the stage 2 of the variant's chunks (--stage2, default none; auto models
--                    read at --read-mbps, default the rate the store's filesystem reads
--                    uncached data at, measured once and remembered, + unpack per chunk and
--                    records its choice: "auto:lz4=5/none=1" counts the chunks of each choice);
--   unpack_mb_s    : payload MB/s of undoing it (st:bench_unpack, all cores, median of 3).
-- --timesteps N keeps the first N timesteps of each dataset (for quick runs); a printf
-- pattern ("vf_t%03d.nrrd") starts at index --first (default 0) and takes --count files or as
-- many as exist; --read-mbps M plays through an emulated disk of M MB/s (the out-of-core case
-- compression is for).
-- Writes DIR/report.csv and DIR/report.png (gnuplot: fps against image PSNR, one colour and
-- legend entry per dataset, each point labelled with its configuration). A dataset that fails
-- (missing files, unreadable data) is reported on stderr and in DIR/failed.txt, the others are
-- still measured and written, and the exit status is 1.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/bench/?.lua;" .. package.path
local common = require "common"

local datasets, opt = common.parse_args(arg, {out = "out/report", frames = "24", width = "256", device = "auto"})
if #datasets == 0 then datasets = {common.shared_data() .. "/series/viscousfingers"} end
local frames, width = tonumber(opt.frames), tonumber(opt.width)
os.execute(('mkdir -p "%s"'):format(opt.out))

local configs = {{name = "raw", codec = "raw"}}
for _, pack in ipairs{"time", "space"} do
  for _, S in ipairs{1, 4} do
    for _, T in ipairs{2, 3} do
      configs[#configs + 1] = {S = S, T = T, pack = pack,
                               name = ("S%dT%d%s"):format(S, T, pack == "space" and "s" or "")}
    end
  end
end

local function codec_loaded(name)
  for _, c in ipairs(cdvr.codecs and cdvr.codecs() or {}) do
    if c.name == name then return true end
  end
  return false
end
if (opt.zfp or "") ~= "none" and codec_loaded("zfp") then
  for rate in (opt.zfp or "0.5,1,2,4"):gmatch("[^,]+") do
    configs[#configs + 1] = {codec = "zfp", rate = assert(tonumber(rate), "--zfp: rates")}
  end
end

local function render_device()
  if opt.device ~= "auto" then return opt.device end
  return (cdvr.cl_info and cdvr.cl_info()) and "cl" or "cpu"
end
local device = render_device()

-- Measures one dataset under `name`; appends its rows. Raises on failure (caught by the caller).
local function measure(spec, name, rows)
  local vol = common.load_dataset(spec, {first = opt.first, count = opt.count})
  if opt.timesteps and tonumber(opt.timesteps) < vol:timesteps() then
    vol = vol:frame(1, tonumber(opt.timesteps))
  end
  local lo, hi = vol:range()
  local q = vol:quantize{lo = lo, hi = hi}
  local tmp = os.tmpname()
  common.progress("%s: encoding %d configurations", name, #configs)
  local st = cdvr.encode(q, {variants = configs, stage2 = opt.stage2 or "none", path = tmp,
                             stage2_read_mbps = tonumber(opt["read-mbps"])})
  local info = st:info()
  -- the oriented box in world coordinates, as the store gives it back
  local x0, x1, y0, y1, z0, z1 = st:decode(1):bounds()
  local c = {(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2}
  local path = cdvr.path.orbit{center = c, distance = 2.4 * math.max(x1 - x0, y1 - y0, z1 - z0),
                               up = {0, 0, 1}, elevation = 25, period = frames, fov = 30}
  local tf = cdvr.tf("hot")
  -- reference renders of the uncompressed data (the lossless raw variant, so that the
  -- reference has exactly the geometry and value window the store gives back) along the path
  local refs = {}
  for f = 1, frames do
    local t = (f - 1) % info.timesteps + 1
    refs[f] = cdvr.render(st:decode(t, "raw"), {tf = tf, camera = path:camera(f, width, width), device = device})
  end
  for vi, var in ipairs(info.variants) do
    common.progress("%s: %s (%d/%d)", name, var.name, vi, #info.variants)
    local p = cdvr.player{store = st, tf = tf, camera = path, variant = var.name, width = width,
                          height = width, device = device, read_mbps = tonumber(opt["read-mbps"]),
                          loop = true}
    local r = p:run{frames = frames}
    p:close()
    local psnr_sum, nfinite = 0, 0
    for f = 1, frames do
      local t = (f - 1) % info.timesteps + 1
      local img = cdvr.render(st:decode(t, var.name), {tf = tf, camera = path:camera(f, width, width), device = device})
      local cmp = cdvr.compare(img, refs[f])
      psnr_sum = psnr_sum + (cmp.psnr == math.huge and 0 or cmp.psnr)
      nfinite = nfinite + (cmp.psnr == math.huge and 0 or 1)
    end
    local image_psnr = nfinite == 0 and math.huge or psnr_sum / nfinite
    local stage2 = common.stage2_label(var)
    rows[#rows + 1] = {dataset = name, config = var.name, codec = var.codec,
                       bpv = 8 * var.bytes / info.raw_bytes, ratio = var.bytes / info.raw_bytes,
                       fps = r.fps, frame_ms = r.median.frame_ms, image_psnr = image_psnr,
                       volume_psnr = var.psnr, maxerr = var.maxerr, stage2 = stage2,
                       unpack_mb_s = st:bench_unpack(var.name, 3)}
  end
  st:close()
  os.remove(tmp)
end

local rows, names, failures = {}, {}, {}
local taken = {}
for _, spec in ipairs(datasets) do
  local name = common.dataset_name(spec)
  local n = 1
  while taken[name .. (n > 1 and ("#" .. n) or "")] do n = n + 1 end
  name = name .. (n > 1 and ("#" .. n) or "")
  taken[name] = true
  local ok, result = pcall(measure, spec, name, rows)
  if ok then
    names[#names + 1] = name
  else
    failures[#failures + 1] = ("%s: %s"):format(spec, tostring(result))
    common.progress_done()
    io.stderr:write(("report.lua: dataset %s failed: %s\n"):format(spec, tostring(result)))
  end
end
common.progress_done()

local fmt = common.csv_number
common.write_results(opt.out, "report.csv",
  "dataset,config,codec,bpv,ratio,fps,frame_ms,image_psnr,volume_psnr,maxerr,stage2,unpack_mb_s", rows,
  function(r)
    return ("%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s"):format(r.dataset, r.config, r.codec, fmt(r.bpv),
      fmt(r.ratio), fmt(r.fps), fmt(r.frame_ms), fmt(r.image_psnr), fmt(r.volume_psnr), fmt(r.maxerr),
      r.stage2, fmt(r.unpack_mb_s))
  end, failures, "report.lua")

-- Chart: one data block (gnuplot index) per dataset, each with its colour and legend entry;
-- lossless points (inf PSNR) are drawn at the right edge and labelled so.
local maxfin = 0
for _, r in ipairs(rows) do
  if r.image_psnr ~= math.huge then maxfin = math.max(maxfin, r.image_psnr) end
end
local lossless_x = maxfin + 6
local COLOURS = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf"}
local dat = assert(io.open(opt.out .. "/report.dat", "w"))
for i, name in ipairs(names) do
  if i > 1 then dat:write("\n\n") end
  for _, r in ipairs(rows) do
    if r.dataset == name then
      local x = r.image_psnr == math.huge and lossless_x or r.image_psnr
      local label = r.config .. (r.image_psnr == math.huge and " (lossless)" or "")
      dat:write(("%.4f %.4f \"%s\"\n"):format(x, r.fps, label))
    end
  end
end
dat:close()
local plots = {}
for i, name in ipairs(names) do
  local colour = COLOURS[(i - 1) % #COLOURS + 1]
  plots[#plots + 1] = ('"%s/report.dat" index %d using 1:2 with points pt 7 ps 1.4 lc rgb "%s" title "%s"'):format(
    opt.out, i - 1, colour, name:gsub('"', ""))
  plots[#plots + 1] = ('"" index %d using 1:2:3 with labels offset char 0,0.9 font ",8" tc rgb "%s" notitle'):format(
    i - 1, colour)
end
local gp = assert(io.open(opt.out .. "/report.gp", "w"))
gp:write(([[
set terminal pngcairo size 1100,750 font ",11" noenhanced
set output "%s/report.png"
set title "cdvr: playback speed against image quality (%dx%d, device %s%s)"
set xlabel "image PSNR against the uncompressed render (dB, higher is better; lossless at the right edge)"
set ylabel "frames per second (median, higher is better)"
set grid
set key outside right top box Left reverse title "dataset"
set offsets 1, 4, 2, 2
plot %s
]]):format(opt.out, width, width, device,
           opt["read-mbps"] and (", disk emulated at " .. opt["read-mbps"] .. " MB/s") or "",
           table.concat(plots, ", \\\n     ")))
gp:close()
local ok = os.execute(('gnuplot "%s/report.gp"'):format(opt.out))
if not ok then
  io.stderr:write("report.lua: gnuplot failed; report.csv is written\n")
  os.exit(1)
end
io.stderr:write(("report.lua: wrote %s/report.csv and %s/report.png\n"):format(opt.out, opt.out))
if #failures > 0 then
  io.stderr:write(("report.lua: %d of %d datasets failed (listed in %s)\n"):format(#failures, #datasets, failed_path))
  os.exit(1)
end
