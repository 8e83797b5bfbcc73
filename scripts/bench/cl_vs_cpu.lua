-- scripts/bench/cl_vs_cpu.lua - ray casting on the OpenCL device against the CPU reference,
-- measured in the same run: medians of N renders each, the ratio, and the image PSNR.
-- usage: cdvr scripts/bench/cl_vs_cpu.lua [volume.nrrd] [size] [repeats]
local data = os.getenv("CDVR_SHARED_DATA") or "../shared/data"
local path = arg[1] or (data .. "/ct/engine_256x256x128_u8.nrrd")
local size = tonumber(arg[2]) or 512
local repeats = tonumber(arg[3]) or 5
local v = assert(cdvr.load(path))
local info, msg = cdvr.cl_info()
if not info then error("no OpenCL device: " .. tostring(msg)) end
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {70, 0, 0, 0, 0}, {110, .9, .6, .3, .05}, {200, 1, 1, .9, .4},
                   {255, 1, 1, 1, .9}}
local cam = cdvr.orbit_camera(v, {azimuth = 45, elevation = 30, width = size, height = size})

local function median(list)
  table.sort(list)
  return list[(#list + 1) // 2]
end

local function bench(opts)
  local times, img, stats = {}, nil, nil
  for i = 1, repeats do
    local t0 = cdvr.clock()
    img, stats = cdvr.render(v, opts)
    times[i] = (cdvr.clock() - t0) * 1e3
  end
  return median(times), img, stats
end

cdvr.render(v, {tf = tf, camera = cam, device = "cl"}) -- warm-up: kernel specialisation
local cpu_ms, cpu_img, cpu_stats = bench{tf = tf, camera = cam}
local cl_ms, cl_img, cl_stats = bench{tf = tf, camera = cam, device = "cl"}
local noskip_ms = bench{tf = tf, camera = cam, device = "cl", skip = false}
print(("device %s (%s); program %s in %.3f s"):format(info.device, info.type,
  info.from_cache and "from cache" or "compiled", info.build_seconds))
print(("%dx%d, median of %d: cpu %.1f ms, cl %.1f ms (skip off %.1f ms), cpu/cl %.2f, skip gain %.2f")
  :format(size, size, repeats, cpu_ms, cl_ms, noskip_ms, cpu_ms / cl_ms, noskip_ms / cl_ms))
print(("samples cpu %d, cl %d; bricks visible %.2f; image psnr cl vs cpu %.1f dB"):format(
  cpu_stats.samples, cl_stats.samples, cl_stats.bricks_visible, cdvr.compare(cl_img, cpu_img).psnr))
