-- scripts/bench/playback.lua [DATASET] [--frames N] [--width W] [--device cl|cpu]
-- Playback frame rate of a real time series at 512x512 for raw chunks and each PVTC variant,
-- with and without LZO, serial and pipelined, warm and cold page cache, in one run; prints the
-- per-stage table (seed 000 Table 4: b1 read, b1' unzip, b2 upload, b3 decode, b4 setup,
-- b5 render; medians over frames) as CSV, each configuration's fps ratio to raw in the same
-- mode, and the two target checks:
--   pipelined frame time <= 1.25 x the slowest stage's median;
--   with read_mbps set so that reading a raw timestep takes 4x the render time, S4T3 >= 3x raw.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"

local args, opt = common.parse_args(arg, {frames = 30, width = 512, device = "auto"})
local dataset = args[1] or (common.shared_data() .. "/series/viscousfingers")
local frames, width = tonumber(opt.frames), tonumber(opt.width)

local vol, name = common.load_dataset(dataset)
local lo, hi = vol:range()
local q = vol:quantize{lo = lo, hi = hi}
local tmp = os.tmpname()
local specs = {}
for _, s2 in ipairs{"none", "lzo"} do
  specs[#specs + 1] = {codec = "raw", stage2 = s2, name = "raw" .. (s2 == "lzo" and "+lzo" or "")}
  for _, p in ipairs{{1, 3}, {4, 3}, {1, 2}, {4, 2}} do
    specs[#specs + 1] = {S = p[1], T = p[2], stage2 = s2,
                         name = ("S%dT%d"):format(p[1], p[2]) .. (s2 == "lzo" and "+lzo" or "")}
  end
end
common.progress("encoding %s ...", name)
local st = assert(cdvr.encode(q, {variants = specs, path = tmp, progress = false}))
common.progress_done()
local info = st:info()
local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(q, {azimuth = 30, elevation = 25, width = width, height = width})

local function play(variant, pipelined, cold, read_mbps)
  local p = cdvr.player{store = st, tf = tf, camera = cam, variant = variant, pipeline = pipelined,
                        cold = cold, read_mbps = read_mbps, device = opt.device, loop = true}
  local r = p:run{frames = frames}
  p:close()
  return r
end

print("dataset,variant,stage2,mode,cache,bytes_per_t,read_ms,unzip_ms,upload_ms,decode_ms,setup_ms,render_ms,serial_ms,frame_ms,fps,ratio_to_raw,slowest_stage_ms,frame_over_slowest")
local fps_raw = {}
local worst_pipe_ratio = 0
for _, cache in ipairs{"warm", "cold"} do
  for _, mode in ipairs{"serial", "pipelined"} do
    for _, var in ipairs(info.variants) do
      common.progress("%s %s %s", var.name, mode, cache)
      local r = play(var.name, mode == "pipelined", cache == "cold")
      local m = r.median
      local slowest = math.max(m.read_ms, m.unzip_ms, m.upload_ms + m.decode_ms + m.setup_ms + m.render_ms)
      local key = mode .. cache .. var.stage2
      if var.codec == "raw" then fps_raw[key] = r.fps end
      local ratio = fps_raw[key] and r.fps / fps_raw[key] or 0 / 0
      if mode == "pipelined" then worst_pipe_ratio = math.max(worst_pipe_ratio, m.frame_ms / slowest) end
      print(("%s,%s,%s,%s,%s,%.0f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.2f,%.3f,%.3f,%.3f"):format(
        name, var.name, var.stage2, mode, cache, var.bytes / info.timesteps, m.read_ms, m.unzip_ms,
        m.upload_ms, m.decode_ms, m.setup_ms, m.render_ms, m.serial_ms, m.frame_ms, r.fps, ratio,
        slowest, m.frame_ms / slowest))
    end
  end
end
common.progress_done()

-- Emulated slow disk: raw read time = 4 x render time.
local probe = play("raw", true, false)
local raw_bytes = info.dims[1] * info.dims[2] * info.dims[3]
local read_mbps = raw_bytes / (4 * probe.median.render_ms * 1e3)
local slow_raw = play("raw", true, false, read_mbps)
local slow_s4t3 = play("S4T3", true, false, read_mbps)
print()
print("check,value,target,holds")
print(("pipelined_frame_over_slowest_stage_max,%.3f,<=1.25,%s"):format(worst_pipe_ratio, tostring(worst_pipe_ratio <= 1.25)))
print(("slow_disk_read_mbps,%.2f,,"):format(read_mbps))
print(("slow_disk_fps_raw,%.2f,,"):format(slow_raw.fps))
print(("slow_disk_fps_S4T3,%.2f,,"):format(slow_s4t3.fps))
local speedup = slow_s4t3.fps / slow_raw.fps
print(("slow_disk_S4T3_over_raw,%.2f,>=3,%s"):format(speedup, tostring(speedup >= 3)))
st:close()
os.remove(tmp)
