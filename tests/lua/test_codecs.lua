-- tests/lua/test_codecs.lua - cdvr.codecs() and cdvr.plugin.load: the registered codecs with
-- their ids, OpenCL modes, default variants and documented parameters; the plugins of the
-- build loaded at start-up (CDVR_PLUGIN_PATH unset); loading a plugin again; every broken
-- plugin of tests/plugins/ refused with an error naming the file and the reason; and
-- CDVR_PLUGIN_PATH at start-up (a warning line per failure, never fatal; empty: none).

local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises_all

local bin = os.getenv("CDVR_BINARY_DIR") or "."
local built = " " .. (os.getenv("CDVR_BUILT_PLUGINS") or "") .. " "
local have_zfp = built:find(" zfp ", 1, true) ~= nil
local have_rle = built:find(" example ", 1, true) ~= nil -- not with -DCDVR_WITH_PLUGINS=OFF
local exe = arg and arg[-1]

local function by_name()
  local t = {}
  for i, c in ipairs(cdvr.codecs()) do
    c.index = i
    t[c.name] = c
  end
  return t
end

-- the list
do
  local codecs = by_name()
  local raw, pvtc = codecs.raw, codecs.pvtc
  check(raw and raw.id == 0 and raw.index == 1 and raw.cl_mode == "decode" and raw.variant == "raw"
        and #raw.params == 0 and raw.plugin == nil, "raw entry")
  check(pvtc and pvtc.id == 1 and pvtc.index == 2 and pvtc.cl_mode == "decode"
        and pvtc.variant == "S4T3", "pvtc entry")
  local hvq = codecs.hvq
  check(hvq and hvq.id == 2 and hvq.index == 3 and hvq.cl_mode == "fetch" and hvq.variant == "hvq"
        and #hvq.params == 7 and hvq.plugin == nil, "hvq entry")
  local want = {S = "4", T = "3", pack = "time", encoder = "lsq"}
  check(pvtc and #pvtc.params == 4, "pvtc params")
  for _, p in ipairs(pvtc and pvtc.params or {}) do
    check(want[p.key] == p.default, "pvtc default of " .. p.key .. ": " .. tostring(p.default))
    check(type(p.description) == "string" and #p.description > 0, "pvtc " .. p.key .. " described")
  end
  for _, c in pairs(codecs) do
    check(type(c.description) == "string" and #c.description > 0, c.name .. " described")
    check(math.type(c.id) == "integer" and c.id >= 0 and c.id < 2^31, c.name .. " id")
    check(c.cl_mode == "decode" or c.cl_mode == "fetch" or c.cl_mode == "none", c.name .. " cl_mode")
  end
  -- the build's plugins came in at start-up
  local rle = codecs.rle
  check(not have_rle or rle and rle.cl_mode == "none" and rle.variant == "rle8" and rle.id == 0x524C4500
        and rle.params[1].key == "bits" and rle.params[1].default == "8"
        and rle.plugin and rle.plugin:find("cdvr_example.so", 1, true), "rle (example plugin) entry")
  if have_zfp then
    local zfp = codecs.zfp
    check(zfp and zfp.id == 0x7A667000 and zfp.cl_mode == "none" and zfp.variant == "zfp2"
          and zfp.params[1].key == "rate" and zfp.params[1].default == "2"
          and zfp.plugin and zfp.plugin:find("cdvr_zfp.so", 1, true), "zfp entry")
  end
end

-- loading
do
  local n = #cdvr.codecs()
  check(not have_rle or cdvr.plugin.load(bin .. "/plugins/cdvr_example.so") == "rle",
        "example loads again")
  check(#cdvr.codecs() == n, "loading again adds nothing")
  local dir = bin .. "/tests/plugins/"
  local bad = {
    {"bad_abi.so", "plugin built for ABI version 42"},
    {"bad_nosym.so", "no cdvr_plugin_v1 symbol"},
    {"bad_null_info.so", "cdvr_plugin_v1 returned NULL"},
    {"bad_null_codec.so", "returned no codec"},
    {"bad_clash_name.so", "codec 'pvtc' is already registered"},
    {"bad_clash_id.so", "already taken by codec 'pvtc'"},
    {"bad_no_decode.so", "the table has no decode"},
    {"bad_undefined.so", "undefined symbol"},
  }
  for _, b in ipairs(bad) do
    raises(function() cdvr.plugin.load(dir .. b[1]) end, {dir .. b[1], b[2]}, b[1])
  end
  raises(function() cdvr.plugin.load(bin .. "/nowhere.so") end, {"nowhere.so", "No such file"},
         "missing file")
  raises(function() cdvr.plugin.load(bin) end, {bin, "not a regular file"}, "directory")
  local text = bin .. "/test_codecs_lua_not_a_plugin.so"
  local f = assert(io.open(text, "w"))
  f:write("not an ELF file\n")
  f:close()
  raises(function() cdvr.plugin.load(text) end, {text, "cannot load plugin"}, "text file")
  os.remove(text)
  raises(function() cdvr.plugin.load() end, {"bad argument #1"}, "no argument")
  check(#cdvr.codecs() == n, "refusals register nothing")
  local help = debug.getregistry()["cdvr.help"]
  check(help and help["cdvr.codecs()"] and help["cdvr.plugin.load(path)"], "help entries")
end

-- CDVR_PLUGIN_PATH at start-up, in child processes
local function run(env, code)
  local cmd = env .. " '" .. exe .. "' -e '" .. code .. "' 2>&1"
  local p = assert(io.popen(cmd))
  local out = p:read("a")
  local ok = p:close()
  return ok, out
end

if exe then
  -- built-ins: raw, pvtc, hvq, hvqc; [5] is the first plugin
  local list = "io.write(#cdvr.codecs(), (cdvr.codecs()[5] or {}).name or \"-\", \"\\n\")"
  local ok, out = run("CDVR_PLUGIN_PATH='" .. bin .. "/tests/plugins:" .. bin .. "/no_such_dir'", list)
  check(ok, "bad plugins at start-up are not fatal: " .. out)
  local warnings = 0
  for line in out:gmatch("[^\n]+") do
    if line:find("^cdvr: warning: ") then warnings = warnings + 1 end
  end
  check(warnings == 9, "one warning per bad plugin and the missing directory (" .. warnings .. "): " .. out)
  check(out:find("bad_abi.so: plugin built for ABI version 42", 1, true), "warning names file and reason")
  check(out:find("\n4-\n", 1, true) or out:find("^4-\n"), "only the built-ins registered: " .. out)

  ok, out = run("CDVR_PLUGIN_PATH=''", list)
  check(ok and out == "4-\n", "empty CDVR_PLUGIN_PATH loads nothing: " .. out)

  if have_rle then
    ok, out = run("CDVR_PLUGIN_PATH='" .. bin .. "/plugins'", list)
    check(ok and out:find("rle") and not out:find("warning"), "CDVR_PLUGIN_PATH=plugins: " .. out)
  end
else
  io.stderr:write("no executable path in arg[-1]: start-up checks skipped\n")
end

checks.finish()
print("test_codecs: all checks passed")
