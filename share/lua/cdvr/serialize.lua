-- cdvr.serialize: save Lua values to plain Lua files (`return {...}`) and load them back.
--
--   serialize.save_lua(value, file) -> true | nil, message
--   serialize.load_lua(file)        -> value | nil, message
--
-- Output is stable and readable: keys sorted (the array part 1..n first, then numbers, then
-- strings, then booleans), integers as integers, floats with %.17g (so they read back to the
-- same double; a float with an integral value keeps a ".0"), inf/-inf/nan as 1/0, -1/0, 0/0,
-- strings with %q. Objects are saved through their __tosave metamethod or their :totable()
-- method. Functions, threads, userdata without either, table keys and cycles are misuse and
-- raise an error naming the key path (e.g. `value.keys[2].eye`). I/O failures return
-- nil, message. The file is written under a temporary name and renamed, so a failed save never
-- leaves a partial file under the final name.
--
-- load_lua runs the file as a text chunk (no precompiled chunks) in an empty environment. A
-- data file needs no function calls, so any call (string methods included) is refused, and the
-- chunk runs under an instruction budget proportional to its size and the callback memory
-- budget: a hostile or corrupt file can neither stall, nor exhaust memory, nor reach anything.
-- To run a file as code, use dofile (e.g. cdvr.tf(dofile(path))).
local serialize = {}

local KEYWORDS = {}
for word in ([[and break do else elseif end false for function goto if in local nil not or
               repeat return then true until while]]):gmatch("%a+") do
  KEYWORDS[word] = true
end

local function format_number(x)
  if math.type(x) == "integer" then
    return string.format("%q", x)   -- %q writes math.mininteger in a form that reads back
  elseif x ~= x then
    return "0/0"
  elseif x == math.huge then
    return "1/0"
  elseif x == -math.huge then
    return "-1/0"
  end
  local s = string.format("%.17g", x)
  if not s:find("[%.eEn]") then
    s = s .. ".0"                    -- keep it a float when read back
  end
  return s
end

local function key_path(path, key)
  if type(key) == "string" and key:match("^[%a_][%w_]*$") and not KEYWORDS[key] then
    return path .. "." .. key
  elseif type(key) == "string" then
    return path .. "[" .. string.format("%q", key) .. "]"
  end
  return path .. "[" .. tostring(key) .. "]"
end

local TYPE_ORDER = { number = 1, string = 2, boolean = 3 }

local function key_less(a, b)
  local ta, tb = type(a), type(b)
  if ta ~= tb then
    return TYPE_ORDER[ta] < TYPE_ORDER[tb]
  elseif ta == "boolean" then
    return (not a) and b
  end
  return a < b
end

-- Converts an object to the value that represents it in a file (or the value itself).
local function to_plain(value, path)
  local mt = getmetatable(value)
  if type(mt) == "table" and mt.__tosave ~= nil then
    return mt.__tosave(value), true
  end
  if type(value) == "table" or type(value) == "userdata" then
    local ok, totable = pcall(function() return value.totable end)
    if ok and type(totable) == "function" then
      return totable(value), true
    end
  end
  if type(value) == "userdata" then
    error(string.format("save_lua: cannot save %s at %s (no totable method)",
                        tostring(value), path), 0)
  end
  return value, false
end

local function sorted_keys(tbl, path)
  local array_len = 0
  while rawget(tbl, array_len + 1) ~= nil do
    array_len = array_len + 1
  end
  local others = {}
  for k in next, tbl do
    local kt = type(k)
    if not TYPE_ORDER[kt] then
      error(string.format("save_lua: cannot save a %s key in %s", kt, path), 0)
    end
    if not (math.type(k) == "integer" and k >= 1 and k <= array_len) then
      others[#others + 1] = k
    end
  end
  table.sort(others, key_less)
  return array_len, others
end

local write_value

local function write_key(out, key)
  if type(key) == "string" and key:match("^[%a_][%w_]*$") and not KEYWORDS[key] then
    out[#out + 1] = key
  elseif type(key) == "string" then
    out[#out + 1] = "[" .. string.format("%q", key) .. "]"
  elseif type(key) == "number" then
    out[#out + 1] = "[" .. format_number(key) .. "]"
  else
    out[#out + 1] = "[" .. tostring(key) .. "]"
  end
  out[#out + 1] = " = "
end

local function is_flat(tbl, array_len, others)
  if #others > 0 or array_len > 16 then
    return false
  end
  for i = 1, array_len do
    local t = type(tbl[i])
    if t == "table" or t == "userdata" then
      return false
    end
  end
  return true
end

local function write_table(out, tbl, path, indent, open)
  if open[tbl] then
    error(string.format("save_lua: cycle at %s (the table contains itself)", path), 0)
  end
  open[tbl] = true
  local array_len, others = sorted_keys(tbl, path)
  if is_flat(tbl, array_len, others) then
    out[#out + 1] = "{"
    for i = 1, array_len do
      out[#out + 1] = i > 1 and ", " or ""
      write_value(out, tbl[i], key_path(path, i), indent, open)
    end
    out[#out + 1] = "}"
  else
    local inner = indent .. "  "
    out[#out + 1] = "{\n"
    for i = 1, array_len do
      out[#out + 1] = inner
      write_value(out, tbl[i], key_path(path, i), inner, open)
      out[#out + 1] = ",\n"
    end
    for _, k in ipairs(others) do
      out[#out + 1] = inner
      write_key(out, k)
      write_value(out, tbl[k], key_path(path, k), inner, open)
      out[#out + 1] = ",\n"
    end
    out[#out + 1] = indent .. "}"
  end
  open[tbl] = nil
end

write_value = function(out, value, path, indent, open)
  local plain, converted = to_plain(value, path)
  if converted and open[value] then
    error(string.format("save_lua: cycle at %s", path), 0)
  end
  local t = type(plain)
  if t == "number" then
    out[#out + 1] = format_number(plain)
  elseif t == "string" then
    out[#out + 1] = string.format("%q", plain)
  elseif t == "boolean" or t == "nil" then
    out[#out + 1] = tostring(plain)
  elseif t == "table" then
    if converted then open[value] = true end
    write_table(out, plain, path, indent, open)
    if converted then open[value] = nil end
  else
    error(string.format("save_lua: cannot save a %s at %s", t, path), 0)
  end
end

-- Returns the text of a Lua file that evaluates to value (raises on what cannot be saved).
function serialize.dump(value)
  local out = { "return " }
  write_value(out, value, "value", "", {})
  out[#out + 1] = "\n"
  return table.concat(out)
end

function serialize.save_lua(value, file)
  if type(file) ~= "string" then
    error(string.format("bad argument #2 to 'save_lua' (string expected, got %s)", type(file)), 2)
  end
  if value == nil then
    error("bad argument #1 to 'save_lua' (nothing to save: value is nil)", 2)
  end
  local text = serialize.dump(value)
  local tmp = file .. ".tmp"
  local fh, open_err = io.open(tmp, "wb")
  if not fh then
    return nil, string.format("save_lua: cannot write %s: %s", file, open_err)
  end
  local ok, write_err = fh:write(text)
  local closed, close_err = fh:close()
  if not ok or not closed then
    os.remove(tmp)
    return nil, string.format("save_lua: cannot write %s: %s", file, write_err or close_err)
  end
  local renamed, rename_err = os.rename(tmp, file)
  if not renamed then
    os.remove(tmp)
    return nil, string.format("save_lua: cannot write %s: %s", file, rename_err)
  end
  return true
end

-- The data loader is cdvr's (lcdvr_load_data, lua/bind/lbudget.c): the same one cdvr.tf(path)
-- and cdvr.camera(path) use.
serialize.load_lua = require("cdvr").load_lua

return serialize
