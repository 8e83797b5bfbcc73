-- scripts/bench/series_render.lua [DATASET] [--count N] [--repeats R] [--size S]
-- Per-frame cost of rendering timestep t of a float series against rendering that frame
-- alone (v:frame(t), a one-timestep volume, made beforehand), over the same timesteps, and
-- against the first frame alone: with one value window per series, computed once and cached
-- (volume.h), a series costs what its frames cost; before, every render of a series scanned
-- the whole series for its range. CSV on stdout: case, median ms over the repeats and the
-- ratio to the frame-alone baseline measured in the same run (CPU renderer).
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"
local specs, opt = common.parse_args(arg, {count = "30", repeats = "9", size = "128"})
local spec = specs[1] or (common.shared_data() .. "/series/viscousfingers/vf_t%03d.nrrd")
local series = cdvr.load_series(spec, {first = spec:find("%%") and 40 or nil, count = tonumber(opt.count)})
local tf = cdvr.tf("hot")
local cam = common.view(series, 30, 20, tonumber(opt.size), tonumber(opt.size))
local first = series:frame(1)
local function median_ms(f)
  local times = {}
  for r = 1, tonumber(opt.repeats) do
    local t0 = cdvr.clock()
    f(r)
    times[r] = (cdvr.clock() - t0) * 1000
  end
  return common.median(times)
end
cdvr.render(first, {tf = tf, camera = cam, device = "cpu"}) -- warm-up
local n = series:timesteps()
local frames = {}
for r = 1, tonumber(opt.repeats) do frames[r] = series:frame((r - 1) % n + 1) end
local t_first = median_ms(function() cdvr.render(first, {tf = tf, camera = cam, device = "cpu"}) end)
local base = median_ms(function(r) cdvr.render(frames[r], {tf = tf, camera = cam, device = "cpu"}) end)
local t_series = median_ms(function(r) cdvr.render(series, {tf = tf, camera = cam, t = (r - 1) % n + 1, device = "cpu"}) end)
print("case,timesteps,median_ms,ratio_to_frame_alone")
print(("frame_t_alone,1,%.2f,1.000"):format(base))
print(("series_timestep_t,%d,%.2f,%.3f"):format(n, t_series, t_series / base))
print(("first_frame_alone,1,%.2f,%.3f"):format(t_first, t_first / base))
