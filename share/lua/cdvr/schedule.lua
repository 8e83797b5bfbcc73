-- cdvr.schedule: encode-time parameter schedules for cdvr.encode(q, {schedule=...}) (DESIGN.md
-- §7). A schedule is a function schedule(t [, variant]) -> params called with t = the first
-- timestep of a chunk group (1-based); params is a table of the variant's codec parameters
-- (for PVTC {S=, T=, pack=}, for zfp {rate=}); the encoder packs the group with them. nil keeps
-- the variant's own parameters.
--
--   schedule.fixed(params)
--   schedule.from_changes(changes, {fast={S=1,T=2}, slow={S=4,T=3}, quantile=0.5, codec="pvtc"})
--       -> schedule, info
--   schedule.change_driven(volume, opts)  -> schedule, info
--       changes[t] = cdvr.compare(v:frame(t), v:frame(t+1)).mse, then from_changes.
--
-- from_changes spends quality where the series changes fastest: changes[t] is the change
-- from timestep t to t+1 (n timesteps -> n-1 values). The threshold is the `quantile` of all
-- changes (linear interpolation between order statistics). The group starting at t covers up
-- to W timesteps, the longer chunk of `fast` and `slow` for the codec (`codec`, default pvtc:
-- cdvr.codec_chunk tells; PVTC with pack="time" holds T timesteps per chunk); it gets `fast`
-- (the better quality) when any change inside that window, changes[t .. t+W-2], exceeds the
-- threshold, and `slow` otherwise. A last group with no change inside it looks at the change
-- that leads into it. info = {threshold=, changes=, timesteps=, window=}.
local options = require "cdvr.options"
local schedule = {}

-- A copy of a parameter table (numbers that are integers become integers). The encoder checks
-- the values against the codec.
local function check_params(params, what)
  if type(params) ~= "table" then
    error(string.format("%s: table of codec parameters expected, got %s", what, type(params)), 3)
  end
  local out = {}
  for k, v in pairs(params) do
    if type(k) ~= "string" then
      error(string.format("%s: parameter names must be strings, got a %s key", what, type(k)), 3)
    end
    out[k] = math.type(v) == "float" and math.tointeger(v) or v
  end
  return out
end

-- Timesteps one chunk of codec holds with params (the encoder's group length).
local function chunk_length(codec, params, what)
  local cdvr = require "cdvr"
  local ok, chunk = pcall(cdvr.codec_chunk, codec, params)
  if not ok then
    error(string.format("%s: %s", what, tostring(chunk):gsub("^cdvr%.codec_chunk: ", "")), 3)
  end
  return chunk.timesteps
end

local function copy(params)
  local out = {}
  for k, v in pairs(params) do out[k] = v end
  return out
end

local function check_t(t, n)
  local ti = math.tointeger(t)
  if ti == nil or ti < 1 or (n ~= nil and ti > n) then
    error(string.format("bad argument #1 to 'schedule' (timestep in 1..%s expected, got %s)",
                        n and tostring(n) or "inf", tostring(t)), 3)
  end
  return ti
end

function schedule.fixed(params)
  local p = check_params(params, "schedule.fixed")
  return function(t)
    check_t(t)
    return copy(p)
  end
end

-- Quantile q of values (type 7: linear between order statistics).
function schedule.quantile(values, q)
  if type(values) ~= "table" then
    error(string.format("bad argument #1 to 'quantile' (table of numbers expected, got %s)", type(values)), 2)
  end
  for i = 1, #values do
    if type(values[i]) ~= "number" or values[i] ~= values[i] then
      error(string.format("bad argument #1 to 'quantile' (values[%d] must be a number, got %s)", i,
                          tostring(values[i])), 2)
    end
  end
  if type(q) ~= "number" or not (q >= 0 and q <= 1) then
    error(string.format("bad argument #2 to 'quantile' (number in [0, 1] expected, got %s)", tostring(q)), 2)
  end
  local n = #values
  if n == 0 then return nil end
  local sorted = table.move(values, 1, n, 1, {})
  table.sort(sorted)
  local h = (n - 1) * q + 1
  local lo = math.floor(h)
  if lo >= n then return sorted[n] end
  return sorted[lo] + (h - lo) * (sorted[lo + 1] - sorted[lo])
end

local function check_changes(changes)
  if type(changes) ~= "table" then
    error(string.format("bad argument #1 to 'from_changes' (table expected, got %s)", type(changes)), 3)
  end
  local out = {}
  for i = 1, #changes do
    local c = changes[i]
    if type(c) ~= "number" or c ~= c or c < 0 then
      error(string.format("from_changes: changes[%d] must be a non-negative number, got %s", i, tostring(c)), 3)
    end
    out[i] = c
  end
  return out
end

local function check_opts(opts, fname)
  if opts ~= nil and type(opts) ~= "table" then
    error(string.format("bad argument #2 to '%s' (table expected, got %s)", fname, type(opts)), 3)
  end
  return opts or {}
end

function schedule.from_changes(changes, opts)
  changes = check_changes(changes)
  opts = check_opts(opts, "from_changes")
  options.check(opts, "cdvr.schedule.from_changes", { "fast", "slow", "quantile", "codec" })
  local fast = check_params(opts.fast or { S = 1, T = 2 }, "from_changes: fast")
  local slow = check_params(opts.slow or { S = 4, T = 3 }, "from_changes: slow")
  local q = opts.quantile or 0.5
  if type(q) ~= "number" or not (q >= 0 and q <= 1) then
    error(string.format("from_changes: quantile must be in [0, 1], got %s", tostring(q)), 2)
  end
  local n = #changes + 1
  local threshold = schedule.quantile(changes, q)
  local codec = opts.codec or "pvtc"
  local window = math.max(chunk_length(codec, fast, "from_changes: fast"),
                          chunk_length(codec, slow, "from_changes: slow"))
  local function busy(t)
    local last = math.min(t + window - 2, n - 1)
    local first = last < t and t - 1 or t    -- a last group: the change leading into it
    for i = math.max(first, 1), last do
      if changes[i] > threshold then return true end
    end
    return false
  end
  local info = { threshold = threshold, changes = changes, timesteps = n, window = window }
  return function(t)
    t = check_t(t, n)
    return copy(busy(t) and fast or slow)
  end, info
end

function schedule.change_driven(volume, opts)
  options.check(opts, "cdvr.schedule.change_driven", { "fast", "slow", "quantile", "codec" })
  local cdvr = require "cdvr"
  if type(cdvr.compare) ~= "function" then
    error("change_driven: cdvr.compare is not available in this build", 2)
  end
  local ok, n = pcall(function() return volume:timesteps() end)
  if not ok or math.tointeger(n) == nil then
    error(string.format("bad argument #1 to 'change_driven' (volume expected, got %s)", type(volume)), 2)
  end
  opts = check_opts(opts, "change_driven")
  local changes = {}
  local frame = volume:frame(1)
  for t = 1, n - 1 do
    local next_frame = volume:frame(t + 1)
    changes[t] = cdvr.compare(frame, next_frame).mse
    frame = next_frame
  end
  return schedule.from_changes(changes, opts)
end

return schedule
