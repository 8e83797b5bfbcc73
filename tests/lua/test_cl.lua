-- tests/lua/test_cl.lua - the OpenCL device from Lua: cdvr.cl_info, cdvr.render{device="cl"}
-- against the CPU, skipping on/off, st:decode{device="cl"} bit-exact with the CPU decoder on
-- every PVTC variant (odd dims, timesteps not a multiple of T), and CDVR_CL_DEVICE=none.
local failed = 0
local function check(cond, msg)
  if not cond then
    failed = failed + 1
    io.stderr:write("check failed: ", msg, "\n")
  end
end

local info, msg = cdvr.cl_info()
if not info then
  print("skip: no OpenCL device: " .. tostring(msg))
  os.exit(77)
end
check(info.type == "cpu" or info.type == "gpu", "cl_info type " .. tostring(info.type))
check(type(info.device) == "string" and #info.device > 0, "cl_info device name")
check(type(info.platform) == "string" and #info.platform > 0, "cl_info platform")
print(("device %s (%s) on %s, program %s in %.3f s"):format(info.device, info.type, info.platform,
  info.from_cache and "from cache" or "compiled", info.build_seconds))

-- rendering: device against the CPU reference, skipping on and off
local v = cdvr.generate("ml", {dims = {37, 29, 41}})
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {110, 0, 0, 0, 0}, {170, .3, .8, 1, .3}, {255, 1, .4, .1, .8}}
for _, az in ipairs{0, 45, 150} do
  local cam = cdvr.camera{eye = {18 + 90 * math.sin(math.rad(az)), 14 - 90 * math.cos(math.rad(az)), 30},
                          center = {18, 14, 20}, up = {0, 0, 1}, fov = 35, width = 64, height = 48}
  local cpu = cdvr.render(v, {tf = tf, camera = cam})
  local cl, stats = cdvr.render(v, {tf = tf, camera = cam, device = "cl"})
  local noskip, stats_off = cdvr.render(v, {tf = tf, camera = cam, device = "cl", skip = false})
  local r = cdvr.compare(cl, cpu)
  print(("azimuth %3d: psnr %.1f dB, samples %d (skip off %d), bricks visible %.2f"):format(
    az, r.psnr, stats.samples, stats_off.samples, stats.bricks_visible))
  check(r.psnr >= 50, ("azimuth %d: cl vs cpu psnr %.2f"):format(az, r.psnr))
  check(cdvr.compare(cl, noskip).maxerr <= 0.5, "skipping changed pixels")
  check(stats.samples < stats_off.samples, "skipping did not skip")
  check(stats.device == info.device, "stats.device")
end
check(not pcall(cdvr.render, v, {tf = tf, device = "gpu-please"}), "bad device name accepted")

-- decoding: every variant, dims not multiples of the block, 5 timesteps (not a multiple of T)
local series = cdvr.generate("sphere", {dims = {13, 6, 11}, timesteps = 5})
local dir = os.getenv("CDVR_BINARY_DIR") or "."
local path = dir .. "/test_cl_lua.cdv"
local variants = {}
for _, S in ipairs{1, 4} do
  for _, T in ipairs{2, 3} do
    for _, pack in ipairs{"time", "space"} do
      variants[#variants + 1] = {S = S, T = T, pack = pack, stage2 = (S == 4) and "lzo" or "none"}
    end
  end
end
variants[#variants + 1] = {codec = "raw"}
local st = assert(cdvr.encode(series, {path = path, variants = variants}))
for vi, name in ipairs(st:variants()) do
  for t = 1, 5 do
    local a = st:decode(t, name, {device = "cl"})
    local b = st:decode(t, name)
    local r = cdvr.compare(a, b)
    check(r.maxerr == 0, ("variant %s t %d: cl decode differs (maxerr %g)"):format(name, t, r.maxerr))
  end
  check(vi <= #variants, "variant count")
end
st:close()
os.remove(path)

-- CDVR_CL_DEVICE=none: a clear error for device="cl", the CPU path keeps working
local exe = dir .. "/cdvr"
local script = [[
local i, m = cdvr.cl_info(); assert(i == nil and m:find("CDVR_CL_DEVICE=none"), tostring(m))
local v = cdvr.generate("sphere", {dims = {8, 8, 8}})
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {255, 1, 1, 1, 1}}
local cam = cdvr.camera{eye = {4, -30, 4}, center = {4, 4, 4}, up = {0, 0, 1}, width = 8, height = 8}
local ok, e = pcall(cdvr.render, v, {tf = tf, camera = cam, device = "cl"})
assert(not ok and e:find("CDVR_CL_DEVICE=none"), tostring(e))
assert(cdvr.render(v, {tf = tf, camera = cam}))
print("none: ok")
]]
local tmp = dir .. "/test_cl_none.lua"
local f = assert(io.open(tmp, "w"))
f:write(script)
f:close()
local ok = os.execute("CDVR_CL_DEVICE=none '" .. exe .. "' '" .. tmp .. "'")
check(ok == true, "CDVR_CL_DEVICE=none run failed")
os.remove(tmp)

print(failed == 0 and "all checks passed" or (failed .. " checks failed"))
os.exit(failed == 0 and 0 or 1)
