-- cdvr.policy: rate-control policies for cdvr.player (DESIGN.md §7).
--
-- The player calls policy(stats) at each group boundary (multiples of the lcm of the
-- variants' T) and reads the next group from the variant it returns:
--
--   policy(stats) -> variant_name [, reason [, lod_error]]
--     reason: one line, shown in the report; lod_error (only when stats.lod_error is given,
--     i.e. the player renders through the brick cache): the cache's level of detail for the
--     group, in pixels (nil: unchanged)
--
--   stats = {
--     target_fps = number or nil,
--     t = next timestep to read (1-based), group = group index (1-based),
--     current = name of the variant used for the last group (nil at the start),
--     best = name of the store's best-quality variant (cdvr_store_best_variant: the default
--            variant of the player and the window; optional, then the order below decides),
--     capture = true when frames are being written (then never choose below the user's
--               quality),
--     min_psnr = number or nil (quality floor the user set),
--     pipelined = true when the player overlaps stages (optional; default false),
--     frames = { last rows, oldest first, at most 16: {t=, variant=, read_ms=, unzip_ms=, grid_ms=,
--                upload_ms=, decode_ms=, setup_ms=, render_ms=, frame_ms=, bytes= (stored
--                bytes read for this frame's chunk share), payload_bytes=} },
--     variants = { {name=, codec=, S=, T=, pack=, stage2=, bytes_per_timestep= (stored),
--                   payload_bytes_per_timestep=, psnr=, group=T or 1}, ... },
--     -- the player through the brick cache (cache=true) only:
--     lod_error = the cache's lod_error now (frames rows carry theirs: frames[i].lod_error),
--     lod_base = the lod_error the user asked for, levels = the store's resolution levels
--   }                                              -- psnr: encode-time PSNR
--
-- Orders: by quality, psnr descending (a raw variant, or psnr = inf, is best; a variant
-- without psnr ranks below every measured one), ties broken by more stored bytes; by speed,
-- stored bytes per timestep ascending.
--
-- Quality floor: stats.min_psnr is honoured in every mode (playback runs slower rather than
-- dropping below it; if no variant reaches it, the best one is used). With stats.capture the
-- floor is also the PSNR of the user's choice (opts.variant) and the choice is deterministic,
-- independent of timings, so captured movies are repeatable: the fastest variant meeting the
-- floor, or the best-quality variant when there is no floor.
--
-- Timing model (open_loop, and closed_loop's step-up prediction), from the recent frames:
--   read   = bytes_per_timestep / (median of bytes / read_ms)
--   unzip  = payload_bytes_per_timestep / (median of payload_bytes / unzip_ms), only for a
--            variant with stage 2 that actually shrank its chunks; the median over the frames
--            of variants with the same stage 2 (lzo, lz4, zstd, auto unpack at very different
--            rates) when policy.measure knows the variants and some were measured, else over
--            all frames
--   upload = payload_bytes_per_timestep / (median of payload_bytes / upload_ms)
--   decode = median decode_ms of that variant's frames (every variant outputs one timestep
--            per frame), else of all frames
--   grid   = median grid_ms over all frames (the skip grids made from the range tables, on
--            the unzip worker; 0 for rows without it)
--   render = median render_ms of that variant's frames, else of all frames (a codec that
--            fetches every sample from its payload, hvq, renders many times slower than a
--            dense volume: the render depends on the variant)
--   setup  = median over all frames (it does not depend on the variant)
-- (policy.stages(v, m) gives these per-stage predictions, policy.predict(v, m) their total.)
-- Serial player: the sum. Pipelined player (cdvr/player.h: reader thread, unzip thread, and
-- the device thread doing upload..render): max(read, unzip+grid, upload+decode+setup+render).
-- A stage never measured yet counts as 0 ms (the next group measures it).
--
--   policy.fixed([name])
--   policy.open_loop{target_fps=, margin=0.9, pipelined=, variant=}
--   policy.closed_loop{target_fps=, hysteresis=0.1, window=, up_after=2, memory=8, variant=}
--     Feedback on the median frame_ms of the current variant's last `window` frames (default
--     the group length, at least 3, at most 16). Above target*(1+h): step down to the
--     best-quality variant with fewer stored bytes whose predicted time (measured median times
--     the timing model's ratio) saves at least the fraction h; when none does (the slowest
--     stage, e.g. rendering on device="cpu", is the same for every variant) it keeps the
--     quality and says so; without stage timings, one step down. Below target*(1-h): step up to the best
--     variant whose predicted time (measured median times the timing model's ratio, or the
--     stored-bytes ratio without stage timings; never less than what that variant measured
--     in the last `memory` groups) fits the target, once that has held for `up_after`
--     consecutive groups. Otherwise stay. It starts at opts.variant or the best quality.
--     Level of detail (stats.lod_error given and stats.levels > 1; opts lod=false turns it
--     off): lod_error is a knob before the variants. Over target it first raises lod_error
--     (x2, 0 -> 1) up to lod_max (default max(lod_base, 1) * 2^(levels-1), each doubling
--     coarsening by about one level) with the variant kept, and steps the variant down only at
--     lod_max; with headroom it first steps the variant up (as above), and when no better
--     variant is to be had it lowers lod_error (/2, to lod_base at the bottom) after up_after
--     groups, unless that finer lod_error measured over target in the last `memory` groups.
--     The median is over the frames of the current variant at the current lod_error.
--   policy.get(name_or_fn [, opts])
local options = require "cdvr.options"
local policy = {}

local INF = math.huge

-- ---- small helpers ------------------------------------------------------------------------
local function median(values)
  local n = #values
  if n == 0 then return nil end
  local sorted = table.move(values, 1, n, 1, {})
  table.sort(sorted)
  if n % 2 == 1 then return sorted[(n + 1) // 2] end
  return (sorted[n // 2] + sorted[n // 2 + 1]) / 2
end

local function positive(x) return type(x) == "number" and x > 0 and x < INF end

-- The quality order of cdvr_store_best_variant (cdvr/store.h), whose pick the player and the
-- window pass as stats.best: a raw variant is lossless, else the recorded psnr (inf when
-- lossless), a variant without one below every measured one.
local function quality(v)
  if v.codec == "raw" then return INF end
  if v.psnr ~= nil then return v.psnr end
  return -INF
end

local function stored_bytes(v) return v.bytes_per_timestep end
local function payload_bytes(v) return v.payload_bytes_per_timestep or v.bytes_per_timestep end

local function better(a, b)
  local qa, qb = quality(a), quality(b)
  if qa ~= qb then return qa > qb end
  if stored_bytes(a) ~= stored_bytes(b) then return stored_bytes(a) > stored_bytes(b) end
  return a.name < b.name
end

local function faster(a, b)
  if stored_bytes(a) ~= stored_bytes(b) then return stored_bytes(a) < stored_bytes(b) end
  if payload_bytes(a) ~= payload_bytes(b) then return payload_bytes(a) < payload_bytes(b) end
  return better(a, b)
end

local function fmt_ms(ms) return string.format("%.1f ms", ms) end

local function fmt_psnr(v)
  local q = quality(v)
  if q == INF then return "lossless" end
  if q == -INF then return "PSNR unknown" end
  return string.format("%.1f dB", q)
end

-- Checks the parts of stats every policy needs; returns variants sorted by quality (best
-- first) and a name -> variant map.
local function check_stats(stats, who)
  if type(stats) ~= "table" then
    error(string.format("%s: stats table expected, got %s", who, type(stats)), 3)
  end
  local variants = stats.variants
  if type(variants) ~= "table" or #variants == 0 then
    error(string.format("%s: stats.variants is empty", who), 3)
  end
  local by_quality, by_name = {}, {}
  for i, v in ipairs(variants) do
    if type(v) ~= "table" or type(v.name) ~= "string" then
      error(string.format("%s: stats.variants[%d].name missing", who, i), 3)
    end
    if type(v.bytes_per_timestep) ~= "number" then
      error(string.format("%s: stats.variants[%d] (%s): bytes_per_timestep missing", who, i, v.name), 3)
    end
    if v.psnr ~= nil and (type(v.psnr) ~= "number" or v.psnr ~= v.psnr) then
      error(string.format("%s: stats.variants[%d] (%s): psnr must be a number", who, i, v.name), 3)
    end
    by_quality[i] = v
    by_name[v.name] = v
  end
  local frames = stats.frames
  if frames ~= nil and type(frames) ~= "table" then
    error(string.format("%s: stats.frames must be a table, got %s", who, type(frames)), 3)
  end
  for i, f in ipairs(frames or {}) do
    if type(f) ~= "table" then
      error(string.format("%s: stats.frames[%d] must be a table, got %s", who, i, type(f)), 3)
    end
  end
  local floor = stats.min_psnr
  if floor ~= nil and (type(floor) ~= "number" or floor ~= floor) then
    error(string.format("%s: stats.min_psnr must be a number (dB), got %s", who, tostring(floor)), 3)
  end
  if stats.current ~= nil and type(stats.current) ~= "string" then
    error(string.format("%s: stats.current must be a variant name, got %s", who, type(stats.current)), 3)
  end
  table.sort(by_quality, better)
  -- the store's own best (stats.best, cdvr_store_best_variant) heads the quality order: the
  -- same default as the player's and the window's, whatever the ties above decided
  local best = stats.best ~= nil and by_name[stats.best]
  if stats.best ~= nil and not best then
    error(string.format("%s: stats.best (%s) is not a variant", who, tostring(stats.best)), 3)
  end
  for i = 2, best and #by_quality or 0 do
    if by_quality[i] == best then
      table.remove(by_quality, i)
      table.insert(by_quality, 1, best)
      break
    end
  end
  return by_quality, by_name
end

local function target_fps(opts, stats)
  local fps = opts.target_fps or stats.target_fps
  if fps ~= nil and not positive(fps) then
    error(string.format("policy: target_fps must be a positive number, got %s", tostring(fps)), 3)
  end
  return fps
end

-- The quality floor (dB, or nil) and a text naming where it comes from.
local function quality_floor(stats, opts, by_name)
  local floor, source = stats.min_psnr, "min_psnr"
  if floor ~= nil then source = string.format("min_psnr %.1f dB", floor) end
  if stats.capture and opts.variant then
    local chosen = by_name[opts.variant]
    if not chosen then
      error(string.format("policy: no variant named %s", tostring(opts.variant)), 3)
    end
    if floor == nil or quality(chosen) > floor then
      floor, source = quality(chosen), "the quality of " .. chosen.name
    end
  end
  return floor, source
end

-- Variants (quality order) that meet the floor; when none does, the best one alone.
local function allowed_variants(by_quality, floor)
  if floor == nil then return by_quality, true end
  local out = {}
  for _, v in ipairs(by_quality) do
    if quality(v) >= floor then out[#out + 1] = v end
  end
  if #out == 0 then return { by_quality[1] }, false end
  return out, true
end

local function contains(list, item)
  for _, v in ipairs(list) do
    if v == item then return true end
  end
  return false
end

local function fastest(list)
  local best = list[1]
  for i = 2, #list do
    if faster(list[i], best) then best = list[i] end
  end
  return best
end

-- Deterministic capture choice: see the module comment.
local function capture_choice(who, by_quality, floor, source)
  local allowed, met = allowed_variants(by_quality, floor)
  if floor == nil then
    return allowed[1].name, string.format("%s: capture, best quality %s (%s)", who,
                                         allowed[1].name, fmt_psnr(allowed[1]))
  end
  if not met then
    return allowed[1].name, string.format("%s: capture, no variant reaches %s; best is %s (%s)",
                                         who, source, allowed[1].name, fmt_psnr(allowed[1]))
  end
  local v = fastest(allowed)
  return v.name, string.format("%s: capture, %s is the fastest variant meeting %s", who, v.name, source)
end

-- ---- timing model -------------------------------------------------------------------------
local function rate_median(frames, amount_field, ms_field)
  local rates = {}
  for _, f in ipairs(frames) do
    if positive(f[amount_field]) and positive(f[ms_field]) then
      rates[#rates + 1] = f[amount_field] / f[ms_field]
    end
  end
  return median(rates)
end

local function field_median(frames, field, variant)
  local values = {}
  for _, f in ipairs(frames) do
    if type(f[field]) == "number" and f[field] >= 0 and (variant == nil or f.variant == variant) then
      values[#values + 1] = f[field]
    end
  end
  return median(values)
end

-- Unzip rate (payload bytes per ms) of the frames of variants with each stage 2, from the
-- variants list ({name=, stage2=}); stage 2 name -> rate.
local function unzip_rates(frames, variants)
  local stage2_of, by_stage2 = {}, {}
  for _, v in ipairs(variants) do
    if type(v) == "table" and type(v.name) == "string" and type(v.stage2) == "string" then
      stage2_of[v.name] = v.stage2
    end
  end
  for _, f in ipairs(frames) do
    local s2 = stage2_of[f.variant]
    if s2 then
      by_stage2[s2] = by_stage2[s2] or {}
      table.insert(by_stage2[s2], f)
    end
  end
  local rates = {}
  for s2, list in pairs(by_stage2) do rates[s2] = rate_median(list, "payload_bytes", "unzip_ms") end
  return rates
end

-- Bandwidths (bytes per ms) and variant-independent times measured on frames; nil if none.
-- variants (optional, stats.variants) gives unzip rates per stage 2.
function policy.measure(frames, variants)
  if type(frames) ~= "table" or #frames == 0 then return nil end
  if variants ~= nil and type(variants) ~= "table" then
    error(string.format("bad argument #2 to 'measure' (table of variants expected, got %s)", type(variants)), 2)
  end
  for i, f in ipairs(frames) do
    if type(f) ~= "table" then
      error(string.format("bad argument #1 to 'measure' (frames[%d] must be a table, got %s)", i, type(f)), 2)
    end
  end
  local m = {
    read = rate_median(frames, "bytes", "read_ms"),
    unzip = rate_median(frames, "payload_bytes", "unzip_ms"),
    upload = rate_median(frames, "payload_bytes", "upload_ms"),
    decode_all = field_median(frames, "decode_ms"),
    setup = field_median(frames, "setup_ms") or 0,
    grid = field_median(frames, "grid_ms") or 0,
    render = field_median(frames, "render_ms") or 0,
    frames = frames,
  }
  m.unzip_by_stage2 = variants and unzip_rates(frames, variants) or {}
  m.decode = {}
  m.render_of = {}
  return m
end

local function uses_stage2(v)
  return v.stage2 ~= nil and v.stage2 ~= false and v.stage2 ~= "none"
    and stored_bytes(v) < payload_bytes(v)
end

local function check_model_args(v, m, fname)
  if type(v) ~= "table" or type(v.bytes_per_timestep) ~= "number" then
    error(string.format("bad argument #1 to '%s' (variant {name=, bytes_per_timestep=, ...} expected, got %s)", fname,
                        type(v) == "table" and "a table without bytes_per_timestep" or type(v)), 3)
  end
  if type(m) ~= "table" or type(m.decode) ~= "table" then
    error(string.format("bad argument #2 to '%s' (a measurement from policy.measure expected, got %s)", fname,
                        type(m)), 3)
  end
end

-- Predicted time (ms) of each stage of variant v from measurement m.
function policy.stages(v, m)
  check_model_args(v, m, "stages")
  local function per(bytes, rate) return rate and bytes / rate or 0 end
  if m.decode[v.name] == nil then
    m.decode[v.name] = field_median(m.frames, "decode_ms", v.name) or m.decode_all or false
  end
  m.render_of = m.render_of or {}
  if m.render_of[v.name] == nil then
    m.render_of[v.name] = field_median(m.frames, "render_ms", v.name) or m.render
  end
  return {
    read = per(stored_bytes(v), m.read),
    unzip = uses_stage2(v) and per(payload_bytes(v), (m.unzip_by_stage2 or {})[v.stage2] or m.unzip)
      or 0,
    upload = per(payload_bytes(v), m.upload),
    decode = m.decode[v.name] or 0,
    grid = m.grid or 0,
    setup = m.setup,
    render = m.render_of[v.name],
  }
end

-- Predicted frame time (ms) of variant v from measurement m.
function policy.predict(v, m, pipelined)
  check_model_args(v, m, "predict")
  local st = policy.stages(v, m)
  local device = st.upload + st.decode + st.setup + st.render
  if pipelined then
    return math.max(st.read, st.unzip + st.grid, device)
  end
  return st.read + st.unzip + st.grid + device
end

-- ---- fixed --------------------------------------------------------------------------------
function policy.fixed(name)
  if name ~= nil and type(name) ~= "string" then
    error(string.format("bad argument #1 to 'fixed' (string expected, got %s)", type(name)), 2)
  end
  return function(stats)
    local by_quality, by_name = check_stats(stats, "fixed")
    if name == nil then
      return by_quality[1].name, "fixed: best quality"
    end
    if not by_name[name] then
      local names = {}
      for _, v in ipairs(by_quality) do names[#names + 1] = v.name end
      error(string.format("policy.fixed: no variant named %s (have: %s)", name,
                          table.concat(names, ", ")), 2)
    end
    return name, "fixed"
  end
end

-- ---- open loop ----------------------------------------------------------------------------
local function check_opts(opts, fname)
  if opts == nil then return {} end
  if type(opts) ~= "table" then
    error(string.format("bad argument #1 to '%s' (table expected, got %s)", fname, type(opts)), 3)
  end
  if opts.target_fps ~= nil and not positive(opts.target_fps) then
    error(string.format("%s: target_fps must be a positive number, got %s", fname, tostring(opts.target_fps)), 3)
  end
  if opts.variant ~= nil and type(opts.variant) ~= "string" then
    error(string.format("%s: variant must be a variant name, got %s", fname, type(opts.variant)), 3)
  end
  return opts
end

local function integer_at_least(x, min)
  return type(x) == "number" and math.tointeger(x) ~= nil and x >= min
end

-- What every adaptive policy does first: validate stats, apply the quality floor, answer
-- capture and no-target requests. Returns name, reason when that settles the choice, else
-- nil, {by_name=, allowed=, fps=, source=} for the policy's own rule.
local function settle_or_context(kind, stats, opts)
  local by_quality, by_name = check_stats(stats, kind)
  local floor, source = quality_floor(stats, opts, by_name)
  if stats.capture then return capture_choice(kind, by_quality, floor, source) end
  local allowed = allowed_variants(by_quality, floor)
  local fps = target_fps(opts, stats)
  if fps == nil then
    return allowed[1].name, kind .. ": no target, best quality " .. allowed[1].name
  end
  return nil, {by_name = by_name, allowed = allowed, fps = fps, source = source}
end

function policy.open_loop(opts)
  opts = check_opts(opts, "open_loop")
  options.check(opts, "cdvr.policy.open_loop", { "target_fps", "margin", "pipelined", "variant" })
  local margin = opts.margin or 0.9
  if not positive(margin) then
    error(string.format("open_loop: margin must be a positive number, got %s", tostring(margin)), 2)
  end
  return function(stats)
    local name, ctx = settle_or_context("open_loop", stats, opts)
    if name then return name, ctx end
    local allowed, fps = ctx.allowed, ctx.fps
    local m = policy.measure(stats.frames, stats.variants)
    if m == nil then
      return allowed[1].name, "open_loop: no measurements yet, best quality " .. allowed[1].name
    end
    local pipelined = stats.pipelined
    if pipelined == nil then pipelined = opts.pipelined end
    local budget = 1000 / fps * margin
    local quickest, quickest_ms
    for _, v in ipairs(allowed) do
      local ms = policy.predict(v, m, pipelined)
      if ms <= budget then
        return v.name, string.format("open_loop: %s predicted %s <= %s", v.name, fmt_ms(ms), fmt_ms(budget))
      end
      if quickest_ms == nil or ms < quickest_ms then quickest, quickest_ms = v, ms end
    end
    return quickest.name, string.format("open_loop: none fits %s, fastest %s predicted %s",
                                        fmt_ms(budget), quickest.name, fmt_ms(quickest_ms))
  end
end

-- ---- closed loop --------------------------------------------------------------------------
local function group_length(variants)
  local function gcd(a, b) while b ~= 0 do a, b = b, a % b end return a end
  local len = 1
  for _, v in ipairs(variants) do
    local g = math.tointeger(v.group or v.T or 1) or 1
    if g > 0 then len = len // gcd(len, g) * g end
  end
  return len
end

local function recent_frame_times(frames, name, window, lod)
  local times = {}
  if type(frames) ~= "table" then return times end
  for i = #frames, 1, -1 do
    local f = frames[i]
    if f.variant == name and positive(f.frame_ms) and (lod == nil or f.lod_error == lod) then
      times[#times + 1] = f.frame_ms
      if #times >= window then break end
    end
  end
  return times
end

-- The slowest stage of variant v under measurement m: name and predicted ms.
local STAGES = { "read", "unzip", "upload", "decode", "setup", "render" }
local function slowest_stage(v, m)
  local st = policy.stages(v, m)
  local name, ms = STAGES[1], st[STAGES[1]]
  for _, k in ipairs(STAGES) do
    if st[k] > ms then name, ms = k, st[k] end
  end
  return name, ms
end

-- The step down from cur when it measures `measured` ms, too slow: the best-quality allowed
-- variant with fewer stored bytes whose predicted time (measured times the timing model's
-- ratio) saves at least the hysteresis fraction h of the frame time. Without stage timings
-- (no model), the next faster variant. Returns the variant, or nil and why not: quality is
-- never given up for a gain the model does not predict (e.g. when rendering, which no
-- variant changes, is the slowest stage).
local function step_down(state, stats, allowed, cur, measured, pipelined)
  local m = policy.measure(stats.frames, stats.variants)
  local cur_model = m and policy.predict(cur, m, pipelined) or 0
  local best, best_ms
  for _, v in ipairs(allowed) do
    if stored_bytes(v) < stored_bytes(cur) then
      if cur_model <= 0 then return v end
      local predicted = measured * policy.predict(v, m, pipelined) / cur_model
      if predicted <= measured * (1 - state.hysteresis) then return v, predicted end
      if best == nil or predicted < best_ms then best, best_ms = v, predicted end
    end
  end
  if best == nil then return nil, "already the fastest allowed" end
  local stage, stage_ms = slowest_stage(cur, m)
  return nil, string.format("%s-bound (%s %s), no faster variant saves %d%% (%s predicted %s): keep %s",
                            stage, stage, fmt_ms(stage_ms), math.floor(state.hysteresis * 100 + 0.5),
                            best.name, fmt_ms(best_ms), cur.name)
end

-- Time of `up` predicted from cur's measured median: the timing model's ratio when stage
-- timings exist, else the stored-bytes ratio; never below what up measured recently.
local function predict_up(state, stats, up, cur, measured_ms, pipelined)
  local m = policy.measure(stats.frames, stats.variants)
  local cur_model = m and policy.predict(cur, m, pipelined) or 0
  local ratio
  if cur_model > 0 then
    ratio = policy.predict(up, m, pipelined) / cur_model
  else
    ratio = stored_bytes(cur) > 0 and stored_bytes(up) / stored_bytes(cur) or 1
  end
  local predicted = measured_ms * ratio
  local seen = state.memory[up.name]
  if seen and (stats.group or 0) - seen.group <= state.memory_groups then
    predicted = math.max(predicted, seen.ms)
  end
  return predicted
end

-- The best-quality allowed variant better than cur whose predicted time fits target, and its
-- prediction; when none fits, the cheapest better one and its prediction; nil when cur is best.
local function step_up(state, stats, allowed, cur, measured, pipelined, target)
  local cheapest, cheapest_ms
  for _, v in ipairs(allowed) do
    if quality(v) > quality(cur) then
      local ms = predict_up(state, stats, v, cur, measured, pipelined)
      if ms <= target then return v, ms end
      if cheapest == nil or faster(v, cheapest) then cheapest, cheapest_ms = v, ms end
    end
  end
  return cheapest, cheapest_ms
end

-- The level-of-detail knob (closed_loop's doc), or nil when the player does not render
-- through the brick cache or the store has one level.
local function lod_knob(state, stats)
  local lod, base, levels = stats.lod_error, stats.lod_base, stats.levels
  if not state.lod or lod == nil then return nil end
  if type(lod) ~= "number" or lod < 0 or lod ~= lod or type(base) ~= "number" or base < 0 or
     not integer_at_least(levels, 1) then
    error(string.format("closed_loop: stats.lod_error, lod_base (numbers >= 0) and levels " ..
                        "(integer >= 1) expected, got %s, %s, %s", tostring(lod), tostring(base),
                        tostring(levels)), 4)
  end
  if levels < 2 then return nil end
  local max = state.lod_max or math.max(base, 1) * 2 ^ (levels - 1)
  return { now = lod, base = base, max = math.max(max, base) }
end

local function fmt_lod(x) return string.format("%g", x) end

-- Over target: lod_error one step coarser, or nil at lod_max.
local function lod_raise(knob)
  if knob == nil or knob.now >= knob.max then return nil end
  return math.min(knob.now > 0 and knob.now * 2 or 1, knob.max)
end

-- With headroom: lod_error one step finer, or nil at lod_base.
local function lod_lower(knob)
  if knob == nil or knob.now <= knob.base then return nil end
  local finer = knob.now / 2
  if finer < knob.base or (knob.base == 0 and finer < 1) then finer = knob.base end
  return finer
end

-- Headroom and no better variant to step to: lower lod_error after up_after groups, unless
-- the finer value measured over target recently.
local function lod_refine(state, stats, knob, cur, what, target)
  local finer = lod_lower(knob)
  if finer == nil then return nil end
  local seen = state.memory[cur.name .. "@" .. fmt_lod(finer)]
  if seen and (stats.group or 0) - seen.group <= state.memory_groups and seen.ms > target then
    state.up_streak = 0
    return cur.name, string.format("%s, lod_error %s measured %s > %s, stay", what,
                                   fmt_lod(finer), fmt_ms(seen.ms), fmt_ms(target)), knob.now
  end
  state.up_streak = state.up_streak + 1
  if state.up_streak < state.up_after then
    return cur.name, string.format("%s, lod_error %s -> %s waiting (%d/%d)", what,
                                   fmt_lod(knob.now), fmt_lod(finer), state.up_streak,
                                   state.up_after), knob.now
  end
  state.up_streak = 0
  return cur.name, string.format("%s, headroom: lod_error %s -> %s", what, fmt_lod(knob.now),
                                 fmt_lod(finer)), finer
end

-- The variant (and lod_error when knob) for the next group: closed_loop's rule.
local function closed_loop_variant(state, stats, allowed, cur, target, h, knob)
  local times = recent_frame_times(stats.frames, cur.name, state.window or
                                   math.min(16, math.max(3, group_length(stats.variants))),
                                   knob and knob.now)
  local measured = median(times)
  if measured == nil then
    state.up_streak = 0
    return cur.name, string.format("closed_loop: %s, no frames measured yet", cur.name)
  end
  state.memory[cur.name] = { ms = measured, group = stats.group or 0 }
  local what = string.format("closed_loop: %s median %s", cur.name, fmt_ms(measured))
  if knob then
    state.memory[cur.name .. "@" .. fmt_lod(knob.now)] = state.memory[cur.name]
    what = what .. " at lod_error " .. fmt_lod(knob.now)
  end
  local pipelined = stats.pipelined
  if pipelined == nil then pipelined = state.pipelined end
  if measured > target * (1 + h) then
    state.up_streak = 0
    local coarser = lod_raise(knob)
    if coarser then
      return cur.name, string.format("%s > %s, lod_error %s -> %s", what, fmt_ms(target * (1 + h)),
                                     fmt_lod(knob.now), fmt_lod(coarser)), coarser
    end
    local down, detail = step_down(state, stats, allowed, cur, measured, pipelined)
    if not down then
      return cur.name, string.format("%s > %s, %s", what, fmt_ms(target * (1 + h)), detail)
    end
    return down.name, string.format("%s > %s, step down to %s%s", what, fmt_ms(target * (1 + h)), down.name,
                                    detail and (" (predicted " .. fmt_ms(detail) .. ")") or "")
  end
  if measured >= target * (1 - h) then
    state.up_streak = 0
    return cur.name, string.format("%s within %s +-%d%%, stay", what, fmt_ms(target), math.floor(h * 100 + 0.5))
  end
  local up, predicted = step_up(state, stats, allowed, cur, measured, pipelined, target)
  if (not up or predicted > target) and lod_lower(knob) then
    return lod_refine(state, stats, knob, cur, what, target)
  end
  if not up then
    state.up_streak = 0
    return cur.name, string.format("%s < %s, already the best allowed", what, fmt_ms(target * (1 - h)))
  end
  if predicted > target then
    state.up_streak = 0
    return cur.name, string.format("%s, %s predicted %s > %s, stay", what, up.name, fmt_ms(predicted), fmt_ms(target))
  end
  state.up_streak = state.up_streak + 1
  if state.up_streak < state.up_after then
    return cur.name, string.format("%s, %s predicted %s fits, waiting (%d/%d)", what, up.name,
                                   fmt_ms(predicted), state.up_streak, state.up_after)
  end
  state.up_streak = 0
  return up.name, string.format("%s, %s predicted %s <= %s, step up", what, up.name,
                                fmt_ms(predicted), fmt_ms(target))
end

local function closed_loop_step(state, stats, allowed, cur, fps)
  local target = 1000 / fps
  local h = state.hysteresis
  local knob = lod_knob(state, stats)
  local name, why, lod = closed_loop_variant(state, stats, allowed, cur, target, h, knob)
  if knob == nil then return name, why end
  return name, why, lod or knob.now
end

function policy.closed_loop(opts)
  opts = check_opts(opts, "closed_loop")
  options.check(opts, "cdvr.policy.closed_loop", { "target_fps", "hysteresis", "window", "up_after", "memory",
                                                   "variant", "pipelined", "lod", "lod_max" })
  local state = {
    hysteresis = opts.hysteresis or 0.1,
    window = opts.window,
    up_after = opts.up_after or 2,
    memory_groups = opts.memory or 8,
    pipelined = opts.pipelined,
    up_streak = 0,
    memory = {},
    lod = opts.lod ~= false,
    lod_max = opts.lod_max,
  }
  if opts.lod ~= nil and type(opts.lod) ~= "boolean" then
    error(string.format("closed_loop: lod must be a boolean, got %s", type(opts.lod)), 2)
  end
  if opts.lod_max ~= nil and not (type(opts.lod_max) == "number" and opts.lod_max >= 0 and
                                  opts.lod_max < INF) then
    error(string.format("closed_loop: lod_max must be a number >= 0, got %s", tostring(opts.lod_max)), 2)
  end
  if type(state.hysteresis) ~= "number" or state.hysteresis < 0 or state.hysteresis >= 1 then
    error(string.format("closed_loop: hysteresis must be in [0, 1), got %s", tostring(state.hysteresis)), 2)
  end
  if state.window ~= nil and not integer_at_least(state.window, 1) then
    error(string.format("closed_loop: window must be a positive integer, got %s", tostring(state.window)), 2)
  end
  if not integer_at_least(state.up_after, 1) then
    error(string.format("closed_loop: up_after must be a positive integer, got %s", tostring(state.up_after)), 2)
  end
  if not integer_at_least(state.memory_groups, 0) then
    error(string.format("closed_loop: memory must be an integer >= 0 (groups), got %s", tostring(state.memory_groups)), 2)
  end
  return function(stats)
    local name, ctx = settle_or_context("closed_loop", stats, opts)
    if name then return name, ctx end
    local by_name, allowed, fps, source = ctx.by_name, ctx.allowed, ctx.fps, ctx.source
    local cur = by_name[stats.current or false]
    if cur == nil then
      local start = by_name[opts.variant or false] or allowed[1]
      return start.name, "closed_loop: start at " .. start.name
    end
    if not contains(allowed, cur) then
      local lift = fastest(allowed)
      return lift.name, string.format("closed_loop: %s is below %s, use %s", cur.name, source, lift.name)
    end
    return closed_loop_step(state, stats, allowed, cur, fps)
  end
end

-- ---- lookup -------------------------------------------------------------------------------
local BUILDERS = {
  fixed = function(opts)
    options.check(opts, "cdvr.policy.fixed", { "variant" }, 3)
    return policy.fixed(opts.variant)
  end,
  open_loop = policy.open_loop,
  closed_loop = policy.closed_loop,
}

function policy.get(name_or_fn, opts)
  opts = check_opts(opts, "get")
  local kind = type(name_or_fn)
  local mt = getmetatable(name_or_fn)
  if kind == "function" or (kind == "table" and type(mt) == "table" and mt.__call) then
    return name_or_fn
  elseif kind == "string" and BUILDERS[name_or_fn] then
    return BUILDERS[name_or_fn](opts)
  elseif kind == "string" then
    error(string.format("policy.get: unknown policy '%s' (fixed, open_loop, closed_loop or a function)",
                        name_or_fn), 2)
  end
  error(string.format("bad argument #1 to 'get' (policy name or function expected, got %s)", kind), 2)
end

return policy
