-- Rate-control policies (share/lua/cdvr/policy.lua) on synthetic stats sequences.
local policy = require "cdvr.policy"
assert(cdvr.policy == policy, "prelude attaches cdvr.policy")

-- Four variants; stored bytes per timestep and encode-time PSNR.
local function variants()
  return {
    { name = "S4T3", codec = "pvtc", S = 4, T = 3, pack = "time", stage2 = "none",
      bytes_per_timestep = 100000, payload_bytes_per_timestep = 100000, psnr = 30, group = 3 },
    { name = "S4T2", codec = "pvtc", S = 4, T = 2, pack = "time", stage2 = "none",
      bytes_per_timestep = 150000, payload_bytes_per_timestep = 150000, psnr = 34, group = 2 },
    { name = "S1T3", codec = "pvtc", S = 1, T = 3, pack = "time", stage2 = "none",
      bytes_per_timestep = 200000, payload_bytes_per_timestep = 200000, psnr = 38, group = 3 },
    { name = "raw", codec = "raw", stage2 = "none",
      bytes_per_timestep = 400000, payload_bytes_per_timestep = 400000, group = 1 },
  }
end

local function by_name(name)
  for _, v in ipairs(variants()) do
    if v.name == name then return v end
  end
  error("no variant " .. name)
end

-- A frame row of a plant where read is 1e-4 ms/byte and the rest costs `fixed_ms`.
local function frame(t, name, opts)
  opts = opts or {}
  local v = by_name(name)
  local read = v.bytes_per_timestep * (opts.ms_per_byte or 1e-4)
  local render = opts.fixed_ms or 10
  local noise = opts.noise or 1
  return { t = t, variant = name, read_ms = read, unzip_ms = 0, upload_ms = 0, decode_ms = 0,
           setup_ms = 0, render_ms = render, frame_ms = (read + render) * noise,
           bytes = v.bytes_per_timestep, payload_bytes = v.payload_bytes_per_timestep }
end

local function stats(fields)
  local s = { variants = variants(), frames = {}, t = 1, group = 1 }
  for k, v in pairs(fields) do s[k] = v end
  return s
end

local function expect_error(pattern, f, ...)
  local ok, err = pcall(f, ...)
  assert(not ok, "expected an error matching " .. pattern)
  assert(tostring(err):find(pattern), "error '" .. tostring(err) .. "' does not match " .. pattern)
end

-- ---- fixed ----
do
  local p = policy.fixed("S4T2")
  local name, reason = p(stats{})
  assert(name == "S4T2" and reason == "fixed")
  assert(p(stats{ current = "raw", frames = { frame(1, "raw") } }) == "S4T2")
  expect_error("no variant named nope", policy.fixed("nope"), stats{})
  assert(policy.fixed()(stats{}) == "raw", "fixed without a name: best quality")
  -- stats.best (cdvr_store_best_variant, from the player or the window) heads the quality
  -- order, so the named policies start where the player and the window do
  local tie = variants()
  tie[5] = { name = "raw2", codec = "raw", stage2 = "none", bytes_per_timestep = 400000,
             payload_bytes_per_timestep = 400000, group = 1 }
  assert(policy.fixed()(stats{variants = tie}) == "raw", "tie by name without stats.best")
  assert(policy.fixed()(stats{variants = tie, best = "raw2"}) == "raw2", "stats.best decides a tie")
  expect_error("stats.best %(nope%) is not a variant", policy.fixed(), stats{best = "nope"})
  -- a raw variant is lossless whatever psnr it lists (as the store's rule)
  local listed = variants()
  listed[4].psnr = 20
  assert(policy.fixed()(stats{variants = listed}) == "raw", "raw ranks first")
  expect_error("string expected", policy.fixed, 3)
  expect_error("stats.variants is empty", p, { variants = {} })
end

-- ---- open loop ----
do
  -- Before any measurement: the best quality.
  local p = policy.open_loop{ target_fps = 25 }
  local name, reason = p(stats{})
  assert(name == "raw", name)
  assert(reason:find("no measurements"), reason)

  -- Predicted (serial) times: raw 50, S1T3 30, S4T2 25, S4T3 20 ms.
  local frames = {}
  for t = 1, 6 do frames[t] = frame(t, t % 2 == 0 and "S4T3" or "S1T3") end
  -- 25 fps, margin 0.9 -> 36 ms: S1T3 (30 ms) is the best that fits.
  name, reason = p(stats{ frames = frames, current = "S1T3" })
  assert(name == "S1T3", name)
  assert(reason:find("^open_loop: S1T3 predicted 30.0 ms <= 36.0 ms"), reason)
  -- 40 fps -> 22.5 ms: only S4T3 (20 ms) fits.
  assert(policy.open_loop{ target_fps = 40 }(stats{ frames = frames }) == "S4T3")
  -- target from stats when the option is absent.
  assert(policy.open_loop{}(stats{ frames = frames, target_fps = 40 }) == "S4T3")
  -- 100 fps -> 9 ms: nothing fits, the fastest.
  name, reason = policy.open_loop{ target_fps = 100 }(stats{ frames = frames })
  assert(name == "S4T3" and reason:find("none fits"), reason)
  -- 10 fps -> 90 ms: raw fits.
  assert(policy.open_loop{ target_fps = 10 }(stats{ frames = frames }) == "raw")

  -- Pipelined: the max of read and the device stages, not the sum. raw: max(40, 10) = 40 ms.
  name = policy.open_loop{ target_fps = 25 }(stats{ frames = frames, pipelined = true })
  assert(name == "S1T3", name)   -- 36 ms budget: raw 40 does not fit
  name = policy.open_loop{ target_fps = 1000 / 45 }(stats{ frames = frames, pipelined = true })
  assert(name == "raw", name)    -- 40.5 ms budget: raw pipelined 40 fits (serial 50 would not)
  name = policy.open_loop{ target_fps = 1000 / 45 }(stats{ frames = frames })
  assert(name == "S1T3", name)
  local m = policy.measure(frames)
  assert(math.abs(policy.predict(by_name("raw"), m, false) - 50) < 1e-9)
  assert(math.abs(policy.predict(by_name("raw"), m, true) - 40) < 1e-9)
  assert(math.abs(policy.predict(by_name("S4T2"), m, true) - 15) < 1e-9)

  -- Stage 2 costs unzip time only for variants whose chunks it shrank.
  local lzo = { name = "lzo", codec = "pvtc", stage2 = "lzo", bytes_per_timestep = 50000,
                payload_bytes_per_timestep = 100000, psnr = 30 }
  local lzo_frames = { { variant = "lzo", read_ms = 5, unzip_ms = 20, upload_ms = 0, decode_ms = 0,
                         setup_ms = 0, render_ms = 10, frame_ms = 35, bytes = 50000,
                         payload_bytes = 100000 } }
  local lm = policy.measure(lzo_frames)
  assert(math.abs(policy.predict(lzo, lm, false) - 35) < 1e-9)
  assert(math.abs(policy.predict(by_name("S4T3"), lm, false) - 20) < 1e-9)

  -- Each stage 2 unpacks at its own rate: lz4 measured 4x faster than lzo here.
  local lz4 = { name = "lz4", codec = "pvtc", stage2 = "lz4", bytes_per_timestep = 50000,
                payload_bytes_per_timestep = 100000, psnr = 30 }
  local zstd = { name = "zstd", codec = "pvtc", stage2 = "zstd", bytes_per_timestep = 40000,
                 payload_bytes_per_timestep = 100000, psnr = 30 }
  local mixed = { lzo_frames[1], { variant = "lz4", read_ms = 5, unzip_ms = 5, upload_ms = 0,
                  decode_ms = 0, setup_ms = 0, render_ms = 10, frame_ms = 20, bytes = 50000,
                  payload_bytes = 100000 } }
  local pm = policy.measure(mixed, { lzo, lz4, zstd })
  assert(math.abs(policy.stages(lzo, pm).unzip - 20) < 1e-9, policy.stages(lzo, pm).unzip)
  assert(math.abs(policy.stages(lz4, pm).unzip - 5) < 1e-9, policy.stages(lz4, pm).unzip)
  -- zstd not measured yet: the median rate over every frame
  local all = 100000 / pm.unzip
  assert(all > 5 and all < 20 and math.abs(policy.stages(zstd, pm).unzip - all) < 1e-9, all)
  -- without the variants: one rate for all
  assert(math.abs(policy.stages(lz4, policy.measure(mixed)).unzip - all) < 1e-9)
  -- the skip grids (grid_ms) run on the unzip worker: pipelined max(read, unzip + grid, device)
  local gridded = { { variant = "lz4", read_ms = 5, unzip_ms = 5, grid_ms = 4, upload_ms = 0,
                      decode_ms = 0, setup_ms = 0, render_ms = 7, frame_ms = 20, bytes = 50000,
                      payload_bytes = 100000 } }
  local gm = policy.measure(gridded, { lz4 })
  assert(math.abs(policy.predict(lz4, gm, true) - 9) < 1e-9, policy.predict(lz4, gm, true))
  assert(math.abs(policy.predict(lz4, gm, false) - 21) < 1e-9, policy.predict(lz4, gm, false))
  local ok, err = pcall(policy.measure, mixed, "lzo")
  assert(not ok and err:find("bad argument #2 to 'measure'"), err)
  -- Render time per variant: an hvq variant (every sample fetched from its payload) renders
  -- slower than the dense variants; once measured, its own median is used.
  local hvq = { name = "hvq", codec = "hvq", bytes_per_timestep = 50000,
                payload_bytes_per_timestep = 50000, psnr = 43 }
  local hmixed = {
    { variant = "S4T3", read_ms = 5, upload_ms = 0, decode_ms = 0, setup_ms = 0, render_ms = 10,
      frame_ms = 15, bytes = 50000, payload_bytes = 50000 },
    { variant = "hvq", read_ms = 5, upload_ms = 0, decode_ms = 0, setup_ms = 0, render_ms = 200,
      frame_ms = 205, bytes = 50000, payload_bytes = 50000 },
    { variant = "S4T3", read_ms = 5, upload_ms = 0, decode_ms = 0, setup_ms = 0, render_ms = 10,
      frame_ms = 15, bytes = 50000, payload_bytes = 50000 } }
  local hm = policy.measure(hmixed)
  assert(math.abs(policy.predict(hvq, hm, false) - 205) < 1e-9, policy.predict(hvq, hm, false))
  assert(policy.stages(by_name("S4T3"), hm).render == 10)
  assert(policy.stages(by_name("raw"), hm).render == 10) -- unmeasured: all frames' median

  -- min_psnr is a floor even when the target cannot be met.
  name = policy.open_loop{ target_fps = 100 }(stats{ frames = frames, min_psnr = 35 })
  assert(name == "S1T3", name)
end

-- ---- closed loop ----
local function run_group(p, s, name, n, opts)
  for i = 1, n do
    s.frames[#s.frames + 1] = frame(s.t + i - 1, name, opts and opts[i] or nil)
  end
  while #s.frames > 16 do table.remove(s.frames, 1) end
  s.t, s.group, s.current = s.t + n, s.group + 1, name
  return p(s)
end

do
  -- Target 32 ms (31.25 fps): raw 50 ms is too slow -> step down one variant per group.
  local p = policy.closed_loop{ target_fps = 31.25 }
  local s = stats{}
  local name, reason = p(s)
  assert(name == "raw", "starts at the best quality")
  assert(reason:find("start"), reason)
  name, reason = run_group(p, s, name, 6)
  assert(name == "S1T3", name)
  assert(reason:find("step down to S1T3"), reason)
  -- S1T3 (30 ms) is within 32 +- 10 %: stays.
  for _ = 1, 5 do
    name, reason = run_group(p, s, name, 6)
    assert(name == "S1T3", reason)
  end

  -- Steps up only when a better variant fits, and only after two groups; then to the best
  -- one that fits (S1T3 30 ms; raw 50 ms does not).
  p = policy.closed_loop{ target_fps = 31.25 }
  s = stats{ current = "S4T3" }
  name, reason = run_group(p, s, "S4T3", 6)  -- 20 ms < 28.8, S1T3 predicted 30 ms: wait 1/2
  assert(name == "S4T3", name)
  assert(reason:find("waiting %(1/2%)"), reason)
  name, reason = run_group(p, s, "S4T3", 6)
  assert(name == "S1T3", reason)             -- second group: step up
  assert(reason:find("S1T3 predicted 30.0 ms <= 32.0 ms, step up"), reason)
  for _ = 1, 4 do
    name, reason = run_group(p, s, name, 6)  -- S1T3 in band; never tries raw
    assert(name == "S1T3", reason)
  end
  -- A group in the band resets the wait.
  p = policy.closed_loop{ target_fps = 31.25 }
  s = stats{ current = "S4T3" }
  assert(run_group(p, s, "S4T3", 6) == "S4T3")
  local in_band = {}
  for i = 1, 6 do in_band[i] = { noise = 1.5 } end  -- 30 ms: in the band
  assert(run_group(p, s, "S4T3", 6, in_band) == "S4T3")
  assert(run_group(p, s, "S4T3", 6) == "S4T3", "wait restarted")
  assert(run_group(p, s, "S4T3", 6) == "S1T3")

  -- Does not step up when the better variant's prediction does not fit.
  p = policy.closed_loop{ target_fps = 1000 / 27 }      -- 27 ms: S4T2 25 fits, S1T3 30 does not
  s = stats{ current = "S4T2" }
  for _ = 1, 6 do
    name, reason = run_group(p, s, "S4T2", 6)
    assert(name == "S4T2", reason)
  end
end

-- Render-bound (device="cpu"): rendering, the same for every variant, is the slowest stage;
-- stepping down would give up quality for nothing, so closed_loop keeps it and says why.
do
  local p = policy.closed_loop{ target_fps = 20 }        -- 50 ms
  local s = stats{ current = "raw" }
  local slow_render = {}
  for i = 1, 6 do slow_render[i] = { fixed_ms = 100, ms_per_byte = 1e-6 } end  -- read 0.4 ms
  for _ = 1, 5 do
    local name, reason = run_group(p, s, "raw", 6, slow_render)
    assert(name == "raw", "render-bound closed_loop stepped down to " .. name .. ": " .. reason)
    assert(reason:find("render-bound", 1, true) and reason:find("keep raw", 1, true), reason)
  end
  -- the same plant read-bound (read 40 ms of 50): stepping down pays and happens
  p = policy.closed_loop{ target_fps = 40 }
  s = stats{ current = "raw" }
  local name, reason = run_group(p, s, "raw", 6)
  assert(name == "S1T3" and reason:find("step down to S1T3 (predicted 30.0 ms)", 1, true), reason)
end

-- Noise of +-5 % around the target never makes it switch.
do
  local target_ms = 30                    -- S1T3 runs at 30 ms
  local p = policy.closed_loop{ target_fps = 1000 / target_ms }
  local s = stats{ current = "S1T3" }
  local seed = 12345
  local function uniform()                -- deterministic LCG in [0, 1)
    seed = (seed * 1103515245 + 12345) % 2147483648
    return seed / 2147483648
  end
  local switches = 0
  local name = "S1T3"
  for _ = 1, 40 do
    local noise = {}
    for i = 1, 6 do noise[i] = { noise = 1 + 0.1 * (uniform() - 0.5) } end
    local next_name = run_group(p, s, name, 6, noise)
    if next_name ~= name then switches = switches + 1 end
    name = next_name
  end
  assert(switches == 0, "switched " .. switches .. " times under +-5% noise")
end

-- A slow up-step that turned out too slow is not retried while remembered.
do
  local p = policy.closed_loop{ target_fps = 1000 / 32 }
  local s = stats{ current = "S1T3" }
  -- S1T3 suddenly measures 40 ms: step down.
  local slow = {}
  for i = 1, 6 do slow[i] = { fixed_ms = 20 } end
  local name = run_group(p, s, "S1T3", 6, slow)
  assert(name == "S4T2", name)
  -- S4T2 at 25 ms < 28.8: S1T3 predicted 30 but remembered 40 -> stays.
  for _ = 1, 4 do
    name = run_group(p, s, name, 6)
    assert(name == "S4T2", name)
  end
end

-- Capture: deterministic, never below min_psnr or the user's choice.
do
  local frames = {}
  for t = 1, 6 do frames[t] = frame(t, "S1T3", { ms_per_byte = 1e-3 }) end  -- very slow
  for _, make in ipairs({ policy.open_loop, policy.closed_loop }) do
    local p = make{ target_fps = 100 }
    local name, reason = p(stats{ capture = true, frames = frames, current = "S1T3", min_psnr = 33 })
    assert(name == "S4T2", name)           -- fastest with PSNR >= 33
    assert(reason:find("capture"), reason)
    name = p(stats{ capture = true, frames = frames, current = "S1T3" })
    assert(name == "raw", name)            -- no floor: best quality
    p = make{ target_fps = 100, variant = "S1T3" }
    name = p(stats{ capture = true, frames = frames, current = "S1T3" })
    assert(name == "S1T3", name)           -- user's choice is the floor
    name = p(stats{ capture = true, frames = frames, current = "S1T3", min_psnr = 50 })
    assert(name == "raw", name)            -- only raw reaches 50 dB
  end
  -- min_psnr outside capture: closed loop never steps below it.
  local p = policy.closed_loop{ target_fps = 100 }
  local s = stats{ current = "S1T3", min_psnr = 37 }
  for _ = 1, 4 do
    local name = run_group(p, s, "S1T3", 6)
    assert(name == "S1T3", name)
  end
  -- a current variant below the floor is lifted at once.
  s = stats{ current = "S4T3", min_psnr = 33 }
  assert(run_group(p, s, "S4T3", 6) == "S4T2")
end

-- Simulated closed loop: plant frame time = a * bytes + b with +-5 % noise; a feasible target
-- (one variant within 10 % below it) is reached within 3 groups and held.
do
  local seed = 99
  local function uniform()
    seed = (seed * 1103515245 + 12345) % 2147483648
    return seed / 2147483648
  end
  local function plant_group(s, name, n)
    for i = 1, n do
      local v = by_name(name)
      local read = 1e-4 * v.bytes_per_timestep
      s.frames[#s.frames + 1] = { t = s.t + i - 1, variant = name, read_ms = read, unzip_ms = 0,
        upload_ms = 0, decode_ms = 0, setup_ms = 0, render_ms = 10,
        frame_ms = (read + 10) * (1 + 0.1 * (uniform() - 0.5)),
        bytes = v.bytes_per_timestep, payload_bytes = v.payload_bytes_per_timestep }
    end
    while #s.frames > 16 do table.remove(s.frames, 1) end
    s.t, s.group, s.current = s.t + n, s.group + 1, name
  end
  for _, case in ipairs({ { target = 32, start = "raw", want = "S1T3" },
                          { target = 27, start = "raw", want = "S4T2" },
                          { target = 22, start = "S1T3", want = "S4T3" },
                          { target = 32, start = "S4T2", want = "S1T3" },
                          { target = 52, start = "S4T3", want = "raw" } }) do
    local p = policy.closed_loop{ target_fps = 1000 / case.target }
    local s = stats{}
    local name = p(s)
    if case.start ~= name then s.current = case.start; name = case.start end
    local used = {}
    for group = 1, 12 do
      plant_group(s, name, 6)
      name = p(s)
      used[group] = name
    end
    for group = 4, 12 do
      assert(used[group] == case.want, string.format("target %d ms from %s: group %d uses %s, want %s",
             case.target, case.start, group, used[group], case.want))
    end
  end
end

-- ---- get ----
do
  assert(policy.get("fixed", { variant = "S4T2" })(stats{}) == "S4T2")
  assert(policy.get("open_loop", { target_fps = 40 })(stats{ frames = { frame(1, "S4T3") } }) == "S4T3")
  assert(type(policy.get("closed_loop", { target_fps = 25 })) == "function")
  local f = function() return "raw" end
  assert(policy.get(f) == f)
  expect_error("unknown policy 'fastest'", policy.get, "fastest")
  expect_error("policy name or function expected", policy.get, 42)
  expect_error("hysteresis", policy.closed_loop, { hysteresis = 2 })
end

print("test_policy: ok")
