-- closed_loop's level-of-detail knob (share/lua/cdvr/policy.lua) on synthetic stats sequences:
-- with stats.lod_error (the player renders through the brick cache) and a store of 3 levels,
-- over target it raises lod_error (0 -> 1 -> 2 -> 4 = lod_max) before it steps the variant
-- down; with headroom it steps the variant up first and then lowers lod_error (after up_after
-- groups), never back to a value that measured over target; without stats.lod_error, with
-- lod=false or when capturing, it returns no lod_error.
local policy = require "cdvr.policy"

local function variants()
  return {
    { name = "S4T3", codec = "pvtc", S = 4, T = 3, pack = "time", stage2 = "none",
      bytes_per_timestep = 100000, payload_bytes_per_timestep = 100000, psnr = 30, group = 3 },
    { name = "S1T3", codec = "pvtc", S = 1, T = 3, pack = "time", stage2 = "none",
      bytes_per_timestep = 200000, payload_bytes_per_timestep = 200000, psnr = 38, group = 3 },
    { name = "raw", codec = "raw", stage2 = "none",
      bytes_per_timestep = 400000, payload_bytes_per_timestep = 400000, group = 1 },
  }
end

-- The plant: read = bytes * ms_per_byte, render by lod_error (coarser bricks render faster).
local RENDER = { [0] = 40, [1] = 25, [2] = 15, [4] = 9 }
local function frame(t, name, lod, ms_per_byte)
  local bytes
  for _, v in ipairs(variants()) do if v.name == name then bytes = v.bytes_per_timestep end end
  local read, render = bytes * ms_per_byte, assert(RENDER[lod or 0], "lod " .. tostring(lod))
  return { t = t, variant = name, read_ms = read, unzip_ms = 0, upload_ms = 0, decode_ms = 0,
           setup_ms = 0, render_ms = render, frame_ms = read + render, bytes = bytes,
           payload_bytes = bytes, lod_error = lod }
end

local function stats(fields)
  local s = { variants = variants(), frames = {}, t = 1, group = 1, levels = 3, lod_base = 0,
              lod_error = 0 }
  for k, v in pairs(fields) do s[k] = v end
  return s
end

-- Plays a group of n frames of the current choice, then asks the policy; the choice (variant
-- and lod_error) applies to the next group. Returns name, reason, lod and the result count.
local function run_group(p, s, ms_per_byte, n)
  for i = 1, n or 6 do
    s.frames[#s.frames + 1] = frame(s.t + i - 1, s.current, s.lod_error, ms_per_byte)
  end
  while #s.frames > 16 do table.remove(s.frames, 1) end
  s.t, s.group = s.t + (n or 6), s.group + 1
  local results = table.pack(p(s))
  s.current = results[1]
  if results[3] ~= nil then s.lod_error = results[3] end
  return results[1], results[2], results[3], results.n
end

-- Over target, render-bound: lod_error rises before any variant changes; it stops where the
-- frame fits, and does not go back to a value that measured over target.
do
  local p = policy.closed_loop{ target_fps = 40 }          -- 25 ms
  local s = stats{ current = "raw" }
  local name, reason, lod = run_group(p, s, 1e-5)          -- raw at 0: 4 + 40 ms
  assert(name == "raw" and lod == 1 and reason:find("lod_error 0 -> 1", 1, true), reason)
  name, reason, lod = run_group(p, s, 1e-5)                -- at 1: 29 ms > 27.5
  assert(name == "raw" and lod == 2 and reason:find("lod_error 1 -> 2", 1, true), reason)
  for _ = 1, 6 do                                          -- at 2: 19 ms < 22.5, but 1 was slow
    name, reason, lod = run_group(p, s, 1e-5)
    assert(name == "raw" and lod == 2, reason)
    assert(reason:find("lod_error 1 measured 29.0 ms > 25.0 ms, stay", 1, true), reason)
  end
end

-- Over target even at lod_max (4 = 2^(levels-1)): then the variant steps down, lod kept.
do
  local p = policy.closed_loop{ target_fps = 1000 / 33 }
  local s = stats{ current = "raw" }
  local seen = {}
  local name, reason, lod
  for _ = 1, 3 do
    name, reason, lod = run_group(p, s, 1e-4)              -- raw reads 40 ms: never fits
    assert(name == "raw", "the variant is kept while lod_error can rise: " .. reason)
    seen[#seen + 1] = lod
  end
  assert(seen[1] == 1 and seen[2] == 2 and seen[3] == 4, "lod_error 1, 2, 4")
  name, reason, lod = run_group(p, s, 1e-4)                -- raw at 4: 49 ms
  assert(name == "S1T3" and lod == 4 and reason:find("step down to S1T3", 1, true), reason)
  -- lod_max caps the knob
  p = policy.closed_loop{ target_fps = 1000 / 33, lod_max = 2 }
  s = stats{ current = "raw" }
  run_group(p, s, 1e-4)
  run_group(p, s, 1e-4)
  name, reason, lod = run_group(p, s, 1e-4)
  assert(name == "S1T3" and lod == 2, "lod_max = 2, then the variant: " .. reason)
end

-- Headroom: the variant steps up first (LIFO: lod_error was raised first), then lod_error
-- comes down after up_after groups each, and stays in the band.
do
  local p = policy.closed_loop{ target_fps = 1000 / 30 }   -- 30 ms, band 27 .. 33
  local s = stats{ current = "S1T3", lod_error = 4 }
  local name, reason, lod = run_group(p, s, 1e-5)          -- S1T3 at 4: 2 + 9 ms
  assert(name == "S1T3" and lod == 4 and reason:find("raw predicted", 1, true), reason)
  name, reason, lod = run_group(p, s, 1e-5)
  assert(name == "raw" and lod == 4 and reason:find("step up", 1, true), reason)
  name, reason, lod = run_group(p, s, 1e-5)                -- raw at 4: 13 ms, raw is the best
  assert(name == "raw" and lod == 4 and reason:find("waiting (1/2)", 1, true), reason)
  name, reason, lod = run_group(p, s, 1e-5)
  assert(lod == 2 and reason:find("headroom: lod_error 4 -> 2", 1, true), reason)
  run_group(p, s, 1e-5)                                    -- raw at 2: 19 ms, waiting
  name, reason, lod = run_group(p, s, 1e-5)
  assert(lod == 1 and reason:find("lod_error 2 -> 1", 1, true), reason)
  for _ = 1, 4 do                                          -- raw at 1: 29 ms, in the band
    name, reason, lod = run_group(p, s, 1e-5)
    assert(name == "raw" and lod == 1 and reason:find("stay", 1, true), reason)
  end
end

-- lod_base is the floor: never finer than the user's lod_error.
do
  local p = policy.closed_loop{ target_fps = 1000 / 30, up_after = 1 }
  local s = stats{ current = "raw", lod_error = 2, lod_base = 2 }
  for _ = 1, 3 do
    local name, reason, lod = run_group(p, s, 1e-5)        -- raw at 2: 19 ms, headroom
    assert(name == "raw" and lod == 2, reason)
  end
end

-- No knob: without stats.lod_error, with one level, with lod=false, when capturing.
do
  local s = stats{ current = "raw" }
  s.lod_error, s.lod_base, s.levels = nil, nil, nil
  local _, _, _, n = run_group(policy.closed_loop{ target_fps = 40 }, s, 1e-5)
  assert(n == 2, "two results without the cache")
  _, _, _, n = run_group(policy.closed_loop{ target_fps = 40 }, stats{ current = "raw", levels = 1 },
                         1e-5)
  assert(n == 2, "two results with one level")
  local name, reason, lod
  name, reason, lod, n = run_group(policy.closed_loop{ target_fps = 40, lod = false },
                                   stats{ current = "raw" }, 1e-5)
  assert(n == 2 and lod == nil and name == "raw" and reason:find("render-bound", 1, true),
         "lod=false: render-bound over target, nothing to trade: " .. reason)
  _, _, _, n = run_group(policy.closed_loop{ target_fps = 40 }, stats{ current = "raw", capture = true },
                         1e-5)
  assert(n == 2, "capture: deterministic variant, lod_error untouched")
  local ok, err = pcall(policy.closed_loop, { target_fps = 40, lod_max = -1 })
  assert(not ok and err:find("lod_max"), err)
  ok, err = pcall(policy.closed_loop{ target_fps = 40 }, stats{ current = "raw", lod_error = "x" })
  assert(not ok and err:find("lod_error"), err)
end

print("test_policy_lod: ok")
