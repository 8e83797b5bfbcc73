-- scripts/bench/rate_control.lua [DATASET] [--frames N] [--read_mbps R] [--repeats K]
-- Rate control against the wall clock (the timed check that used to be
-- tests/lua/test_rate_control.lua; the test now injects stage times and checks decisions only).
-- A real series (default: viscous fingers timesteps 40-69) is stored as S1T3, S4T3 and raw and
-- played under an emulated disk (read_mbps, default 5 MB/s: raw 52 ms, S1T3 8.7 ms, S4T3 5.5 ms
-- per 64^3 timestep), with pacing at the target frame rate. For each policy and target:
--   achieved_fps   1000 / median interval_ms over the frames after the first 3 groups
--   ratio          achieved_fps / target (the old test asked 0.9 .. 1.1)
--   variant        the variant those frames used
--   fixed_fps      the same variant played with policy "fixed" in the same run (the baseline:
--                  what that variant sustains on this machine now), and achieved / fixed
-- Medians over --repeats runs (default 3). CSV on stdout; progress on stderr when it is a terminal.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"

local args, opt = common.parse_args(arg, {frames = 30, read_mbps = 5, repeats = 3})
local frames, read_mbps, repeats = tonumber(opt.frames), tonumber(opt.read_mbps), tonumber(opt.repeats)
local dataset = args[1] or (common.shared_data() .. "/series/viscousfingers/vf_t%03d.nrrd")
local vol
if dataset:find("%%") then
  vol = assert(cdvr.load_series(dataset, {first = 40, count = 30}))
else
  vol = common.load_dataset(dataset)
end
local lo, hi = vol:range()
local q = vol:quantize{lo = lo, hi = hi}
local path = os.tmpname()
common.progress("encoding ...")
local st = assert(cdvr.encode(q, {variants = {{S = 1, T = 3}, {S = 4, T = 3}, {codec = "raw"}},
                                  stage2 = "none", path = path, progress = false}))
common.progress_done()
local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(q, {azimuth = 30, elevation = 20, width = 24, height = 24})

-- fps after the first 3 groups, and the variant most of those frames used
local function play(policy, target, variant)
  local p = cdvr.player{store = st, tf = tf, camera = cam, device = "cpu", threads = 1, pipeline = false,
                        read_mbps = read_mbps, policy = policy, target_fps = target, variant = variant}
  local r = p:run{frames = frames}
  p:close()
  local intervals, count = {}, {}
  for i, row in ipairs(r.frames) do
    assert(not row.error, row.error)
    if i > 9 then
      intervals[#intervals + 1] = row.interval_ms
      count[row.variant] = (count[row.variant] or 0) + 1
    end
  end
  local used, most = nil, -1
  for name, n in pairs(count) do
    if n > most then used, most = name, n end
  end
  return 1000 / common.median(intervals), used
end

print("policy,target_fps,variant,achieved_fps,ratio_to_target,fixed_fps,ratio_to_fixed")
for _, case in ipairs{{"closed_loop", 50}, {"closed_loop", 125}, {"open_loop", 50}, {"open_loop", 125}} do
  local policy, target = case[1], case[2]
  local achieved, fixed, used = {}, {}, nil
  for k = 1, repeats do
    common.progress("%s %g fps, run %d/%d", policy, target, k, repeats)
    local fps
    fps, used = play(policy, target)
    achieved[k] = fps
    fixed[k] = play("fixed", target, used)
  end
  common.progress_done()
  local a, f = common.median(achieved), common.median(fixed)
  print(("%s,%g,%s,%.2f,%.3f,%.2f,%.3f"):format(policy, target, used, a, a / target, f, a / f))
end
st:close()
os.remove(path)
