-- scripts/bench/codecs.lua: speed against error of every PVTC variant, encoder and stage 2.
--
--   cdvr scripts/bench/codecs.lua [DATASET ...]
--
-- DATASET: a printf series pattern ("dir/vf_t%03d.nrrd"), a directory of NRRD files (sorted by
-- name, one timestep each) or a 4D NIfTI. Default: the viscous fingers series and the mpld_asl
-- 4D NIfTI in ../shared/data (or $CDVR_SHARED_DATA). Non-u8 data is quantized over its range.
--
-- CSV on stdout, one row per dataset x variant x encoder x stage2:
--   decode_mbps  C decoder, output bytes, single thread, median of 5 passes over all chunks
--   memcpy_mbps  memcpy of the same byte count, measured right after, median of 5, copied in
--                pieces of 3 frames into one reused buffer: the same write working set as the
--                decode pass, which decodes every chunk into one reused 3-frame buffer
--   decode_ratio decode_mbps / memcpy_mbps (the machine-independent figure)
--   lzo_ratio    stored / payload bytes;  lzo_decode_mbps  LZO unpack, payload bytes, median of 5
--   encode_mbps  input bytes / wall time of cdvr.encode (includes the PSNR decode)
-- A summary of the targets (lsq gain over bbox, S1T3 decode ratio) goes to stderr.

local REPEATS = 5

local function script_dir()
  local p = arg and arg[0] or ""
  return p:match("^(.*)/[^/]*$") or "."
end

local function shared_data()
  return os.getenv("CDVR_SHARED_DATA") or (script_dir() .. "/../../../shared/data")
end

local function exists(path)
  local f = io.open(path, "rb")
  if f then f:close() end
  return f ~= nil
end

local function first_index(pattern)
  for i = 0, 10000 do
    if exists(pattern:format(i)) then return i end
  end
  error("no file matches " .. pattern)
end

local function list_nrrd(dir)
  local files = {}
  local p = assert(io.popen("ls -1 '" .. dir:gsub("'", "'\\''") .. "'"))
  for name in p:lines() do
    if name:match("%.nrrd$") or name:match("%.nhdr$") then files[#files + 1] = dir .. "/" .. name end
  end
  p:close()
  table.sort(files)
  assert(#files > 0, dir .. ": no NRRD files")
  return files
end

local function is_dir(path)
  return os.execute("test -d '" .. path:gsub("'", "'\\''") .. "'") == true
end

local function load_dataset(spec)
  local v, err
  if spec:find("%%") then
    local first = first_index(spec)
    local count = 0
    while exists(spec:format(first + count)) do count = count + 1 end
    v, err = cdvr.load_series(spec, {first = first, count = count})
  elseif is_dir(spec) then
    v, err = cdvr.load_series(list_nrrd(spec))
  else
    v, err = cdvr.load(spec)
  end
  assert(v, err)
  if v:type() ~= "u8" then v = v:quantize{} end
  return v
end

-- "viscousfingers" for a series pattern or directory, the file name without extensions else.
local function short_name(spec)
  local path = spec:gsub("/+$", "")
  if spec:find("%%") then path = path:match("^(.*)/[^/]*$") or path end
  local base = path:match("([^/]+)$") or path
  return (base:gsub("%.nii%.gz$", ""):gsub("%.[^.]*$", ""))
end

local VARIANTS = {}
for _, pack in ipairs({"time", "space"}) do
  for _, st in ipairs({{1, 2}, {1, 3}, {4, 2}, {4, 3}}) do
    VARIANTS[#VARIANTS + 1] = {S = st[1], T = st[2], pack = pack}
  end
end
VARIANTS[#VARIANTS + 1] = {codec = "raw"}

local function fmt(x)
  if x == nil then return "" end
  if x == math.huge then return "inf" end
  return ("%.4g"):format(x)
end

local tmpdir = os.tmpname()
os.remove(tmpdir)
assert(os.execute("mkdir -p '" .. tmpdir .. "'"))

local function bench_one(dsname, vol, variant, encoder, stage2, results)
  local opts = {path = tmpdir .. "/b.cdv", progress = false, stage2 = stage2, encoder = encoder}
  for k, val in pairs(variant) do opts[k] = val end
  local t0 = cdvr.clock()
  local st = assert(cdvr.encode(vol, opts))
  local encode_s = cdvr.clock() - t0
  local info = st:info()
  local v = info.variants[1]
  local decode = st:bench_decode(1, REPEATS)
  local frame_bytes = info.dims[1] * info.dims[2] * info.dims[3]
  local memcpy = cdvr.bench_memcpy(info.raw_bytes, REPEATS, math.min(3 * frame_bytes, info.raw_bytes))
  local lzo_decode = stage2 == "lzo" and st:bench_unpack(1, REPEATS) or nil
  st:close()
  os.remove(opts.path)
  local row = {dataset = dsname, variant = v.name, encoder = variant.codec == "raw" and "-" or encoder,
               stage2 = stage2, bpv = v.bpv, psnr = v.psnr, maxerr = v.maxerr,
               encode_mbps = info.raw_bytes / 1e6 / encode_s, decode_mbps = decode,
               memcpy_mbps = memcpy, decode_ratio = decode / memcpy,
               lzo_ratio = v.bytes / v.payload_bytes, lzo_decode_mbps = lzo_decode}
  results[#results + 1] = row
  io.write(table.concat({row.dataset, row.variant, row.encoder, row.stage2, fmt(row.bpv), fmt(row.psnr),
    fmt(row.maxerr), fmt(row.encode_mbps), fmt(row.decode_mbps), fmt(row.memcpy_mbps),
    fmt(row.decode_ratio), fmt(row.lzo_ratio), fmt(row.lzo_decode_mbps)}, ","), "\n")
  io.stdout:flush()
end

local function summarize(results)
  local by = {}
  for _, r in ipairs(results) do by[r.dataset .. "/" .. r.variant .. "/" .. r.encoder .. "/" .. r.stage2] = r end
  local seen = {}
  for _, r in ipairs(results) do
    if not seen[r.dataset] then
      seen[r.dataset] = true
      for _, name in ipairs({"S1T3", "S4T3"}) do
        local lsq, bbox = by[r.dataset .. "/" .. name .. "/lsq/none"], by[r.dataset .. "/" .. name .. "/bbox/none"]
        if lsq and bbox then
          local gain = lsq.psnr - bbox.psnr
          io.stderr:write(("%s %s: lsq %.2f dB, bbox %.2f dB, gain %.2f dB (target >= 1.5) %s\n"):format(
            r.dataset, name, lsq.psnr, bbox.psnr, gain, gain >= 1.5 and "MET" or "MISSED"))
        end
      end
      local s13 = by[r.dataset .. "/S1T3/lsq/none"]
      if s13 then
        io.stderr:write(("%s S1T3 decode %.0f MB/s = %.2fx memcpy (target >= 0.3) %s\n"):format(
          r.dataset, s13.decode_mbps, s13.decode_ratio, s13.decode_ratio >= 0.3 and "MET" or "MISSED"))
      end
    end
  end
end

local datasets = {...}
if #datasets == 0 then
  local d = shared_data()
  datasets = {d .. "/series/viscousfingers/vf_t%03d.nrrd", d .. "/mri/mpld_asl_64x64x24x25_f32.nii.gz"}
end

print("dataset,variant,encoder,stage2,bpv,psnr,maxerr,encode_mbps,decode_mbps,memcpy_mbps,decode_ratio,lzo_ratio,lzo_decode_mbps")
local results = {}
for _, spec in ipairs(datasets) do
  local vol = load_dataset(spec)
  local name = short_name(spec)
  for _, variant in ipairs(VARIANTS) do
    local encoders = variant.codec == "raw" and {"lsq"} or {"lsq", "bbox"}
    for _, encoder in ipairs(encoders) do
      for _, stage2 in ipairs({"none", "lzo"}) do
        bench_one(name, vol, variant, encoder, stage2, results)
      end
    end
  end
end
summarize(results)
os.execute("rm -rf '" .. tmpdir .. "'")
