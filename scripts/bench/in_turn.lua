-- scripts/bench/in_turn.lua [DATASET_A [DATASET_B]] [--count 15] [--rounds 3] [--size 512]
--                           [--step 1.0] [--device cl]
-- Two volumes rendered in turn (an original beside its decoded or edited copy, two datasets
-- side by side) against each rendered alone, in one process: per round, A alone --count
-- times, B alone, then A and B alternately --count times each; the first round is not
-- counted (kernel builds, first uploads). The render context keeps a device stream per volume
-- (cdvr/method.h, CDVR_RENDER_CTX_STREAMS), so in turn should cost what alone costs; with one
-- stream every render in turn uploaded the frame and rebuilt its copies. Default: Colin27 and
-- a copy of it with its top value clipped (same dims, other voxels) from ../shared/data, else
-- share/data's neghip and its copy; one dataset given: it and its copy; two: those two.
-- CSV on stdout: volume, case (alone, in_turn), median ms per render over the counted rounds,
-- in_turn_over_alone, the 1-minute load average at the start. Compare two builds with
-- scripts/bench/compare_binaries.sh OLD NEW 3 scripts/bench/in_turn.lua.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"
local specs, opt = common.parse_args(arg, {count = "15", rounds = "3", size = "512", step = "1.0",
                                           device = "cl"})
if #specs == 0 then
  local shared = common.shared_data()
  local colin = shared and shared .. "/mri/colin27_t1_301x370x316_u8.nii.gz"
  if colin and common.exists(colin) then
    specs[1] = colin
  else
    specs[1] = (arg[0]:match("^(.*)/scripts/bench/[^/]*$") or ".") ..
               "/share/data/neghip_66x66x66_u8.nrrd"
  end
end
local a, name_a = common.load_dataset(specs[1])
local b, name_b
if specs[2] then
  b, name_b = common.load_dataset(specs[2])
else -- the same dims, other voxels: the top value clipped one code lower
  b, name_b = a:quantize{lo = 0, hi = 254}, name_a .. "_copy"
end
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {35, 0, 0, 0, 0}, {60, 0.8, 0.45, 0.35, 0.03},
                   {90, 1.0, 0.85, 0.7, 0.3}, {130, 1, 1, 1, 0.8}, unit = 1}
local size, count, rounds = tonumber(opt.size), tonumber(opt.count), tonumber(opt.rounds)
local function options(v)
  return {tf = tf, camera = common.view(v, 45, 25, size, size), step = tonumber(opt.step),
          device = opt.device}
end
local vols = {{v = a, name = name_a, o = options(a)}, {v = b, name = name_b, o = options(b)}}
local function timed(vol)
  local t0 = cdvr.clock()
  cdvr.render(vol.v, vol.o)
  return (cdvr.clock() - t0) * 1e3
end
local load = io.open("/proc/loadavg")
local loadavg = load and tonumber(load:read("l"):match("^(%S+)")) or 0 / 0
if load then load:close() end
local ms = {{alone = {}, in_turn = {}}, {alone = {}, in_turn = {}}}
for r = 0, rounds do
  common.progress("round %d/%d", r, rounds)
  for i, vol in ipairs(vols) do
    for _ = 1, count do
      local t = timed(vol)
      if r > 0 then table.insert(ms[i].alone, t) end
    end
  end
  for _ = 1, count do
    for i, vol in ipairs(vols) do
      local t = timed(vol)
      if r > 0 then table.insert(ms[i].in_turn, t) end
    end
  end
end
common.progress_done()
print("volume,case,median_ms,in_turn_over_alone,loadavg")
for i, vol in ipairs(vols) do
  local alone, in_turn = common.median(ms[i].alone), common.median(ms[i].in_turn)
  print(("%s,alone,%.2f,,%.2f"):format(vol.name, alone, loadavg))
  print(("%s,in_turn,%.2f,%.3f,%.2f"):format(vol.name, in_turn, in_turn / alone, loadavg))
end
