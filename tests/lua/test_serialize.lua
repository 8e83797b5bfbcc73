-- cdvr.save_lua / cdvr.load_lua (share/lua/cdvr/serialize.lua).
local serialize = require "cdvr.serialize"
assert(cdvr.save_lua == serialize.save_lua and cdvr.load_lua == serialize.load_lua)

local dir = os.getenv("CDVR_BINARY_DIR") or "."
local file = dir .. "/test_serialize_out.lua"

local function expect_error(pattern, f, ...)
  local ok, err = pcall(f, ...)
  assert(not ok, "expected an error matching " .. pattern)
  assert(tostring(err):find(pattern, 1, true), "error '" .. tostring(err) .. "' does not match " .. pattern)
end

local function is_nan(x) return x ~= x end

-- Deep equality that tells integers from floats, -0.0 from 0.0 and compares NaN as equal.
local function same(a, b, where)
  where = where or "value"
  if type(a) ~= type(b) then error(where .. ": type " .. type(a) .. " vs " .. type(b)) end
  if type(a) == "number" then
    assert(math.type(a) == math.type(b), where .. ": " .. math.type(a) .. " vs " .. math.type(b))
    if is_nan(a) then assert(is_nan(b), where .. ": nan lost") return end
    assert(a == b, string.format("%s: %.17g vs %.17g", where, a, b))
    if a == 0 then assert(1 / a == 1 / b, where .. ": sign of zero") end
  elseif type(a) == "table" then
    for k, v in pairs(a) do same(v, b[k], where .. "." .. tostring(k)) end
    for k in pairs(b) do assert(a[k] ~= nil, where .. ": extra key " .. tostring(k)) end
  else
    assert(a == b, where .. ": " .. tostring(a) .. " vs " .. tostring(b))
  end
end

local function round_trip(value)
  assert(cdvr.save_lua(value, file))
  local back, err = cdvr.load_lua(file)
  assert(back ~= nil, err)
  same(value, back)
  return back
end

-- Scalars and special numbers.
for _, v in ipairs({ 0, 1, -1, 42, math.maxinteger, math.mininteger, 0.0, -0.0, 1.0, 0.1, 1 / 3,
                     -2.5e-310, 5e-324, 1.7976931348623157e308, 1e300, 123456789012345680.0,
                     math.pi, math.huge, -math.huge, "", "plain", "quote\" back\\slash",
                     "new\nline\r\0nul\1\255", true, false }) do
  round_trip(v)
  round_trip({ v })
end
do
  local back = round_trip({ nan = 0 / 0, inf = 1 / 0, ninf = -1 / 0 })
  assert(is_nan(back.nan) and back.inf == math.huge and back.ninf == -math.huge)
end

-- Nested tables, mixed keys, holes, keywords and odd string keys.
round_trip({
  dims = { 128, 128, 64 }, spacing = { 0.5, 0.5, 1.25 }, name = "vortex",
  tf = { { 0, 0, 0, 0, 0 }, { 60, 0.9, 0.6, 0.4, 0.05 }, { 255, 1, 1, 1, 0.8 } },
  nested = { a = { b = { c = { d = { 1, 2, { 3, { 4 } } } } } } },
  holes = { [1] = "a", [2] = "b", [4] = "d", [100] = "x", [-3] = "neg", [2.5] = "half" },
  ["end"] = "keyword", ["with space"] = 1, ["1abc"] = 2, [true] = "yes", [false] = "no",
  [1 / 0] = "inf key", empty = {},
})
-- A long array (not inline) and a shared, non-cyclic sub-table.
do
  local long = {}
  for i = 1, 100 do long[i] = i * 0.25 end
  local shared = { 1, 2, 3 }
  round_trip({ long = long, a = shared, b = shared })
end

-- Stable output: the same value gives the same bytes, whatever the insertion order.
do
  local a, b = {}, {}
  local keys = { "zeta", "alpha", "mu", "beta", "omega", "k10", "k9" }
  for i, k in ipairs(keys) do a[k] = i end
  for i = #keys, 1, -1 do b[keys[i]] = i end
  a[3.5], b[3.5] = "x", "x"
  assert(serialize.dump(a) == serialize.dump(b))
  local text = serialize.dump({ b = 1, a = 2, [2] = 3, [1] = 4 })
  assert(text == "return {\n  4,\n  3,\n  a = 2,\n  b = 1,\n}\n", text)
  assert(serialize.dump({ 1, 2.0, "x" }) == 'return {1, 2.0, "x"}\n')
  assert(serialize.dump(0.1) == "return 0.10000000000000001\n")
end

-- Objects are saved through __tosave or :totable().
do
  local Point = { __tosave = function(p) return { x = p.x, y = p.y, kind = "point" } end }
  local pt = setmetatable({ x = 1, y = 2, cache = function() end }, Point)
  local obj = { totable = function(self) return { kind = "obj", n = self.n } end, n = 7 }
  assert(cdvr.save_lua({ p = pt, o = obj }, file))
  local back = assert(cdvr.load_lua(file))
  same({ p = { x = 1, y = 2, kind = "point" }, o = { kind = "obj", n = 7 } }, back)
  local Self = {}
  Self.__tosave = function(s) return s end
  expect_error("cycle at value", serialize.dump, setmetatable({}, Self))
end

-- Misuse raises, naming the key path.
expect_error("cannot save a function at value.keys[2].eye", serialize.dump,
             { keys = { { eye = 1 }, { eye = print } } })
expect_error('cannot save a function at value["odd key"]', serialize.dump, { ["odd key"] = print })
do
  local cyc = { a = { b = {} } }
  cyc.a.b.back = cyc
  expect_error("cycle at value.a.b.back", serialize.dump, cyc)
  local keyed = {}
  keyed[{}] = 1
  expect_error("cannot save a table key in value", serialize.dump, keyed)
  expect_error("cannot save a thread at value.co", serialize.dump, { co = coroutine.create(print) })
  expect_error("nothing to save", cdvr.save_lua, nil, file)
  expect_error("string expected", cdvr.save_lua, {}, 42)
end

-- I/O failures return nil, message and leave no partial file.
do
  local bad = dir .. "/no_such_dir/out.lua"
  local ok, err = cdvr.save_lua({ 1 }, bad)
  assert(ok == nil and err:find("no_such_dir", 1, true), err)
  assert(io.open(bad) == nil)
  local value, lerr = cdvr.load_lua(dir .. "/missing_file.lua")
  assert(value == nil and lerr:find("missing_file", 1, true), lerr)
end

-- A failed save keeps the previous file intact.
do
  assert(cdvr.save_lua({ version = 1 }, file))
  expect_error("cannot save a function", cdvr.save_lua, { version = 2, f = print }, file)
  same({ version = 1 }, assert(cdvr.load_lua(file)))
end

-- load_lua: empty environment, text only, no calls, bounded running time.
local function write(text)
  local fh = assert(io.open(file, "wb"))
  fh:write(text)
  fh:close()
end
local function load_fails(text, pattern)
  write(text)
  local value, err = cdvr.load_lua(file)
  assert(value == nil, "expected load_lua to fail on: " .. text)
  assert(err:find(pattern, 1, true), err)
end
load_fails("return os.exit(3)", "attempt to index a nil value")
load_fails("return print", "no value")
load_fails("return ('x'):rep(1e9)", "calls a function")
load_fails("local function f() return 1 end return { f() }", "calls a function")
load_fails("while true do end", "runs too long")
load_fails("return {", "expected")
load_fails("", "no value")
load_fails(string.dump(function() return 1 end), "binary")
write("return {a = 1/0, b = -1/0, c = 0/0, d = 'x' .. 'y', e = -(3)}")
do
  local v = assert(cdvr.load_lua(file))
  assert(v.a == math.huge and v.b == -math.huge and is_nan(v.c) and v.d == "xy" and v.e == -3)
end
write("x = 1 return {x = x}")          -- globals go to the empty environment, not _G
assert(cdvr.load_lua(file).x == 1 and rawget(_G, "x") == nil)

os.remove(file)
print("test_serialize: ok")
