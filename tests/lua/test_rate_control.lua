-- Rate control on a real series under an emulated disk (read_mbps): closed_loop with a
-- feasible target holds the median achieved frame rate within 10% of the target after the
-- first 3 groups and picks no variant of lower quality than needed; open_loop too.
-- Prints the policy trace (variant per group) for each target.
local shared = os.getenv("CDVR_SHARED_DATA")
local first = shared and shared .. "/series/viscousfingers/vf_t040.nrrd"
if not (first and io.open(first)) then
  print("skip: ../shared/data/series/viscousfingers not found")
  os.exit(77)
end
local vf = assert(cdvr.load_series(shared .. "/series/viscousfingers/vf_t%03d.nrrd", {first = 40, count = 30}))
local q = vf:quantize{lo = 0, hi = 125}
local path = os.tmpname()
local st = assert(cdvr.encode(q, {variants = {{S = 1, T = 3}, {S = 4, T = 3}, {codec = "raw"}},
                                  stage2 = "none", path = path}))
local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(q, {azimuth = 30, elevation = 20, width = 24, height = 24})
local READ_MBPS = 5    -- raw timestep 262144 B -> 52 ms, S1T3 -> 8.7 ms, S4T3 -> 5.5 ms

local function median(t)
  table.sort(t)
  local n = #t
  return n % 2 == 1 and t[(n + 1) // 2] or 0.5 * (t[n // 2] + t[n // 2 + 1])
end

local function play(policy, target)
  local p = cdvr.player{store = st, tf = tf, camera = cam, device = "cpu", threads = 1,
                        pipeline = false, read_mbps = READ_MBPS, policy = policy, target_fps = target}
  local r = p:run{frames = 30}
  p:close()
  local trace, after = {}, {}
  for i, row in ipairs(r.frames) do
    assert(not row.error, row.error)
    if row.reason then trace[#trace + 1] = ("t=%d %s (%s)"):format(row.t, row.variant, row.reason) end
    if i > 9 then after[#after + 1] = row end   -- after the first 3 groups of 3
  end
  return r, trace, after
end

local function check(policy, target, needed)
  local r, trace, after = play(policy, target)
  print(("%s, target %g fps:"):format(policy, target))
  for _, line in ipairs(trace) do print("  " .. line) end
  local intervals = {}
  for _, row in ipairs(after) do
    intervals[#intervals + 1] = row.interval_ms
    assert(row.variant == needed, ("%s target %g: frame t=%d used %s, needed %s"):format(
      policy, target, row.t, row.variant, needed))
  end
  local fps = 1000 / median(intervals)
  print(("  achieved %.1f fps after the first 3 groups (target %g)"):format(fps, target))
  assert(math.abs(fps - target) <= 0.1 * target,
         ("%s: median fps %.1f not within 10%% of target %g"):format(policy, fps, target))
end

-- target 50 fps (20 ms): raw (52 ms) cannot, S1T3 (~9 ms) can: S1T3 is the best that fits.
check("closed_loop", 50, "S1T3")
-- target 125 fps (8 ms): only S4T3 (~6 ms) fits.
check("closed_loop", 125, "S4T3")
check("open_loop", 50, "S1T3")
st:close()
os.remove(path)
print("test_rate_control: ok")
