-- scripts/bench/float_encode.lua PATTERN COUNT [quantize|direct] [--dims 256] [--variant S4T3]
-- Peak memory of encoding a float series (raw f32 files of D^3 voxels, as
-- scripts/bench/make_series.py --type f32 writes them), as one CSV line on stdout:
--   mode,timesteps,seconds,psnr,peak_rss_mb
-- quantize: s:quantize{lo, hi} over s:range(), then cdvr.encode; direct: cdvr.encode of the
-- float series itself (quantised over its window on the fly). Written so that an older cdvr
-- runs the quantize mode too: compare the peak of the old and the new executable.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"
local args, opt = common.parse_args(arg, {dims = "256", variant = "S4T3"})
local pattern, count, mode = args[1], tonumber(args[2]), args[3] or "quantize"
assert(pattern and count, "usage: float_encode.lua PATTERN COUNT [quantize|direct]")
local D = tonumber(opt.dims)
local S, T = opt.variant:match("^S(%d)T(%d)$")
assert(S, "--variant SxTy expected")

local function vmhwm_mb()
  local f = io.open("/proc/self/status")
  local txt = f and f:read("a") or ""
  if f then f:close() end
  return (tonumber(txt:match("VmHWM:%s*(%d+)")) or 0) / 1024
end

local t0 = cdvr.clock()
local s = assert(cdvr.load_series(pattern, {first = 0, count = count, dims = {D, D, D}, type = "f32"}))
local src = s
if mode == "quantize" then
  local lo, hi = s:range()
  src = s:quantize{lo = lo, hi = hi}
elseif mode ~= "direct" then
  error("mode " .. mode .. ": quantize or direct expected")
end
local path = os.tmpname()
local st = assert(cdvr.encode(src, {path = path, variants = {{S = tonumber(S), T = tonumber(T)}}}))
local v = st:info().variants[1]
local seconds = cdvr.clock() - t0
st:close()
os.remove(path)
print("mode,timesteps,seconds,psnr,peak_rss_mb")
print(("%s,%d,%.1f,%.3f,%.1f"):format(mode, count, seconds, v.psnr, vmhwm_mb()))
