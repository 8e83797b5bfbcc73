-- scripts/bench/hvq.lua: hvq (FCHVQ + perfect spatial hashing, rendered in the compressed
-- domain) against PVTC and zfp (when its plugin is loaded) on the Colin27 MRI, the engine CT
-- and a copy of Colin27 thresholded so that ~85% of voxels are zero (the seed's sparse
-- light-sheet data). All in one run, so ratios between rows are comparable.
--
--   cdvr scripts/bench/hvq.lua [--runs N] [--size PIXELS]
--
-- scripts/bench/hvq_bench.sh measures the codec side alone (ratio, bpv, volume PSNR, maxerr,
-- encode/decode time) through the codec table, without the store or a device.
--
-- CSV on stdout, one row per dataset x variant:
--   ratio, bpv          raw bytes / stored bytes of the variant (st:info()'s ratio is the
--                       inverse, stored / raw), bits per voxel stored
--   volume_psnr, maxerr decoded volume against the original
--   image_psnr          device render of the variant against the CPU render of the original
--   encode_s            wall time of cdvr.encode (one variant)
--   device_bytes        device memory held for one frame (st:info()); dense_bytes: X*Y*Z
--   fps_variant         renders per second of the variant on the device (hvq: compressed
--                       domain, every sample through the fetch), median of RUNS
--   fps_dense           the same camera on the dense decoded volume on the device
--   fps_ratio           fps_variant / fps_dense
--   zero_blocks, residual_voxels, means, codebook1, codebook2, index_hash, residual_hash
--                       hvq's figures (st:info(), summed over chunks)
local common = dofile((debug.getinfo(1, "S").source:match("^@(.*)/[^/]*$") or ".") .. "/common.lua")

local _, opt = common.parse_args(arg, {runs = "5", size = "384"})
local RUNS, SIZE = assert(math.tointeger(tonumber(opt.runs))), assert(math.tointeger(tonumber(opt.size)))
local data = common.shared_data()

local function sparse_copy(v, zero_fraction)
  local X, Y, Z = v:dims()
  local hist = {}
  for i = 0, 255 do hist[i] = 0 end
  for z = 0, Z - 1 do for y = 0, Y - 1 do for x = 0, X - 1 do
    local val = v:get(x, y, z)
    hist[val] = hist[val] + 1
  end end end
  local n, below, t, best = X * Y * Z, 0, 0, math.huge
  for val = 0, 256 do
    local miss = math.abs(below / n - zero_fraction)
    if miss < best then best, t = miss, val end
    if val < 256 then below = below + hist[val] end
  end
  local s = cdvr.volume{dims = {X, Y, Z}, type = "u8"}
  for z = 0, Z - 1 do for y = 0, Y - 1 do for x = 0, X - 1 do
    local val = v:get(x, y, z)
    s:set(x, y, z, val < t and 0 or val)
  end end end
  io.stderr:write(("colin27_sparse85: voxels below %d set to 0\n"):format(t))
  return s
end

local function fmt(x)
  if x == nil then return "" end
  if type(x) == "string" then return x end
  if x == math.huge then return "inf" end
  if math.type(x) == "integer" then return tostring(x) end
  return ("%.4g"):format(x)
end

local function timed_fps(target, opts)
  cdvr.render(target, opts) -- warm-up: program build, uploads
  local times = {}
  for r = 1, RUNS do
    local t0 = cdvr.clock()
    cdvr.render(target, opts)
    times[r] = cdvr.clock() - t0
  end
  return 1 / common.median(times)
end

local tmp = os.tmpname()
local columns = {"dataset", "variant", "codec", "ratio", "bpv", "volume_psnr", "maxerr", "image_psnr",
                 "encode_s", "device_bytes", "dense_bytes", "fps_variant", "fps_dense", "fps_ratio",
                 "zero_blocks", "residual_voxels", "means", "codebook1", "codebook2", "index_hash",
                 "residual_hash"}
print(table.concat(columns, ","))

local function bench(name, vol, tf, spec)
  local t0 = cdvr.clock()
  local st = assert(cdvr.encode(vol, {variants = {spec}, path = tmp, progress = false}))
  local encode_s = cdvr.clock() - t0
  local row = st:info().variants[1]
  local dec = st:decode(1, row.name)
  local vcmp = cdvr.compare(vol, dec)
  local cam = common.view(vol, 30, 20, SIZE, SIZE)
  local ref = cdvr.render(vol, {tf = tf, camera = cam, device = "cpu"})
  local img = cdvr.render(st, {t = 1, variant = row.name, tf = tf, camera = cam, device = "cl"})
  local X, Y, Z = vol:dims()
  local fps_v = timed_fps(st, {t = 1, variant = row.name, tf = tf, camera = cam, device = "cl"})
  local fps_d = timed_fps(dec, {tf = tf, camera = cam, device = "cl"})
  local bytes = row -- hvq's part sizes are fields of its row (st:info())
  local r = {dataset = name, variant = row.name, codec = spec.codec, ratio = 1 / row.ratio,
             bpv = row.bpv, volume_psnr = vcmp.psnr, maxerr = vcmp.maxerr,
             image_psnr = cdvr.compare(ref, img).psnr, encode_s = encode_s,
             device_bytes = row.device_bytes, dense_bytes = X * Y * Z, fps_variant = fps_v,
             fps_dense = fps_d, fps_ratio = fps_v / fps_d, zero_blocks = row.zero_blocks,
             residual_voxels = row.residual_voxels, means = bytes.means, codebook1 = bytes.codebook1,
             codebook2 = bytes.codebook2, index_hash = bytes.index_hash,
             residual_hash = bytes.residual_hash}
  local out = {}
  for i, c in ipairs(columns) do out[i] = fmt(r[c]) end
  print(table.concat(out, ","))
  io.stdout:flush()
  st:close()
  os.remove(tmp)
  return r
end

local has_zfp = false
for _, c in ipairs(cdvr.codecs and cdvr.codecs() or {}) do
  if (type(c) == "table" and c.name or c) == "zfp" then has_zfp = true end
end

local colin = assert(cdvr.load(data .. "/mri/colin27_t1_301x370x316_u8.nii.gz"))
local sets = {
  {"colin27", colin, cdvr.tf("mri")},
  {"engine", assert(cdvr.load(data .. "/ct/engine_256x256x128_u8.nrrd")), cdvr.tf("ct_bone")},
  {"colin27_sparse85", sparse_copy(colin, 0.85), cdvr.tf("mri")},
}
for _, s in ipairs(sets) do
  local name, vol, tf = s[1], s[2], s[3]
  common.progress("%s", name)
  local hvq = bench(name, vol, tf, {codec = "hvq"})
  bench(name, vol, tf, {codec = "hvq", grad = 64, residual = 10})
  bench(name, vol, tf, {codec = "pvtc", S = 4, T = 3, pack = "space"})
  bench(name, vol, tf, {codec = "pvtc", S = 1, T = 3, pack = "space"})
  if has_zfp then -- fixed rate at hvq's bits per voxel (zfp's 1/64 steps): the nearest ratio
    bench(name, vol, tf, {codec = "zfp", rate = math.max(1, math.floor(hvq.bpv * 64 + 0.5)) / 64})
  end
end
common.progress_done()
