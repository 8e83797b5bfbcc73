-- scripts/bench/hvq.lua: hvq (FCHVQ, seed 004) in one run: the hashed form "hvq" (rendered in
-- the compressed domain, every sample through the OpenCL fetch) and the compact form "hvqc"
-- (zstd-coded sections, CPU decode), against the old binary's hvq (--old) for the compression
-- targets of issue 27, on a generated light-sheet-like volume (scripts/bench/lightsheet_gen.c:
-- sparse tubes and blobs, ~5% foreground, background 10 + noise sigma 1, 256^3), Colin27 and
-- the engine CT; the light-sheet volume also bricked 4x4x4 (64^3 bricks); "series": 60
-- timesteps of a 128^3 light-sheet volume whose objects drift 0.25 voxel a step (fresh noise
-- each), where hvqc shared=1 pays its codebooks once (bytes_per_t: stored bytes / timesteps).
--
--   cdvr scripts/bench/hvq.lua [--runs N] [--size PIXELS] [--old PATH_TO_OLD_CDVR]
--                              [--sets lightsheet,colin27,engine,series] [--lightsheet FILE.nrrd]
--                              [--specs 'codec=hvqc,psnr=43;codec=hvqc,k2=512'] [--render 0]
--
-- --specs replaces the default rows (hvq, hvqc, hvqc shared=1, and on lightsheet the same
-- bricked 4^3) by these variants, ';'-separated K=V lists (bricks=4 bricks one); the old
-- binary then runs its hvq once per set. --render 0 leaves the renders out (compression only).
--
-- The old binary runs this same script as a child (--child DATASET --spec K=V,..), which
-- prints one row of the compression columns; the rows of both binaries are printed together.
-- Renders are interleaved: variant, dense, variant, dense, ... (RUNS each), medians reported.
--
-- CSV on stdout, one row per dataset x binary x variant:
--   binary              new | old
--   ratio, bpv          raw bytes / stored bytes (st:info()), bits per voxel stored
--   volume_psnr, maxerr decoded volume against the original
--   decode_gbps         voxels decoded per second / 1e9 by st:decode (one thread: the hvq
--                       decoders are single-threaded), median of RUNS
--   encode_s            wall time of cdvr.encode
--   device_bytes        device memory of one frame (st:info())
--   fps_variant         renders/s of the store's variant on the device (hvq: every sample
--                       fetched from the payload; hvqc: as cdvr.render reads a store frame:
--                       the chunk decoded on the CPU, uploaded, then the dense cast)
--   fps_dense           the same camera on the dense decoded volume (OpenCL ray cast)
--   fps_ratio           fps_variant / fps_dense
--   image_psnr          device render of the variant against the CPU render of the original
--   the parts (bytes): means, codebook1, codebook2, index_hash, residual_hash (hashed form),
--   indices, residuals (compact form), residual_voxels, zero_blocks
--   residual_applied    hvqc: the mean residual threshold its chunks got (psnr= target)
local here = (arg and arg[0] and arg[0]:match("^(.*)/[^/]*$")) or "."
local common = dofile(here .. "/common.lua")

local _, opt = common.parse_args(arg, {runs = "5", size = "256", sets = "lightsheet,colin27,engine",
                                       render = "1"})
local RUNS, SIZE = assert(math.tointeger(tonumber(opt.runs))), assert(math.tointeger(tonumber(opt.size)))
local data = common.shared_data()
local outdir = os.getenv("CDVR_BENCH_OUT") or "/tmp/cdvr-hvq"
os.execute("mkdir -p '" .. outdir .. "'")

local function generator()
  local exe = outdir .. "/lightsheet_gen"
  if not common.exists(exe) then
    assert(os.execute(("cc -O2 -std=c11 '%s/lightsheet_gen.c' -lm -o '%s'"):format(here, exe)),
           "cannot build lightsheet_gen")
  end
  return exe
end

local function lightsheet_path()
  if opt.lightsheet then return opt.lightsheet end
  local out = outdir .. "/lightsheet_256_s1.nrrd"
  if common.exists(out) then return out end
  assert(os.execute(("'%s' '%s' 256 1 0"):format(generator(), out)), "lightsheet_gen failed")
  return out
end

local SERIES_T = 60
local function series_glob()
  local dir = outdir .. "/series_128"
  if not common.exists(("%s/ls_%02d.nrrd"):format(dir, SERIES_T - 1)) then
    os.execute("mkdir -p '" .. dir .. "'")
    for t = 0, SERIES_T - 1 do
      assert(os.execute(("'%s' '%s/ls_%02d.nrrd' 128 1 %d 2>/dev/null"):format(generator(), dir, t, t)))
    end
  end
  return dir .. "/ls_*.nrrd"
end

local DATASETS = {
  lightsheet = function() return lightsheet_path(), "ct_bone" end,
  series = function() return series_glob(), "ct_bone", true end,
  colin27 = function() return data .. "/mri/colin27_t1_301x370x316_u8.nii.gz", "mri" end,
  engine = function() return data .. "/ct/engine_256x256x128_u8.nrrd", "ct_bone" end,
}

local columns = {"dataset", "binary", "variant", "bricks", "ratio", "bpv", "bytes_per_t",
                 "shared_bytes", "volume_psnr", "maxerr",
                 "decode_gbps", "encode_s", "device_bytes", "fps_variant", "fps_dense", "fps_ratio",
                 "image_psnr", "means", "codebook1", "codebook2", "index_hash", "residual_hash",
                 "indices", "residuals", "residual_voxels", "zero_blocks", "residual_applied"}

local function fmt(x)
  if x == nil then return "" end
  if type(x) == "string" then return x end
  if x == math.huge then return "inf" end
  if math.type(x) == "integer" then return tostring(x) end
  if x == math.floor(x) and math.abs(x) < 1e15 then return ("%d"):format(x) end
  return ("%.4g"):format(x)
end

local function row_text(r)
  local out = {}
  for i, c in ipairs(columns) do out[i] = fmt(r[c]) end
  return table.concat(out, ",")
end

local function parse_spec(text)
  local spec, bricks = {}, nil
  for k, v in text:gmatch("([%w_]+)=([%w_%.]+)") do
    if k == "bricks" then bricks = assert(math.tointeger(tonumber(v)))
    else spec[k] = tonumber(v) or v end
  end
  return spec, bricks
end

-- Compression columns of one variant (both binaries run this).
local function compress(name, vol, spec, bricks)
  local tmp = os.tmpname()
  local t0 = cdvr.clock()
  local st = assert(cdvr.encode(vol, {variants = {spec}, path = tmp, progress = false,
                                      bricks = bricks and {bricks, bricks, bricks} or nil}))
  local encode_s = cdvr.clock() - t0
  local row = st:info().variants[1]
  local times, dec = {}, nil
  for r = 1, RUNS do
    local t1 = cdvr.clock()
    dec = st:decode(1, row.name)
    times[r] = cdvr.clock() - t1
  end
  local X, Y, Z = vol:dims()
  local T = st:info().timesteps
  -- a series: the encoder's figures over every timestep (st:info()); a volume: compared here
  local c = T > 1 and {psnr = row.psnr, maxerr = row.maxerr} or cdvr.compare(vol, dec)
  local r = {dataset = name, variant = row.name, bricks = bricks and (bricks .. "^3") or "1",
             ratio = 1 / row.ratio, bpv = row.bpv, bytes_per_t = row.bytes / T,
             shared_bytes = row.shared_bytes, volume_psnr = c.psnr, maxerr = c.maxerr,
             decode_gbps = X * Y * Z / common.median(times) / 1e9, encode_s = encode_s,
             device_bytes = row.device_bytes}
  for _, k in ipairs{"means", "codebook1", "codebook2", "index_hash", "residual_hash", "indices",
                     "residuals", "residual_voxels", "zero_blocks"} do r[k] = row[k] end
  if row.residual_sum then r.residual_applied = row.residual_sum / row.chunks end
  return r, st, dec, tmp
end

if opt.child then -- one row for the parent (possibly another binary)
  local path, _, series = DATASETS[opt.child]()
  local spec, bricks = parse_spec(opt.spec or "codec=hvq")
  local vol = assert(series and cdvr.load_series(path) or cdvr.load(path))
  local r, st, _, tmp = compress(opt.child, vol, spec, bricks)
  st:close()
  os.remove(tmp)
  r.binary = "old"
  print(row_text(r))
  return
end

-- Renders alternate variant / dense, RUNS each after one warm-up of each.
local function interleaved_fps(st, row_name, dec, tf, cam)
  local vopts = {t = 1, variant = row_name, tf = tf, camera = cam, device = "cl"}
  local dopts = {tf = tf, camera = cam, device = "cl"}
  local img = cdvr.render(st, vopts)
  cdvr.render(dec, dopts)
  local tv, td = {}, {}
  for r = 1, RUNS do
    local t0 = cdvr.clock()
    cdvr.render(st, vopts)
    tv[r] = cdvr.clock() - t0
    t0 = cdvr.clock()
    cdvr.render(dec, dopts)
    td[r] = cdvr.clock() - t0
  end
  return 1 / common.median(tv), 1 / common.median(td), img
end

local function new_row(name, vol, tfname, spec, bricks, no_render)
  local r, st, dec, tmp = compress(name, vol, spec, bricks)
  r.binary = "new"
  if not bricks and not no_render and opt.render ~= "0" then
    local tf = cdvr.tf(tfname)
    local cam = common.view(vol, 30, 20, SIZE, SIZE)
    local ref = cdvr.render(vol, {tf = tf, camera = cam, device = "cpu"})
    local fv, fd, img = interleaved_fps(st, r.variant, dec, tf, cam)
    r.fps_variant, r.fps_dense, r.fps_ratio = fv, fd, fv / fd
    r.image_psnr = cdvr.compare(ref, img).psnr
  end
  st:close()
  os.remove(tmp)
  print(row_text(r))
  io.stdout:flush()
end

local function old_row(name, spec_text)
  if not opt.old then return end
  local cmd = ("'%s' '%s/hvq.lua' --child %s --spec '%s' --runs %d"):format(opt.old, here, name,
                                                                          spec_text, RUNS)
  local p = assert(io.popen(cmd))
  local out = p:read("a")
  p:close()
  io.write(out)
  io.stdout:flush()
end

print(table.concat(columns, ","))
for name in opt.sets:gmatch("[^,]+") do
  local path, tf, series = assert(DATASETS[name], "unknown set " .. name)()
  common.progress("%s", name)
  local vol = assert(series and cdvr.load_series(path) or cdvr.load(path))
  if opt.specs then
    old_row(name, "codec=hvq")
    for text in opt.specs:gmatch("[^;]+") do
      local spec, bricks = parse_spec(text)
      new_row(name, vol, tf, spec, bricks, series)
    end
    goto next_set
  end
  old_row(name, "codec=hvq")
  new_row(name, vol, tf, {codec = "hvq"}, nil, series)
  new_row(name, vol, tf, {codec = "hvqc"}, nil, series)
  new_row(name, vol, tf, {codec = "hvqc", shared = 1}, nil, series)
  if name == "lightsheet" then
    old_row(name, "codec=hvq,bricks=4")
    new_row(name, vol, tf, {codec = "hvq"}, 4)
    new_row(name, vol, tf, {codec = "hvqc"}, 4)
    new_row(name, vol, tf, {codec = "hvqc", shared = 1}, 4)
  end
  ::next_set::
end
common.progress_done()
