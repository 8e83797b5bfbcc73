-- scripts/bench/cold_render.lua [DATASET ...] [--count 9] [--size 512] [--step 0.5] [--device cl]
-- The first render of a changed frame against rendering it again. After v:set changes a voxel
-- (the volume's revision: the render context uploads it again, cdvr/render.h), a render on
-- OpenCL uploads the frame, makes its value ranges per 4^3 brick, the TF's skip flags and
-- distances (cdvr/skip.h) and the entry distances before it casts; the render after it casts
-- alone. That first render is what each new timestep of a series costs outside the player (and
-- every render of a volume edited in between). Default datasets: the engine CT and Colin27 of
-- ../shared/data, else share/data's neghip. CSV on stdout: dataset, case (cold, again, setup =
-- cold - again), medians in ms over --count rounds, the first of which (kernel build) is not
-- counted. Compare two builds with scripts/bench/compare_binaries.sh OLD NEW 5
-- scripts/bench/cold_render.lua.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"
local specs, opt = common.parse_args(arg, {count = "9", size = "512", step = "0.5", device = "cl"})
if #specs == 0 then
  local shared = common.shared_data()
  for _, rel in ipairs{"/ct/engine_256x256x128_u8.nrrd", "/mri/colin27_t1_301x370x316_u8.nii.gz"} do
    if shared and common.exists(shared .. rel) then specs[#specs + 1] = shared .. rel end
  end
  if #specs == 0 then
    local here = arg[0]:match("^(.*)/scripts/bench/[^/]*$") or "."
    specs[1] = here .. "/share/data/neghip_66x66x66_u8.nrrd"
  end
end
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {35, 0, 0, 0, 0}, {60, 0.8, 0.45, 0.35, 0.03},
                   {90, 1.0, 0.85, 0.7, 0.3}, {130, 1, 1, 1, 0.8}, unit = 1}
local size, count = tonumber(opt.size), tonumber(opt.count)
print("dataset,case,median_ms")
for _, spec in ipairs(specs) do
  local v, name = common.load_dataset(spec)
  local o = {tf = tf, camera = common.view(v, 45, 25, size, size), step = tonumber(opt.step),
             device = opt.device}
  local keep = v:get(0, 0, 0)
  local cold, again, setup = {}, {}, {}
  for r = 0, count do
    common.progress("%s: round %d/%d", name, r, count)
    v:set(0, 0, 0, r % 2 == 0 and keep or (keep + 1) % 256) -- a new revision: uploaded again
    local t0 = cdvr.clock()
    cdvr.render(v, o)
    local t1 = cdvr.clock()
    cdvr.render(v, o)
    local t2 = cdvr.clock()
    if r > 0 then
      cold[r], again[r] = (t1 - t0) * 1e3, (t2 - t1) * 1e3
      setup[r] = cold[r] - again[r]
    end
  end
  v:set(0, 0, 0, keep)
  common.progress_done()
  print(("%s,cold,%.2f"):format(name, common.median(cold)))
  print(("%s,again,%.2f"):format(name, common.median(again)))
  print(("%s,setup,%.2f"):format(name, common.median(setup)))
end
