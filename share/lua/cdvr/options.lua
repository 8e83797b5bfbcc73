-- cdvr.options: unknown-option checks for the Lua modules, worded as the C side words them
-- (lcdvr_checkoptions in lua/bind/lcdvr.c): "what: unknown option 'devcie' (did you mean
-- 'device'?)". A suggestion is the closest known name within edit distance 2 (1 for names of
-- up to 3 letters).
--   options.check(tbl, what, keys [, level])        keys: list of names; raises at `level` as
--                                                    error() counts it from the calling function (2)
--   options.check_array(tbl, what, keys [, level])  also allows the array part 1..#tbl
local options = {}

local function distance(a, b)
  if #a > 63 or #b > 63 then return math.huge end
  local row = {}
  for j = 0, #b do row[j] = j end
  for i = 1, #a do
    local diag = row[0]
    row[0] = i
    for j = 1, #b do
      local up = row[j]
      local best = diag + (a:byte(i) ~= b:byte(j) and 1 or 0)
      best = math.min(best, up + 1, row[j - 1] + 1)
      row[j] = best
      diag = up
    end
  end
  return row[#b]
end

local function check(tbl, what, keys, level, array)
  if type(tbl) ~= "table" then return end
  local n = array and #tbl or 0
  local known = {}
  for _, k in ipairs(keys) do known[k] = true end
  for k in pairs(tbl) do
    local index = math.type(k) == "integer" and k >= 1 and k <= n
    if not index then
      if type(k) ~= "string" then
        error(string.format("%s: option keys must be names, got a %s key", what, type(k)), level)
      end
      if not known[k] then
        local best, best_d = nil, 3
        for _, name in ipairs(keys) do
          local d = distance(k, name)
          if d < best_d then best, best_d = name, d end
        end
        if best and best_d <= (#k > 3 and 2 or 1) then
          error(string.format("%s: unknown option '%s' (did you mean '%s'?)", what, k, best), level)
        end
        error(string.format("%s: unknown option '%s'", what, k), level)
      end
    end
  end
end

function options.check(tbl, what, keys, level)
  check(tbl, what, keys, (level or 2) + 2, false)
end

function options.check_array(tbl, what, keys, level)
  check(tbl, what, keys, (level or 2) + 2, true)
end

return options
