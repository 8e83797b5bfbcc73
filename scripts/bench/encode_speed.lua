-- scripts/bench/encode_speed.lua [DATASET] [--count N] [--variants S1T3,S4T3] [--encoders lsq,bbox]
-- Encode speed of PVTC variants on a series held in memory (loaded and, if not u8, quantised
-- over its range before the clock starts), as CSV on stdout:
--   variant,encoder,mbps,psnr,seconds
-- mbps: input megabytes (u8 voxels) per second of cdvr.encode with its default thread count;
-- psnr: the store's volume PSNR. DATASET: a printf pattern of raw u8 256^3 files as
-- scripts/bench/make_series.py writes them (first N files), a directory of NRRD files, or any
-- volume; default the viscous fingers series. Written so that an older cdvr runs it too:
-- scripts/bench/compare_binaries.sh OLD NEW ROUNDS scripts/bench/encode_speed.lua ... runs two
-- binaries in alternation and reports medians and ratios.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"

local args, opt = common.parse_args(arg, {count = "6", variants = "S1T3", encoders = "lsq",
                                          dims = "256"})
local spec = args[1] or (common.shared_data() .. "/series/viscousfingers")
local count, D = tonumber(opt.count), tonumber(opt.dims)
local vol
if spec:find("%%") and spec:match("%.raw$") then
  vol = assert(cdvr.load_series(spec, {first = 0, count = count, dims = {D, D, D}, type = "u8"}))
else
  vol = common.load_dataset(spec)
  count = math.min(count, vol:timesteps())
end
vol = vol:frame(1, count) -- in memory, for the old and the new cdvr alike
if vol:type() ~= "u8" then
  local lo, hi = vol:range()
  vol = vol:quantize{lo = lo, hi = hi}
end
local x, y, z = vol:dims()
local mb = x * y * z * count / 1e6
local tmp = os.tmpname()
print("variant,encoder,mbps,psnr,seconds")
for variant in opt.variants:gmatch("[^,]+") do
  local S, T = variant:match("^S(%d)T(%d)$")
  assert(S, "variant " .. variant .. ": SxTy expected")
  for encoder in opt.encoders:gmatch("[^,]+") do
    common.progress("%s %s ...", variant, encoder)
    local t0 = cdvr.clock()
    local st = assert(cdvr.encode(vol, {path = tmp, S = tonumber(S), T = tonumber(T),
                                        encoder = encoder, progress = false}))
    local dt = cdvr.clock() - t0
    print(("%s,%s,%.3f,%.4f,%.3f"):format(variant, encoder, mb / dt, st:info().variants[1].psnr, dt))
    st:close()
  end
end
common.progress_done()
os.remove(tmp)
