-- scripts/bench/scale.lua --series PATTERN --timesteps N[,N2..] --dims D [options]
-- Out-of-core scale of encode and playback, measured for one or two cdvr executables in one
-- run (the "old" one, when given, is the baseline; every measurement runs in its own child
-- process so peak RSS is that of the measurement alone):
--   encode:   for each series length and variant: seconds for load + encode (the lazy series
--             reads while it encodes; an eager one reads first), MB/s of u8 input, peak RSS
--             (VmHWM), PSNR and stored bytes;
--   playback: for each series length, variant and image size: fps, per-stage medians (b1 read,
--             b1' unzip, b2 upload, b3 decode, b4 setup, b5 render, frame), setup's share of
--             the frame, peak RSS; the first run of each player warms it up (kernel build,
--             decode-path measurement) and is not counted.
-- Then, per new/old pair, the ratios the issue's targets name. CSV on stdout, progress on
-- stderr when it is a terminal. The series is raw u8 files of D^3 voxels numbered from 0, as
-- scripts/bench/make_series.py writes them (PATTERN like /tmp/vf256/vf256_t%03d.raw); each
-- length N takes its first N files, or --series-for-N gives another pattern per length.
--
-- Options: --old EXE (baseline executable), --new EXE (default: the cdvr running this script),
--   --variants raw,S4T3,S1T3 (names: raw, SxTy or zfpR, zfp at rate R: the zfp plugin beside
--   each executable),
--   --stage2 none|lzo|lz4|zstd|auto (the new executable's stores only; without it each
--   executable keeps its default: auto since 2026-12-06, lzo before),
--   --stage2-read-mbps M (the new executable's stores: auto's modelled read rate; by default
--   its store's filesystem's, from the page cache where the series fits in half the memory,
--   else from the disk, store.h),
--   --rounds R (playback: R rounds alternating old, new, old, new, ...; the ratio is that of
--   the medians; each row has the 1-minute load average before it ran),
--   --encoder lsq|bbox, --sizes 512,64, --frames 30, --device cl|cpu, --threads 0,
--   --out DIR (stores; default a fresh directory under /tmp, removed at the end unless --keep),
--   --skip encode|playback, --repeats 1 (playback repeats; medians of fps and stages),
--   --range-brick 4|8|16 (the new executable's range tables; default its encoder's),
--   --empty-skip on|off (empty-space skipping of the players, default on),
--   --read-mbps M (both players read at most M MB/s, player.h read_mbps: playback from a
--   disk of that rate, e.g. the one --stage2-read-mbps models, rather than the page cache),
--   --cold (both players drop each chunk from the page cache before reading it, player.h
--   cold: playback from the disk itself, the out-of-core case).
-- Playback rows carry grid_ms (the skip grids made from the range tables; the old executable
-- may count them in unzip_ms) and samples (median samples the ray caster took per frame, 0
-- when the executable does not report them: with --empty-skip off, every sample),
-- unzip_cpu_ms (b1' in CPU time on all its threads, per frame; nan from an executable that
-- does not report it: unzip_ms, a worker's wall time, also counts its waits for the render's
-- cores) and unzip_cpu_share (that CPU time over the machine's, nproc cores, in a frame's
-- interval 1000 / fps: the share of the machine stage 2 takes).
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"

local _, opt = common.parse_args(arg, {timesteps = "60", dims = "256", variants = "raw,S4T3,S1T3",
                                       encoder = "lsq", sizes = "512,64", frames = "30",
                                       device = "cl", threads = "0", repeats = "1"})
assert(opt.series, "--series PATTERN is required (see scripts/bench/make_series.py)")
local new_exe = opt.new or arg[-1]
local exes = {{name = "new", path = new_exe}}
if opt.old then table.insert(exes, 1, {name = "old", path = opt.old}) end

local function split(s, conv)
  local out = {}
  for item in s:gmatch("[^,]+") do out[#out + 1] = conv and conv(item) or item end
  return out
end
local lengths, sizes, variants = split(opt.timesteps, tonumber), split(opt.sizes, tonumber),
                                 split(opt.variants)
local D, frames, repeats = tonumber(opt.dims), tonumber(opt.frames), tonumber(opt.repeats)
local rounds = tonumber(opt.rounds or "1")
local outdir = opt.out or os.tmpname() .. "_scale"
os.execute(("mkdir -p '%s'"):format(outdir))

local function range_opts(exe)
  if exe.name ~= "new" or not opt["range-brick"] then return "" end
  return ", range_brick=" .. tonumber(opt["range-brick"])
end

local function stage2_opts(exe)
  if exe.name ~= "new" then return "" end
  return (opt.stage2 and (', stage2=%q'):format(opt.stage2) or "") ..
         (opt["stage2-read-mbps"] and (", stage2_read_mbps=" .. opt["stage2-read-mbps"]) or "")
end

local function variant_spec(name, exe)
  if name == "raw" then return ('{codec="raw", name="raw"%s}'):format(stage2_opts(exe)) end
  local rate = name:match("^zfp([%d.]+)$")
  if rate then return ('{codec="zfp", rate=%s, name=%q%s}'):format(rate, name, stage2_opts(exe)) end
  local S, T = name:match("^S(%d)T(%d)$")
  assert(S, "variant " .. name .. ": raw or SxTy expected")
  return ('{S=%s, T=%s, encoder=%q, name=%q%s}'):format(S, T, opt.encoder, name, stage2_opts(exe))
end

-- Runs lua code in a child process of exe; returns its last stdout line split at commas.
local function child(exe, code)
  local path = outdir .. "/child.lua"
  local f = assert(io.open(path, "w"))
  f:write([[
local function vmhwm_mb()
  local st = io.open("/proc/self/status")
  local txt = st and st:read("a") or ""
  if st then st:close() end
  return (tonumber(txt:match("VmHWM:%s*(%d+)")) or 0) / 1024
end
]] .. code)
  f:close()
  local p = assert(io.popen(("'%s' '%s' 2>&1"):format(exe, path)))
  local out = p:read("a")
  p:close()
  local last = out:match("([^\n]*)\n?$")
  if not last or not last:match("^OK,") then
    return nil, out
  end
  return split(last:sub(4), function(x)
    return tonumber(x) or (x == "inf" and math.huge) or (x == "-nan" or x == "nan") and 0 / 0 or x
  end)
end

local function series_pattern(n)
  return opt["series-for-" .. n] or opt.series
end

-- ---- encode ------------------------------------------------------------------------------
local stores = {} -- stores[exe][n][variant] = path
print("section,exe,timesteps,variant,seconds,mb_per_s,peak_rss_mb,psnr,stored_bytes,range_table_bytes")
for _, n in ipairs(lengths) do
  for _, var in ipairs(variants) do
    for _, exe in ipairs(exes) do
      stores[exe.name] = stores[exe.name] or {}
      stores[exe.name][n] = stores[exe.name][n] or {}
      local path = ("%s/%s_%d_%s.cdv"):format(outdir, exe.name, n, var)
      stores[exe.name][n][var] = path
      if opt.skip ~= "encode" then
        common.progress("encode %s %d timesteps %s ...", exe.name, n, var)
        local threads = exe.name == "new" and (", threads=" .. opt.threads) or ""
        local r, msg = child(exe.path, ([[
local t0 = cdvr.clock()
local s = assert(cdvr.load_series(%q, {first=0, count=%d, dims={%d,%d,%d}, type="u8"}))
local st = assert(cdvr.encode(s, {path=%q, variants={%s}, progress=false%s%s}))
local dt = cdvr.clock() - t0
local v = st:info().variants[1]
print(("OK,%%.3f,%%.4f,%%.0f,%%.1f,%%.0f"):format(dt, v.psnr, v.bytes, vmhwm_mb(), v.ranges_bytes or 0))
]]):format(series_pattern(n), n, D, D, D, path, variant_spec(var, exe), threads, range_opts(exe)))
        if r then
          local mbs = n * D ^ 3 / 1e6 / r[1]
          print(("encode,%s,%d,%s,%.2f,%.2f,%.1f,%.3f,%.0f,%.0f"):format(exe.name, n, var, r[1],
                                                                         mbs, r[4], r[2], r[3], r[5]))
        else
          print(("encode,%s,%d,%s,nan,nan,nan,nan,nan  # %s"):format(exe.name, n, var,
                                                                  (msg or ""):gsub("\n", " | ")))
        end
        io.stdout:flush()
      end
    end
  end
end
common.progress_done()

-- ---- playback ----------------------------------------------------------------------------
local tf_points = "{0, 0,0,0, 0}, {40, 0.2,0.1,0.5, 0}, {90, 0.9,0.5,0.2, 0.05}, " ..
                  "{160, 1,0.9,0.6, 0.3}, {255, 1,1,1, 0.8}"
local fps_of = {} -- fps_of[exe][n][var][size], setup share too
print()
print("section,exe,timesteps,variant,size,fps,read_ms,unzip_ms,upload_ms,decode_ms,setup_ms," ..
      "render_ms,frame_ms,setup_share,peak_rss_mb,round,loadavg,grid_ms,samples,unzip_cpu_ms," ..
      "unzip_cpu_share")
local function online_cpus()
  local p = io.popen("nproc 2>/dev/null")
  local n = p and tonumber(p:read("l") or "") or nil
  if p then p:close() end
  return n or 1
end
local cpus = online_cpus()
local function loadavg()
  local f = io.open("/proc/loadavg")
  local l = f and f:read("l") or ""
  if f then f:close() end
  return tonumber(l:match("^(%S+)")) or 0 / 0
end
for _, n in ipairs(opt.skip == "playback" and {} or lengths) do
  for _, var in ipairs(variants) do
    for _, size in ipairs(sizes) do
      for round = 1, rounds do
      for _, exe in ipairs(exes) do
        common.progress("play %s %d timesteps %s %dx%d round %d ...", exe.name, n, var, size, size, round)
        local load = loadavg()
        local c = D / 2 - 0.5
        local r, msg = child(exe.path, ([[
local st = assert(cdvr.open(%q))
local tf = cdvr.tf{ %s }
local cam = cdvr.camera{eye={%g,%g,%g}, center={%g,%g,%g}, up={0,0,1}, fov=30,
                        width=%d, height=%d}
local p = cdvr.player{store=st, tf=tf, camera=cam, variant=%q, device=%q, pipeline=true%s}
p:run{frames=%d}
local keys = {"read_ms","unzip_ms","upload_ms","decode_ms","setup_ms","render_ms","frame_ms"}
local runs = {}
for i = 1, %d do runs[i] = p:run{frames=%d} end
local function med(get)
  local v = {}
  for i, r in ipairs(runs) do v[i] = get(r) end
  table.sort(v)
  return v[(#v + 1) // 2]
end
local out = {("%%.3f"):format(med(function(r) return r.fps end))}
for _, k in ipairs(keys) do out[#out + 1] = ("%%.3f"):format(med(function(r) return r.median[k] end)) end
local function frames_median(r, k)
  local v = {}
  for i, row in ipairs(r.frames) do v[i] = row[k] or 0 end
  table.sort(v)
  return v[(#v + 1) // 2] or 0
end
local extra = {("%%.3f"):format(med(function(r) return r.median.grid_ms or 0 end)),
               ("%%.0f"):format(med(function(r) return frames_median(r, "samples") end)),
               ("%%.3f"):format(med(function(r) return r.median.unzip_cpu_ms or 0 / 0 end))}
p:close()
print("OK," .. table.concat(out, ",") .. (",%%.1f"):format(vmhwm_mb()) .. "," .. table.concat(extra, ","))
]]):format(stores[exe.name][n][var], tf_points, c + 2.2 * D, c - 1.3 * D, c + 1.3 * D, c, c, c,
           size, size, var, opt.device,
           (opt["empty-skip"] == "off" and ", empty_skip=false" or "") ..
           (opt["read-mbps"] and (", read_mbps=" .. assert(tonumber(opt["read-mbps"]), "--read-mbps M")) or "") ..
           (opt.cold and ", cold=true" or ""),
           math.min(frames, 6), repeats, frames))
        if r then
          local share = r[7] > 0 and r[6] / r[8] or 0 / 0
          -- unzip's CPU per frame as a share of the machine's CPU in a frame's interval
          local unzip_share = r[12] / (cpus * 1000 / r[1])
          print(("playback,%s,%d,%s,%d,%.2f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.1f,%d,%.2f,%.3f,%.0f,%.3f,%.3f"):format(
            exe.name, n, var, size, r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], share, r[9],
            round, load, r[10], r[11], r[12], unzip_share))
          fps_of[exe.name] = fps_of[exe.name] or {}
          local key = n .. var .. size
          fps_of[exe.name][key] = fps_of[exe.name][key] or {}
          table.insert(fps_of[exe.name][key], r[1])
        else
          print(("playback,%s,%d,%s,%d,nan  # %s"):format(exe.name, n, var, size,
                                                        (msg or ""):gsub("\n", " | ")))
        end
        io.stdout:flush()
      end
      end
    end
  end
end
common.progress_done()

local function median(list)
  if not list or #list == 0 then return nil end
  local v = {table.unpack(list)}
  table.sort(v)
  return #v % 2 == 1 and v[(#v + 1) // 2] or (v[#v // 2] + v[#v // 2 + 1]) / 2
end

if opt.old and fps_of.new and fps_of.old then
  print()
  print("ratio,timesteps,variant,size,new_fps_over_old")
  for _, n in ipairs(lengths) do
    for _, var in ipairs(variants) do
      for _, size in ipairs(sizes) do
        local a, b = median(fps_of.new[n .. var .. size]), median(fps_of.old[n .. var .. size])
        if a and b then print(("fps,%d,%s,%d,%.2f"):format(n, var, size, a / b)) end
      end
    end
  end
end
if not opt.keep then os.execute(("rm -rf '%s'"):format(outdir)) end
