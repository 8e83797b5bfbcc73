-- Rate control end to end, with injected stage times: the real player plays a real store and
-- calls the real policies, but every frame row the policy sees carries stage times from a fixed
-- model of an emulated disk (5 MB/s) and device, computed from the row's own variant and byte
-- counts. So the decisions are deterministic and this test checks correctness (which variant
-- each group gets, and why), never the wall clock. The timed version of the same scenario is the
-- benchmark scripts/bench/rate_control.lua.
--
-- Series: the viscous-fingers timesteps 40-69 when ../shared/data is there, else a generated
-- Marschner-Lobb series of the same size (64^3 x 30); variants S1T3, S4T3 and raw.
local shared = os.getenv("CDVR_SHARED_DATA")
local first = shared and shared .. "/series/viscousfingers/vf_t040.nrrd"
local q
if first and io.open(first) then
  local vf = cdvr.load_series(shared .. "/series/viscousfingers/vf_t%03d.nrrd", {first = 40, count = 30})
  q = vf:quantize{lo = 0, hi = 125}
else
  print("note: ../shared/data not found; a generated 64^3 x 30 series stands in")
  q = cdvr.generate("ml", {dims = {64, 64, 64}, timesteps = 30})
end
local path = os.tmpname()
local st = assert(cdvr.encode(q, {variants = {{S = 1, T = 3}, {S = 4, T = 3}, {codec = "raw"}},
                                  encoder = "bbox", stage2 = "none", path = path, progress = false}))
local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(q, {azimuth = 30, elevation = 20, width = 16, height = 16})

-- The model: read at 5 MB/s (5000 bytes per ms; a 64^3 raw timestep takes 52.4 ms, S1T3 8.7 ms,
-- S4T3 5.5 ms), decode 0.5 ms for a PVTC frame and 0 for raw, render 1 ms; the frame time is the
-- serial sum, or for the pipelined player the slowest of read and the device stages.
local READ_BYTES_PER_MS, DECODE_MS, RENDER_MS = 5000, 0.5, 1.0
local function model_ms(bytes, variant, pipelined)
  local read = bytes / READ_BYTES_PER_MS
  local device = (variant == "raw" and 0 or DECODE_MS) + RENDER_MS
  return read, device, pipelined and math.max(read, device) or read + device
end

local function inject(row, pipelined)
  local read, device, frame = model_ms(row.bytes, row.variant, pipelined)
  row.read_ms, row.unzip_ms, row.upload_ms = read, 0, 0
  row.decode_ms, row.setup_ms, row.render_ms = device - RENDER_MS, 0, RENDER_MS
  row.frame_ms, row.interval_ms = frame, frame
end

-- A policy that sees the model's times instead of the measured ones.
local function with_model(policy, pipelined)
  return function(stats)
    for _, row in ipairs(stats.frames) do inject(row, pipelined) end
    return policy(stats)
  end
end

local function play(name, opts)
  local make = cdvr.policy.get(name, {target_fps = opts.target}) -- the floor comes in stats.min_psnr
  local p = cdvr.player{store = st, tf = tf, camera = cam, device = "cpu", threads = 1, pace = false, ring = 3,
                        pipeline = opts.pipelined or false, target_fps = opts.target,
                        min_psnr = opts.min_psnr, policy = with_model(make, opts.pipelined)}
  local r = p:run{frames = 30}
  p:close()
  print(("%s, target %g fps%s%s:"):format(name, opts.target, opts.pipelined and ", pipelined" or "",
                                          opts.min_psnr and (", min_psnr %g"):format(opts.min_psnr) or ""))
  local decisions = 0
  for _, row in ipairs(r.frames) do
    assert(not row.error, row.error)
    if row.reason then
      decisions = decisions + 1
      print(("  t=%2d %-5s %s"):format(row.t, row.variant, row.reason))
    end
  end
  assert(decisions == 10, "one decision per group of 3: " .. decisions)
  return r
end

-- After the first `settle` groups every frame uses `needed`, and its modelled frame time meets
-- the target (when the target is feasible).
local function check(r, opts, needed, settle)
  for i = 3 * settle + 1, #r.frames do
    local row = r.frames[i]
    assert(row.variant == needed, ("frame %d (t=%d) used %s, needed %s"):format(i, row.t, row.variant, needed))
    local _, _, ms = model_ms(row.bytes, row.variant, opts.pipelined)
    if opts.feasible ~= false then
      assert(ms <= 1000 / opts.target, ("modelled %.2f ms misses the target %.2f ms"):format(ms, 1000 / opts.target))
    end
  end
end

local S1T3_psnr
for _, v in ipairs(st:info().variants) do
  if v.name == "S1T3" then S1T3_psnr = v.psnr end
end

-- closed_loop starts at the best quality (raw: 53.9 ms) and steps down.
-- 50 fps (20 ms): raw cannot, S1T3 (10.2 ms) can, and raw's prediction (53.9 ms) keeps it there.
local opts = {target = 50}
check(play("closed_loop", opts), opts, "S1T3", 1)
-- 125 fps (8 ms): S1T3 (10.2 ms) is over target + 10 %, S4T3 (7.0 ms) fits.
opts = {target = 125}
check(play("closed_loop", opts), opts, "S4T3", 2)
-- open_loop predicts from the first group's model times: S1T3 at 50 fps, S4T3 at 125 fps.
opts = {target = 50}
check(play("open_loop", opts), opts, "S1T3", 1)
opts = {target = 125}
check(play("open_loop", opts), opts, "S4T3", 1)
-- Pipelined: the frame time is the read alone (device 1.5 ms), so 100 fps (10 ms) fits S1T3
-- (8.7 ms) where the serial sum (10.2 ms) would not. The reader decides ahead of the frames
-- shown (up to `ring` chunks queued, plus the one being read), so how many rows a decision sees
-- depends on thread timing: the check starts after ring + 2 groups.
opts = {target = 100, pipelined = true}
check(play("closed_loop", opts), opts, "S1T3", 5)
opts = {target = 100, pipelined = true}
check(play("open_loop", opts), opts, "S1T3", 5)
-- A quality floor at S1T3's PSNR: 125 fps is infeasible above it, so S1T3 stays (never S4T3).
opts = {target = 125, min_psnr = S1T3_psnr - 0.01, feasible = false}
local r = play("closed_loop", opts)
check(r, opts, "S1T3", 1)
local said = false
for _, row in ipairs(r.frames) do
  said = said or (row.reason and row.reason:find("already the fastest allowed", 1, true) ~= nil)
end
assert(said, "the reason says why it stays")

st:close()
os.remove(path)
print("test_rate_control: ok")
