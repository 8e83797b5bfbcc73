-- scripts/bench/decode_speed.lua [DATASET]: C decode and LZO unpack speed of every PVTC variant
-- (and raw) of one dataset, single thread, as CSV on stdout:
--   variant,stage2,decode_mbps,unpack_mbps,memcpy_mbps
-- decode_mbps: output bytes per second of st:bench_decode (median of 7 passes over all
-- chunks); unpack_mbps: LZO unpack of the payload (lzo rows only); memcpy_mbps: the same byte
-- count copied in pieces of 3 frames, right after (the machine's baseline). Written so that an
-- older cdvr runs it too: scripts/bench/compare_binaries.sh runs it with two binaries in
-- alternation and reports the ratio. Default dataset: the viscous fingers series.
package.path = (arg[0]:match("^(.*)/[^/]*$") or ".") .. "/?.lua;" .. package.path
local common = require "common"
local spec = arg[1] or (common.shared_data() .. "/series/viscousfingers")
local vol = common.load_dataset(spec)
if vol:type() ~= "u8" then
  local lo, hi = vol:range()
  vol = vol:quantize{lo = lo, hi = hi}
end
local tmp = os.tmpname()
local variants = {{codec = "raw"}}
for _, pack in ipairs{"time", "space"} do
  for _, st in ipairs{{1, 2}, {1, 3}, {4, 2}, {4, 3}} do
    variants[#variants + 1] = {S = st[1], T = st[2], pack = pack, encoder = "bbox"}
  end
end
print("variant,stage2,decode_mbps,unpack_mbps,memcpy_mbps")
for _, v in ipairs(variants) do
  for _, stage2 in ipairs{"none", "lzo"} do
    local opts = {path = tmp, progress = false, stage2 = stage2, lzo_min_saving = 0}
    for k, x in pairs(v) do opts[k] = x end
    local st = assert(cdvr.encode(vol, opts))
    local info = st:info()
    local decode = st:bench_decode(1, 7)
    local unpack = stage2 == "lzo" and st:bench_unpack(1, 7) or 0
    local frame = info.dims[1] * info.dims[2] * info.dims[3]
    local memcpy = cdvr.bench_memcpy(info.raw_bytes, 7, math.min(3 * frame, info.raw_bytes))
    print(("%s,%s,%.1f,%.1f,%.1f"):format(info.variants[1].name, stage2, decode, unpack, memcpy))
    st:close()
  end
end
os.remove(tmp)
