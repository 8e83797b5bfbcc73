-- tests/lua/test_store.lua: the whole Lua surface of the store (cdvr.encode, cdvr.open,
-- st:info/decode/chunk/variants/close, bench helpers), bad input and corruption.
local failures = 0
local function check(cond, msg)
  if not cond then
    failures = failures + 1
    io.stderr:write("FAIL: ", msg, "\n", debug.traceback(), "\n")
  end
end
local function raises(pattern, f, ...)
  local ok, err = pcall(f, ...)
  check(not ok, "expected an error matching " .. pattern)
  check(ok or tostring(err):find(pattern, 1, true), "error '" .. tostring(err) .. "' lacks '" .. pattern .. "'")
end

local dir = os.tmpname()
os.remove(dir)
assert(os.execute("mkdir -p " .. dir))
local function tmp(name) return dir .. "/" .. name end
local function exists(path) local f = io.open(path, "rb"); if f then f:close() end; return f ~= nil end

-- a moving sphere, odd dims, timesteps not a multiple of T
local src = cdvr.generate("sphere", {dims = {17, 9, 11}, timesteps = 5})
local path = tmp("a.cdv")
local st = cdvr.encode(src, {path = path, progress = false, variants = {
  {S = 4, T = 3}, {S = 1, T = 2, pack = "space", encoder = "bbox"}, {codec = "raw", stage2 = "none"},
  {S = 1, T = 3, name = "mine", stage2 = "none"}}})
check(tostring(st):find("cdvr.Store", 1, true), "tostring")
local info = st:info()
check(info.path == path and info.timesteps == 5, "info path/timesteps")
check(info.dims[1] == 17 and info.dims[2] == 9 and info.dims[3] == 11, "info dims")
check(info.raw_bytes == 17 * 9 * 11 * 5, "raw_bytes")
check(info.window[1] == 0 and info.window[2] == 255, "u8 window")
check(#info.variants == 4, "4 variants")
local names = st:variants()
check(names[1] == "S4T3" and names[2] == "S1T2s" and names[3] == "raw" and names[4] == "mine",
      "names: " .. table.concat(names, ","))
local total = 0
for i, v in ipairs(info.variants) do
  total = total + v.bytes
  check(v.bpv == 8 * v.bytes / info.raw_bytes and v.ratio == v.bytes / info.raw_bytes, "bpv/ratio " .. v.name)
  check(v.payload_bytes >= v.bytes, "payload >= stored " .. v.name)
end
check(info.bytes == total, "info.bytes sums variants")
check(info.ratio == info.variants[1].bytes / info.raw_bytes, "info.ratio")
check(info.variants[1].chunks == 2 and info.variants[2].chunks == 5 and info.variants[3].chunks == 5,
      "chunk counts")
check(info.variants[2].encoder == "bbox" and info.variants[2].pack == "space", "variant fields")
check(info.variants[3].codec == "raw" and info.variants[3].psnr == math.huge and info.variants[3].maxerr == 0,
      "raw lossless")
-- S4T3 time packing with 5 timesteps: {1,2,3}, {4,5} padded
-- stage 2 defaults to auto: stored bytes equal the payload exactly when no chunk packs
local v1 = info.variants[1]
check(v1.stage2 == "auto" and (v1.stage2_chunks.none == v1.chunks) == (v1.bytes == v1.payload_bytes),
      "stage2")

-- decode: every timestep of every variant; PSNR recorded at encode time matches cdvr.compare
for vi, v in ipairs(info.variants) do
  local sse = 0
  local maxerr = 0
  for t = 1, 5 do
    local d = (vi % 2 == 0) and st:decode(t, v.name) or st:decode(t, vi)
    check(d:type() == "u8" and d:timesteps() == 1, "decoded u8 frame")
    local r = cdvr.compare(src:frame(t), d)
    sse = sse + r.mse
    maxerr = math.max(maxerr, r.maxerr)
  end
  local psnr = sse == 0 and math.huge or 10 * math.log(255 * 255 / (sse / 5), 10)
  check(math.abs(psnr - v.psnr) < 1e-6 or psnr == v.psnr, ("%s psnr %g vs compare %g"):format(v.name, v.psnr, psnr))
  check(maxerr == v.maxerr, v.name .. " maxerr")
end
check(cdvr.compare(st:decode(1), st:decode(1, 1)).mse == 0, "default variant is the first")
check(cdvr.compare(st:decode(2, {device = "cpu"}), st:decode(2, 1)).mse == 0, "opts in 3rd place")
local ok, cl = pcall(st.decode, st, 4, "S4T3", {device = "cl"})
if ok then check(cdvr.compare(cl, st:decode(4, "S4T3")).mse == 0, "cl decode bit-exact") end
raises("timestep out of range", st.decode, st, 6)
raises("timestep out of range", st.decode, st, 0)
raises('no variant "nope"', st.decode, st, 1, "nope")
raises("variant index out of range", st.decode, st, 1, 9)
raises("invalid value 'gpu'", st.decode, st, 1, 1, {device = "gpu"})

-- chunks
local bytes, ci = st:chunk(2, "S4T3")
check(ci.t0 == 4 and ci.timesteps == 2 and ci.S == 4 and ci.T == 3 and ci.pack == "time", "chunk 2 info")
check(#bytes == ci.payload_bytes and type(ci.stage2) == "boolean", "chunk payload size")
local blocks = math.ceil(17 / 4) * math.ceil(9 / 4) * math.ceil(11 / 4)
check(#bytes == blocks * (4 + 4 * 4), "PVTC geometry of S4T3")
local raw1 = st:chunk(3, "raw")
check(#raw1 == 17 * 9 * 11, "raw chunk")
check(raw1:byte(1 + 8 + 17 * (4 + 9 * 5)) == src:get(8, 4, 5, 3), "raw chunk holds the voxels")
raises("chunk index out of range", st.chunk, st, 3, "S4T3")

-- timing helpers
local c0 = cdvr.clock()
check(type(c0) == "number" and cdvr.clock() >= c0, "clock")
check(cdvr.bench_memcpy(1 << 16, 3) > 0, "bench_memcpy")
check(st:bench_decode("S4T3", 3) > 0 and st:bench_unpack(1, 3) > 0, "bench decode/unpack")
raises("repeats must be", st.bench_decode, st, 1, 0)

st:close()
check(tostring(st):find("closed", 1, true), "closed tostring")
raises("closed store", st.info, st)
st:close() -- idempotent

-- reopen, __close
do
  local s2 <close> = assert(cdvr.open(path))
  check(#s2:variants() == 4, "reopen")
end

-- schedule: T per group, called with t from 1
local seen = {}
local s3 = cdvr.encode(src, {path = tmp("sched.cdv"), progress = false, S = 1, T = 3,
  schedule = function(t, variant) seen[#seen + 1] = t; if t == 1 then return {T = 2} end; return {S = 4} end})
check(table.concat(seen, ",") == "1,3", "schedule calls " .. table.concat(seen, ","))
local _, c1 = s3:chunk(1)
local _, c2 = s3:chunk(2)
check(c1.T == 2 and c1.S == 1 and c1.timesteps == 2 and c2.T == 3 and c2.S == 4 and c2.t0 == 3, "per-chunk params")
s3:close()
raises("boom", cdvr.encode, src, {path = tmp("boom.cdv"), progress = false,
  schedule = function(t) if t > 1 then error("boom") end end})
check(not exists(tmp("boom.cdv")), "no file after a schedule error")
raises("S = '2', must be 1 or 4", cdvr.encode, src, {path = tmp("boom.cdv"), schedule = function() return {S = 2} end})

-- bad options raise; write failures return nil, msg
raises("unknown codec 'zip' (loaded: raw, pvtc", cdvr.encode, src, {path = tmp("x.cdv"), codec = "zip"})
raises("S = '3', must be 1 or 4", cdvr.encode, src, {path = tmp("x.cdv"), S = 3})
raises("pack = 'diagonal', must be \"time\" or \"space\"", cdvr.encode, src, {path = tmp("x.cdv"), pack = "diagonal"})
raises("encoder = 'magic'", cdvr.encode, src, {path = tmp("x.cdv"), encoder = "magic"})
raises("option 'stage2': invalid value 'brotli' (expected none, lzo, lz4, zstd, auto)", cdvr.encode, src, {path = tmp("x.cdv"), stage2 = "brotli"})
raises("lzo_min_saving", cdvr.encode, src, {path = tmp("x.cdv"), lzo_min_saving = 2})
raises("'path' is required", cdvr.encode, src, {})
raises("two variants are called S4T3", cdvr.encode, src, {path = tmp("x.cdv"), variants = {{}, {}}})
-- a write failure raises (an encoder opens what it writes, as cdvr.open: lcdvr.h's rule)
raises(tmp("no/dir/x.cdv"), cdvr.encode, src, {path = tmp("no/dir/x.cdv"), progress = false})
raises(tmp("missing.cdv"), cdvr.open, tmp("missing.cdv")) -- an error naming the file

-- float input is quantized over its range; the window is recorded
local f = cdvr.generate("ml", {dims = {9, 8, 7}, timesteps = 2, type = "f32"})
local lo, hi = f:range()
local sf = cdvr.encode(f, {path = tmp("f.cdv"), codec = "raw", progress = false})
local fi = sf:info()
check(fi.window[1] == lo and fi.window[2] == hi and fi.source_type == "f32", "window recorded")
check(cdvr.compare(sf:decode(2), f:quantize{lo = lo, hi = hi}:frame(2)).mse == 0, "quantized like v:quantize")
sf:close()

-- corruption: a flipped chunk byte raises naming file and chunk; a flipped header byte fails open
local function flip(p, offset)
  local fh = assert(io.open(p, "r+b"))
  fh:seek("set", offset)
  local b = fh:read(1)
  fh:seek("set", offset)
  fh:write(string.char(b:byte() ~ 0x10))
  fh:close()
end
local cpath = tmp("c.cdv")
cdvr.encode(src, {path = cpath, codec = "raw", stage2 = "none", progress = false}):close()
local size = #assert(io.open(cpath, "rb")):read("a")
flip(cpath, size - 10) -- inside the last chunk
local sc = assert(cdvr.open(cpath))
check(sc:decode(1) ~= nil, "intact chunk still decodes")
raises("chunk 5: CRC-32C mismatch", sc.decode, sc, 5)
raises(cpath, sc.decode, sc, 5)
sc:close()
flip(cpath, 30)
raises(cpath, cdvr.open, cpath)
raises("CRC", cdvr.open, cpath)

-- real data: lsq never loses to bbox on a viscous-fingers excerpt
local data = os.getenv("CDVR_SHARED_DATA")
if data then
  local vf = assert(cdvr.load_series(data .. "/series/viscousfingers/vf_t%03d.nrrd", {first = 60, count = 6}))
  local q = vf:quantize{lo = 0, hi = 125}
  local sv = cdvr.encode(q, {path = tmp("vf.cdv"), progress = false, variants = {
    {S = 1, T = 3, encoder = "lsq"}, {S = 1, T = 3, encoder = "bbox", name = "bbox"}}})
  local vi = sv:info().variants
  check(vi[1].psnr >= vi[2].psnr, ("lsq %.2f dB < bbox %.2f dB"):format(vi[1].psnr, vi[2].psnr))
  sv:close()
end

os.execute("rm -rf " .. dir)
if failures > 0 then
  io.stderr:write(failures, " failures\n")
  os.exit(1)
end
print("test_store.lua: ok")
