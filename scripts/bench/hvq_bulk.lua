-- scripts/bench/hvq_bulk.lua: a fetch-mode codec (hvq) on the cl device against the dense
-- render of the same voxels, interleaved in one process (issue 25 item 2).
--
--   cdvr scripts/bench/hvq_bulk.lua [--store PATH] [--size PIXELS] [--repeats N] [--data FILE]
--
-- Two stores of one volume (default the engine CT): PATH with variant "hvq" and PATH.raw with
-- variant "raw" of the hvq-decoded voxels, so both render exactly the same voxels; made when
-- absent (reused otherwise, so an old and a new binary time the same files).
-- Each repeat renders, in turn, cdvr.render(st, {variant="hvq", device="cl"}) (whatever path
-- the binary takes for a fetch-mode codec: the per-sample fetch, or on a CPU device since
-- issue 25 the bulk C decode then the dense render), the raw variant of the store (read,
-- upload, dense render) and the decoded volume already in memory (dense render only). The
-- order rotates every repeat; the first render of each is a warm-up (program build).
-- CSV on stdout: one row per case, median ms and the median of the per-repeat ratio to the
-- dense volume render; loadavg on stderr.
local common = dofile((arg and arg[0] and arg[0]:match("^(.*/)") or "./") .. "common.lua")

local _, opt = common.parse_args(arg, {store = "", size = "512", repeats = "7", data = ""})
local SIZE, REPEATS = assert(math.tointeger(tonumber(opt.size))), assert(math.tointeger(tonumber(opt.repeats)))
local data = opt.data ~= "" and opt.data or common.shared_data() .. "/ct/engine_256x256x128_u8.nrrd"
local path = opt.store ~= "" and opt.store or os.tmpname() .. ".cdv"

if not common.exists(path) then
  local vol = cdvr.load(data)
  local h = cdvr.encode(vol, {path = path, progress = false, variants = {{codec = "hvq", name = "hvq"}}})
  -- the raw store beside it (PATH .. ".raw") holds exactly the hvq-decoded voxels
  cdvr.encode(h:decode(1, "hvq"), {path = path .. ".raw", progress = false,
                                   variants = {{codec = "raw", name = "raw"}}})
end
local st = cdvr.open(path)
local raw = cdvr.open(path .. ".raw")
local dense = raw:decode(1, "raw")
assert(cdvr.compare(st:decode(1, "hvq"), dense).maxerr == 0, "the raw store holds the hvq voxels")

local tf = cdvr.tf("ct_bone")
local cam = cdvr.orbit_camera(dense, {azimuth = 30, elevation = 20, width = SIZE, height = SIZE})
local cases = {
  {"hvq_store", function() return cdvr.render(st, {variant = "hvq", tf = tf, camera = cam, device = "cl"}) end},
  {"raw_store", function() return cdvr.render(raw, {variant = "raw", tf = tf, camera = cam, device = "cl"}) end},
  {"dense_volume", function() return cdvr.render(dense, {tf = tf, camera = cam, device = "cl"}) end},
}
local ref = cases[3][2]()
for _, c in ipairs(cases) do
  local img = c[2]()
  c.maxerr = cdvr.compare(img, ref).maxerr
  c.ms = {}
end
io.stderr:write("loadavg before: " .. common.loadavg() .. "\n")
local ratios = {{}, {}, {}}
for r = 1, REPEATS do
  local times = {}
  for k = 0, #cases - 1 do
    local i = (r + k - 1) % #cases + 1
    local t0 = cdvr.clock()
    cases[i][2]()
    times[i] = (cdvr.clock() - t0) * 1000
    cases[i].ms[r] = times[i]
  end
  for i = 1, #cases do ratios[i][r] = times[i] / times[3] end
end
io.stderr:write("loadavg after: " .. common.loadavg() .. "\n")
print("case,median_ms,ratio_to_dense_volume,image_maxerr_vs_dense,size,repeats")
for i, c in ipairs(cases) do
  print(("%s,%.1f,%.2f,%g,%d,%d"):format(c[1], common.median(c.ms), common.median(ratios[i]), c.maxerr, SIZE, REPEATS))
end
