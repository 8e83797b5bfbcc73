-- scripts/frontier.lua [DATASET ...] [--out DIR] [--quick] [--series PATTERN|none]
--                     [--series-size 256] [--series-timesteps 3] [--timesteps 3] [--frames 6]
--                     [--width 128] [--device cl|cpu|auto] [--zfp RATES|none]
-- The speed-against-error frontier: which codec to pick for a target quality or size.
-- For each dataset (default: every dataset under ../shared/data, i.e. CDVR_SHARED_DATA: each
-- volume file and each directory of NRRD timesteps) and for a generated series (the real
-- viscous-fingers series upsampled to --series-size^3 by scripts/bench/make_series.py, written
-- under DIR/series; --series PATTERN takes an existing printf pattern of raw u8 cubes of that
-- size instead, --series none leaves it out), encode every codec and variant into one store:
--   raw; raw with stage 2 zstd, lz4 and auto (lossless, fewer bits; auto: cdvr.encode's
--   default, per chunk by the read + unpack model, the stage2 column names what it took);
--   PVTC S1T3, S4T3, S1T2, S4T2 (no stage 2), and S4T3 / S1T3 with stage 2 lzo, lz4, zstd,
--   auto;
--   zfp at each rate of --zfp (bits per voxel, default 0.5,1,2,4) when the zfp plugin is
--   loaded; hvq and hvqc (default parameters; hvqc also with shared=1 unless --quick) when
--   those codecs are registered;
-- then measure, per variant:
--   bpv          stored bits per voxel (chunks after stage 2; range tables not counted);
--   image_psnr   mean over --frames frames of an orbit of the PSNR of the render of the
--                decoded variant against the render of the raw variant (inf: identical);
--   volume_psnr  encode-time PSNR over all voxels (inf: lossless);
--   decode_gb_s  the C decoder, one thread, output GB/s (st:bench_decode, median of 3);
--   unpack_gb_s  undoing stage 2, all cores, payload GB/s (0 without stage 2);
--   fps          median playback frames per second of the pipelined player along the orbit
--                (--width^2 pixels, --device);
--   pareto       1 if no other variant of the dataset has fewer or equal bits per voxel and
--                an equal or higher image PSNR, one of them strictly (the front a user picks
--                from: the best quality for a budget of bits).
-- Each dataset keeps its first --timesteps timesteps (default 3). --quick: fewer variants
-- (raw, raw_zstd, raw_auto, S1T3, S4T3, S4T3_lz4, S4T3_zstd, S4T3_auto, zfp at 1 and 4 bpv,
-- hvq, hvqc), 4 frames of
-- 96^2 and a 128^3 series, for a run of a few minutes on 2 cores.
-- Writes DIR/frontier.csv (columns above, one row per dataset and variant) and
-- DIR/frontier.png (gnuplot, one panel per dataset: image PSNR against bits per voxel, each
-- point labelled with its variant, decode GB/s and fps, the pareto front joined by a line and
-- circled; lossless points at the top of their panel). A dataset that fails is reported on stderr and
-- in DIR/failed.txt, the others are still measured, and the exit status is 1.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/bench/?.lua;" .. package.path
local common = require "common"

local datasets, opt = common.parse_args(arg, {out = "out/frontier", device = "auto"})
local quick = opt.quick ~= nil
local frames = tonumber(opt.frames or (quick and "4" or "6"))
local width = tonumber(opt.width or (quick and "96" or "128"))
local timesteps = tonumber(opt.timesteps or "3")
local series_size = tonumber(opt["series-size"] or (quick and "128" or "256"))
local series_timesteps = tonumber(opt["series-timesteps"] or "3")
assert(frames and frames >= 1 and width and width >= 8 and timesteps and timesteps >= 1,
       "--frames, --width (>= 8) and --timesteps must be positive numbers")
os.execute(('mkdir -p "%s"'):format(opt.out))
local script_dir = arg[0]:match("^(.*)/[^/]*$") or "."

-- ---- datasets -----------------------------------------------------------------------------
local function shell_lines(cmd)
  local p = io.popen(cmd)
  local out = {}
  for line in p:lines() do out[#out + 1] = line end
  p:close()
  return out
end

-- Every volume file and every directory of timesteps one level below the data directory's
-- subdirectories (ct/engine.nrrd, series/viscousfingers, ...).
local function shared_datasets()
  local found = {}
  for _, path in ipairs(shell_lines(('ls -d "%s"/*/* 2>/dev/null'):format(common.shared_data()))) do
    local is_dir = os.execute(('test -d "%s"'):format(path))
    if is_dir or path:match("%.nrrd$") or path:match("%.nii%.gz$") or path:match("%.nii$") or
       path:match("%.nhdr$") or path:match("%.mha$") or path:match("%.vti$") then
      found[#found + 1] = path
    end
  end
  return found
end

if #datasets == 0 then datasets = shared_datasets() end

-- The generated series: {spec=, load=function} or nil.
local function series_dataset()
  if opt.series == "none" then return nil end
  local S = series_size
  local pattern = opt.series
  if not pattern then
    local dir = opt.out .. "/series"
    pattern = ("%s/vf%d_t%%03d.raw"):format(dir, S)
    if not common.exists(pattern:format(series_timesteps - 1)) then
      common.progress("generating a %d^3 x %d series", S, series_timesteps)
      local ok = os.execute(('/usr/bin/python3 "%s/bench/make_series.py" "%s" --timesteps %d --size %d ' ..
                             '--data "%s" >/dev/null'):format(script_dir, dir, series_timesteps, S,
                                                              common.shared_data()))
      if not ok then error("make_series.py failed (it needs python3-numpy and the viscous-fingers series)") end
    end
  end
  return {spec = pattern, name = ("vf%d_series"):format(S), load = function()
    return cdvr.load_series(pattern, {first = 0, count = series_timesteps, dims = {S, S, S}, type = "u8"})
  end}
end

-- ---- variants -----------------------------------------------------------------------------
local function codec_loaded(name)
  for _, c in ipairs(cdvr.codecs and cdvr.codecs() or {}) do
    if c.name == name then return true end
  end
  return false
end

local function variant_list()
  local list = {{name = "raw", codec = "raw"}, {name = "raw_zstd", codec = "raw", stage2 = "zstd"},
                {name = "raw_auto", codec = "raw", stage2 = "auto"}}
  local pvtc = quick and {{1, 3}, {4, 3}} or {{1, 3}, {4, 3}, {1, 2}, {4, 2}}
  for _, st in ipairs(pvtc) do
    list[#list + 1] = {name = ("S%dT%d"):format(st[1], st[2]), S = st[1], T = st[2]}
  end
  local staged = quick and {{4, "lz4"}, {4, "zstd"}, {4, "auto"}} or
                 {{4, "lzo"}, {4, "lz4"}, {4, "zstd"}, {4, "auto"}, {1, "lzo"}, {1, "lz4"},
                  {1, "zstd"}, {1, "auto"}}
  if not quick then table.insert(list, 3, {name = "raw_lz4", codec = "raw", stage2 = "lz4"}) end
  for _, s in ipairs(staged) do
    list[#list + 1] = {name = ("S%dT3_%s"):format(s[1], s[2]), S = s[1], T = 3, stage2 = s[2]}
  end
  if (opt.zfp or "") ~= "none" and codec_loaded("zfp") then
    for rate in (opt.zfp or (quick and "1,4" or "0.5,1,2,4")):gmatch("[^,]+") do
      local r = assert(tonumber(rate), "--zfp: comma-separated rates expected")
      list[#list + 1] = {name = "zfp" .. rate, codec = "zfp", rate = r}
    end
  end
  if codec_loaded("hvq") then list[#list + 1] = {name = "hvq", codec = "hvq"} end
  if codec_loaded("hvqc") then -- hvq's compact form; shared=1: one codebook set per variant
    list[#list + 1] = {name = "hvqc", codec = "hvqc"}
    if not quick then list[#list + 1] = {name = "hvqc_s", codec = "hvqc", shared = 1} end
  end
  return list
end
local variants = variant_list()

local function render_device()
  if opt.device ~= "auto" then return opt.device end
  return (cdvr.cl_info and cdvr.cl_info()) and "cl" or "cpu"
end
local device = render_device()

-- ---- measuring ----------------------------------------------------------------------------
-- Encodes one dataset with every variant and appends one row per variant to rows.
local function measure(vol, name, rows)
  if timesteps < vol:timesteps() then vol = vol:frame(1, timesteps) end
  local lo, hi = vol:range()
  local q = vol:quantize{lo = lo, hi = hi}
  local tmp = os.tmpname()
  common.progress("%s: encoding %d variants", name, #variants)
  local st = cdvr.encode(q, {variants = variants, stage2 = "none", path = tmp, progress = false})
  local info = st:info()
  local x0, x1, y0, y1, z0, z1 = st:decode(1):bounds()
  local c = {(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2}
  local path = cdvr.path.orbit{center = c, distance = 2.4 * math.max(x1 - x0, y1 - y0, z1 - z0),
                               up = {0, 0, 1}, elevation = 25, period = math.max(frames, 2), fov = 30}
  local tf = cdvr.tf("hot")
  local function render(t, variant, f)
    return cdvr.render(st:decode(t, variant), {tf = tf, camera = path:camera(f, width, width), device = device})
  end
  local refs = {}
  for f = 1, frames do refs[f] = render((f - 1) % info.timesteps + 1, "raw", f) end
  for vi, var in ipairs(info.variants) do
    common.progress("%s: %s (%d/%d)", name, var.name, vi, #info.variants)
    local p = cdvr.player{store = st, tf = tf, camera = path, variant = var.name, width = width,
                          height = width, device = device, loop = true}
    local r = p:run{frames = frames}
    p:close()
    local sum, n = 0, 0
    for f = 1, frames do
      local cmp = cdvr.compare(render((f - 1) % info.timesteps + 1, var.name, f), refs[f])
      if cmp.psnr ~= math.huge then sum, n = sum + cmp.psnr, n + 1 end
    end
    local staged = var.stage2 ~= "none"
    rows[#rows + 1] = {dataset = name, config = var.name, codec = var.codec,
                       stage2 = common.stage2_label(var),
                       bpv = 8 * var.bytes / info.raw_bytes,
                       image_psnr = n == 0 and math.huge or sum / n, volume_psnr = var.psnr,
                       decode_gb_s = st:bench_decode(var.name, 3) / 1e3,
                       unpack_gb_s = staged and st:bench_unpack(var.name, 3) / 1e3 or 0,
                       fps = r.fps, frame_ms = r.median.frame_ms}
  end
  st:close()
  os.remove(tmp)
end

-- pareto = 1 for the rows of each dataset that no other row of it dominates (bpv <= and
-- image_psnr >=, one strictly; inf PSNR is the highest).
local function mark_front(rows)
  for _, a in ipairs(rows) do
    a.pareto = 1
    for _, b in ipairs(rows) do
      if b ~= a and b.dataset == a.dataset and b.bpv <= a.bpv and b.image_psnr >= a.image_psnr and
         (b.bpv < a.bpv or b.image_psnr > a.image_psnr) then
        a.pareto = 0
        break
      end
    end
  end
end

local rows, names, failures, taken = {}, {}, {}, {}
local function unique(name)
  local n = 1
  while taken[name .. (n > 1 and ("#" .. n) or "")] do n = n + 1 end
  name = name .. (n > 1 and ("#" .. n) or "")
  taken[name] = true
  return name
end

local jobs = {}
for _, spec in ipairs(datasets) do
  jobs[#jobs + 1] = {spec = spec, name = common.dataset_name(spec), load = function()
    return common.load_dataset(spec)
  end}
end
local ok_series, series = pcall(series_dataset)
if not ok_series then
  failures[#failures + 1] = ("generated series: %s"):format(tostring(series))
  io.stderr:write(("frontier.lua: the generated series failed: %s\n"):format(tostring(series)))
elseif series then
  jobs[#jobs + 1] = series
end
for _, job in ipairs(jobs) do
  local name = unique(job.name)
  local ok, err = pcall(function() measure(job.load(), name, rows) end)
  if ok then
    names[#names + 1] = name
  else
    failures[#failures + 1] = ("%s: %s"):format(job.spec, tostring(err))
    common.progress_done()
    io.stderr:write(("frontier.lua: dataset %s failed: %s\n"):format(job.spec, tostring(err)))
  end
end
common.progress_done()
mark_front(rows)

-- ---- CSV ----------------------------------------------------------------------------------
local COLUMNS = "dataset,config,codec,stage2,bpv,image_psnr,volume_psnr,decode_gb_s,unpack_gb_s," ..
                "fps,frame_ms,pareto"
local fmt = common.csv_number
common.write_results(opt.out, "frontier.csv", COLUMNS, rows, function(r)
  return ("%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%d"):format(r.dataset, r.config, r.codec, r.stage2,
    fmt(r.bpv), fmt(r.image_psnr), fmt(r.volume_psnr), fmt(r.decode_gb_s), fmt(r.unpack_gb_s),
    fmt(r.fps), fmt(r.frame_ms), r.pareto)
end, failures, "frontier.lua")

-- ---- chart --------------------------------------------------------------------------------
-- One panel per dataset in one PNG (gnuplot multiplot). Per dataset two data blocks: every
-- point (labelled), then the front by bits per voxel. Lossless points (inf PSNR) sit at the
-- top of their panel, 6 dB above its best lossy point.
-- Label heights (data units) so that labels do not overwrite each other: variants of one
-- codec at equal PSNR (a PVTC variant and its stage-2 versions) stand at one height. Greedy, in
-- order of bits per voxel: a label takes the first of its point's height, one line above, one
-- below, two above, ... that keeps a line's distance from every label placed within
-- LABEL_OCTAVES of it along the (log 2) bits axis. A line is 1/24 of the panel's PSNR span.
local LABEL_OCTAVES = 1.4
local function place_labels(points, top)
  local low = top
  for _, r in ipairs(points) do
    if r.image_psnr ~= math.huge then low = math.min(low, r.image_psnr) end
  end
  local line = math.max(top - low, 6) / 24
  local order = {}
  for k in ipairs(points) do order[k] = k end
  table.sort(order, function(a, b) return points[a].bpv < points[b].bpv end)
  local placed, out = {}, {}
  for _, k in ipairs(order) do
    local r = points[k]
    local y = r.image_psnr == math.huge and top or r.image_psnr
    local x = math.log(math.max(r.bpv, 1e-9), 2)
    local chosen = y
    for step = 0, 16 do
      local dy = (step % 2 == 1 and 1 or -1) * math.ceil(step / 2) * line
      local free = true
      for _, p in ipairs(placed) do
        if math.abs(p.x - x) < LABEL_OCTAVES and math.abs(p.y - (y + dy)) < line then
          free = false
          break
        end
      end
      if free then
        chosen = y + dy
        break
      end
    end
    placed[#placed + 1] = {x = x, y = chosen}
    out[k] = chosen
  end
  return out
end

local COLOURS = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf"}
local dat = assert(io.open(opt.out .. "/frontier.dat", "w"))
local panels = {}
for i, name in ipairs(names) do
  local mine, front, maxfin = {}, {}, 0
  for _, r in ipairs(rows) do
    if r.dataset == name then
      mine[#mine + 1] = r
      if r.pareto == 1 then front[#front + 1] = r end
      if r.image_psnr ~= math.huge then maxfin = math.max(maxfin, r.image_psnr) end
    end
  end
  local top = maxfin + 6
  table.sort(front, function(a, b) return a.bpv < b.bpv end)
  if i > 1 then dat:write("\n\n") end
  local label_y = place_labels(mine, top)
  for k, r in ipairs(mine) do
    local y = r.image_psnr == math.huge and top or r.image_psnr
    dat:write(("%.5f %.4f \"%s %.2fGB/s %.0ffps%s\" %.4f\n"):format(r.bpv, y, r.config, r.decode_gb_s,
      r.fps, r.image_psnr == math.huge and " lossless" or "", label_y[k]))
  end
  dat:write("\n\n")
  for _, r in ipairs(front) do
    dat:write(("%.5f %.4f\n"):format(r.bpv, r.image_psnr == math.huge and top or r.image_psnr))
  end
  local colour = COLOURS[(i - 1) % #COLOURS + 1]
  local file = opt.out .. "/frontier.dat"
  local title = name:gsub('"', "")
  panels[#panels + 1] = table.concat({
    ('set title "%s"'):format(title),
    ('plot "%s" index %d using 1:2 with points pt 7 ps 0.9 lc rgb "%s" title "variant", \\'):format(
      file, 2 * (i - 1), colour),
    ('     "%s" index %d using 1:2 with linespoints pt 6 ps 2.0 lw 1.5 dt 2 lc rgb "%s" title "pareto front", \\'):format(
      file, 2 * i - 1, colour),
    ('     "%s" index %d using 1:4:3 with labels offset char 0,0.8 font ",7" tc rgb "#333333" notitle'):format(
      file, 2 * (i - 1)),
  }, "\n")
end
dat:close()
local cols = math.ceil(math.sqrt(#names))
local nrows = math.ceil(#names / cols)
local gp = assert(io.open(opt.out .. "/frontier.gp", "w"))
gp:write(([[
set terminal pngcairo size %d,%d font ",10" noenhanced
set output "%s/frontier.png"
set multiplot layout %d,%d title "cdvr frontier (labels: variant, decode GB/s per thread, fps at %dx%d on %s; circled: pareto front)"
set xlabel "bits per voxel (log scale)"
set ylabel "image PSNR (dB)"
set logscale x 2
set grid
set key bottom right font ",8"
set offsets graph 0.08, graph 0.15, 3, 3
%s
unset multiplot
]]):format(560 * cols, 420 * nrows + 40, opt.out, nrows, cols, width, width, device,
           table.concat(panels, "\n")))
gp:close()
local ok = os.execute(('gnuplot "%s/frontier.gp"'):format(opt.out))
if not ok then
  io.stderr:write("frontier.lua: gnuplot failed; frontier.csv is written\n")
  os.exit(1)
end
io.stderr:write(("frontier.lua: wrote %s/frontier.csv and %s/frontier.png\n"):format(opt.out, opt.out))
if #failures > 0 then
  io.stderr:write(("frontier.lua: %d dataset(s) failed (listed in %s)\n"):format(#failures, failed_path))
  os.exit(1)
end
