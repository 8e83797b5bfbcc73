-- fetch="auto" on a CPU OpenCL device measures once per device and remembers (issue 25 item 2,
-- cdvr/device.h cdvr_cl_fetch_path): the first render of an hvq size class times the whole
-- frame through the per-sample fetch and through the bulk decoder and remembers the faster; later
-- renders, in this process and in a new one, take the remembered path without measuring; every
-- path gives the same image. The cache directory is a fresh one, so nothing is remembered before.
if not cdvr.cl_info() then
  print("SKIP: no OpenCL device")
  os.exit(77)
end
if cdvr.cl_info().type ~= "cpu" then
  print("SKIP: only a CPU device measures (GPUs keep the per-sample fetch)")
  os.exit(77)
end
local bin = assert(os.getenv("CDVR_BINARY_DIR"), "CDVR_BINARY_DIR") .. "/cdvr"
local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q/cache"):format(tmp)))

local vol = cdvr.generate("sphere", {dims = {48, 40, 36}, timesteps = 2, radius = 0.6})
local st = assert(cdvr.encode(vol, {path = tmp .. "/h.cdv", progress = false,
                                    variants = {{codec = "hvq", name = "hvq"}}}))
st:close()

-- Renders timestep t in a child cdvr with the fresh cache directory and prints its stats.
local child = tmp .. "/child.lua"
local f = assert(io.open(child, "w"))
f:write([[
local st = assert(cdvr.open(arg[1]))
local vol = st:decode(1)
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {90, 1, .6, .2, .3}, {255, 1, 1, 1, .9}}
local cam = cdvr.orbit_camera(vol, {azimuth = 30, elevation = 20, width = 96, height = 80})
for pass = 1, 2 do
  local img, s = cdvr.render(st, {t = 1, tf = tf, camera = cam, device = "cl"})
  img:save(arg[2] .. "/img" .. arg[3] .. pass .. ".png")
  print(("pass %d path %s sample %s bulk %s"):format(pass, s.fetch_path,
        tostring(s.fetch_probe_sample_ms), tostring(s.fetch_probe_bulk_ms)))
end
local img = cdvr.render(st, {t = 1, tf = tf, camera = cam, device = "cl", fetch = "sample"})
img:save(arg[2] .. "/sample" .. arg[3] .. ".png")
]])
f:close()

local function run(tag)
  local cmd = ("CDVR_CACHE_DIR=%q CDVR_CL_FETCH= %q %q %q %q %s 2>&1"):format(
    tmp .. "/cache", bin, child, tmp .. "/h.cdv", tmp, tag)
  local p = assert(io.popen(cmd))
  local out = p:read("a")
  assert(p:close(), "child failed: " .. out)
  local passes = {}
  for pass, path, sample, bulk in out:gmatch("pass (%d) path (%S+) sample (%S+) bulk (%S+)") do
    passes[tonumber(pass)] = {path = path, sample = tonumber(sample), bulk = tonumber(bulk)}
  end
  assert(passes[1] and passes[2], "child printed its passes: " .. out)
  return passes
end

local first = run("a")
assert(first[1].sample and first[1].bulk, "the first render measures both paths")
assert(first[1].sample > 0 and first[1].bulk > 0, "both timed")
local faster = first[1].sample < first[1].bulk and "sample" or "bulk"
assert(not first[2].sample and not first[2].bulk, "the second render does not measure again")
assert(first[2].path == faster, ("the faster path is taken: %s, expected %s (%.2f / %.2f ms)"):
       format(first[2].path, faster, first[1].sample, first[1].bulk))
local again = run("b")
assert(not again[1].sample and again[1].path == faster,
       "a new process takes the remembered path without measuring: " .. again[1].path)

-- a damaged record (truncated, or another file's bytes) is not a choice: the next process
-- measures again
assert(os.execute(("for f in %q/cache/*.fetch; do printf 'sample -1 x' > \"$f\"; done"):format(tmp)))
local damaged = run("c")
assert(damaged[1].sample and damaged[1].bulk, "a damaged record is measured again")

local function bytes(path)
  local h = assert(io.open(path, "rb"))
  local s = h:read("a")
  h:close()
  return s
end
local ref = bytes(tmp .. "/samplea.png")
for _, name in ipairs{"imga1", "imga2", "imgb1", "imgb2", "sampleb"} do
  assert(bytes(tmp .. "/" .. name .. ".png") == ref, name .. " equals the per-sample image")
end
assert(os.execute(("rm -rf %q"):format(tmp)))
print(("fetch probe: sample %.2f ms, bulk %.2f ms, remembered %s"):format(
      first[1].sample, first[1].bulk, faster))
