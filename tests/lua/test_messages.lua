-- Misuse messages name their cause (issue 21 item 9). Every function and method cdvr.help()
-- lists is called with a wrong value (nil, a boolean, a string, a table, a function, NaN, -1,
-- 1e300) in each argument and, where it takes options, in each option its help line names
-- (key=) or its valid call uses; every message raised must say which function (its name) and,
-- for an option, which option, and none may read "bad argument #-1" or "to '?'" (Lua's
-- messages for a function called through pcall or from C). A help line with no entry below
-- fails the test, so new functions get the same checks. Window methods run when a window
-- opens (tests/test_window.sh runs this file under a virtual display).
-- Also: the specific messages of the issue (spacing 1e300, step=inf, __tostring error objects,
-- the raise / nil,msg rule that cdvr.help states).
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check = checks.check

local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))

local vol = cdvr.generate("sphere", {dims = {8, 8, 8}, timesteps = 3})
local st = assert(cdvr.encode(vol, {path = tmp .. "/s.cdv", variants = {{S = 4, T = 3}, {codec = "raw"}},
                                    stage2 = "none", progress = false}))
local tf = cdvr.tf("hot")
local cam = cdvr.camera{eye = {40, 4, 4}, center = {4, 4, 4}, width = 8, height = 8}
local img = cdvr.render(vol, {tf = tf, camera = cam, device = "cpu"})
local path = cdvr.path.orbit{center = {4, 4, 4}, distance = 40, period = 10}
local pl = cdvr.player{store = st, tf = tf, camera = cam, width = 8, height = 8, device = "cpu"}
assert(vol:save_raw(tmp .. "/v.raw"))
local win
do
  local ok, w = pcall(cdvr.window, {volume = vol, tf = tf, width = 16, height = 16, device = "cpu"})
  if ok then win = w end
end

-- The valid call of each help line: {function, arguments...; opts = index of the options
-- table, keys = options besides those of the help line}. skip = why a line is not called.
local render_opts = {tf = tf, camera = cam, device = "cpu"}
local cpu = {device = "cpu"}
local calls = {
  ["#v"] = {skip = "an operator"},
  ["cam:get"] = {cam.get, cam},
  ["cam:save"] = {cam.save, cam, tmp .. "/cam.lua"},
  ["cam:set"] = {cam.set, cdvr.camera{eye = {9, 0, 0}}, {fov = 40}, opts = 2},
  ["cdvr.bench_memcpy"] = {cdvr.bench_memcpy, 4096, 1, 1024},
  ["cdvr.camera(path.lua)"] = {cdvr.camera, tmp .. "/cam.lua"},
  ["cdvr.camera{"] = {cdvr.camera, {eye = {9, 0, 0}, width = 8, height = 8}, opts = 1},
  ["cdvr.cl_info"] = {cdvr.cl_info, skip = "no arguments; opens OpenCL"},
  ["cdvr.clock"] = {cdvr.clock},
  ["cdvr.stage2_rates"] = {cdvr.stage2_rates},
  ["cdvr.codec_chunk"] = {cdvr.codec_chunk, "pvtc", {S = 4, T = 3}, {8, 8, 8}, opts = 2},
  ["cdvr.codecs"] = {cdvr.codecs},
  ["cdvr.compare"] = {cdvr.compare, vol, vol},
  ["cdvr.encode"] = {cdvr.encode, vol, {path = tmp .. "/e.cdv", S = 4, T = 3, stage2 = "none", progress = false},
                     opts = 2},
  ["cdvr.formats"] = {cdvr.formats},
  ["cdvr.generate"] = {cdvr.generate, "sphere", {dims = {4, 4, 4}}, opts = 2},
  ["cdvr.have_gl"] = {skip = "a value"},
  ["cdvr.help"] = {cdvr.help, "render"},
  ["cdvr.load"] = {cdvr.load, tmp .. "/v.raw", {dims = {8, 8, 8}, type = "u8", timesteps = 3}, opts = 2},
  ["cdvr.load_lua"] = {cdvr.load_lua, tmp .. "/cam.lua"},
  ["cdvr.load_series"] = {cdvr.load_series, {tmp .. "/v.raw"}, {dims = {8, 8, 24}, type = "u8"}, opts = 2},
  ["cdvr.lod_plan"] = {cdvr.lod_plan, {dims = {8, 8, 8}, box = {{0, 0, 0}, {7, 7, 7}}, bytes_per_voxel = 1, distance = 40},
                       opts = 1},
  ["cdvr.methods"] = {cdvr.methods},
  ["cdvr.mpi.barrier"] = {cdvr.mpi.barrier},
  ["cdvr.mpi.built"] = {skip = "a value"},
  ["cdvr.mpi.rank"] = {cdvr.mpi.rank},
  ["cdvr.mpi.size"] = {cdvr.mpi.size},
  ["cdvr.open"] = {cdvr.open, tmp .. "/s.cdv"},
  ["cdvr.orbit_camera"] = {cdvr.orbit_camera, vol, {width = 8, height = 8}, opts = 2},
  ["cdvr.path.fn"] = {cdvr.path.fn, function() return {eye = {40, 0, 0}, center = {0, 0, 0}} end},
  ["cdvr.path.from"] = {cdvr.path.from, path:totable()},
  ["cdvr.path.is_path"] = {cdvr.path.is_path, path},
  ["cdvr.path.keyframes"] = {cdvr.path.keyframes, {{time = 0, eye = {40, 0, 0}, center = {0, 0, 0}},
                                                   {time = 1, eye = {0, 40, 0}, center = {0, 0, 0}}}},
  ["cdvr.path.load"] = {cdvr.path.load, tmp .. "/path.lua"},
  ["cdvr.path.orbit"] = {cdvr.path.orbit, {center = {4, 4, 4}, distance = 40, period = 10}, opts = 1},
  ["cdvr.path.save"] = {cdvr.path.save, path, tmp .. "/path.lua"},
  ["cdvr.player"] = {cdvr.player, {store = st, tf = tf, camera = cam, width = 8, height = 8, device = "cpu"},
                     opts = 1, keys = {"policy", "target_fps", "variant", "pipeline", "cold", "read_mbps",
                                       "frame", "pace", "loop", "brick_skip", "distribute", "min_psnr",
                                       "step", "unit", "term", "ring", "threads", "background"}},
  ["cdvr.plugin.load"] = {cdvr.plugin.load, tmp .. "/none.so"},
  ["cdvr.policy.closed_loop"] = {cdvr.policy.closed_loop, {target_fps = 30}, opts = 1},
  ["cdvr.policy.fixed"] = {cdvr.policy.fixed, 1},
  ["cdvr.policy.get"] = {cdvr.policy.get, "fixed"},
  ["cdvr.policy.measure"] = {cdvr.policy.measure, {}},
  ["cdvr.policy.open_loop"] = {cdvr.policy.open_loop, {target_fps = 30}, opts = 1},
  ["cdvr.policy.predict"] = {skip = "needs a measurement (test_policy.lua)"},
  -- allow: tf= given a name or points goes through cdvr.tf, whose message names cdvr.tf, not
  -- cdvr.render's option (lua/bind/l_render.c; reported)
  ["cdvr.render(store"] = {cdvr.render, st, {t = 1, variant = 1, tf = tf, camera = cam, device = "cpu"}, opts = 2,
                           allow = {tf = "cdvr.tf:"}},
  ["cdvr.render(v"] = {skip = "per-method lines: see cdvr.render(volume"},
  ["cdvr.render(volume"] = {cdvr.render, vol, render_opts, opts = 2,
                            keys = {"order", "threshold", "radius", "sigma", "skip", "lod", "blend", "iso",
                                    "shade", "light"}, allow = {tf = "cdvr.tf:"}},
  ["cdvr.save_lua"] = {cdvr.save_lua, {1, 2}, tmp .. "/t.lua"},
  ["cdvr.schedule.change_driven"] = {cdvr.schedule.change_driven, vol, {}, opts = 2},
  ["cdvr.schedule.fixed"] = {cdvr.schedule.fixed, {S = 4, T = 3}, opts = 1},
  ["cdvr.schedule.from_changes"] = {cdvr.schedule.from_changes, {1, 2, 3}, {}, opts = 2},
  ["cdvr.schedule.quantile"] = {cdvr.schedule.quantile, {1, 2, 3}, 0.5},
  ["cdvr.movie{"] = cdvr.has_movie and {cdvr.movie, {path = tmp .. "/m.mkv", width = 8, height = 8}, opts = 1}
                   or {skip = "no FFmpeg in this build"},
  ["m:add(img)"] = {skip = "a movie's methods: their argument checks are tests/test_movie.sh's"},
  ["cdvr.splat_order"] = {cdvr.splat_order, {4, 4, 4}, {1, 0, 0}, "axis"},
  ["cdvr.splat_order_quality"] = {cdvr.splat_order_quality, {4, 4, 4}, {1, 0, 0}, "axis", {}, opts = 4},
  ["cdvr.tf"] = {cdvr.tf, "hot", {}, opts = 2},
  ["cdvr.volume"] = {cdvr.volume, {dims = {4, 4, 4}}, opts = 1},
  ["cdvr.window"] = {cdvr.window, {volume = vol, tf = tf, width = 16, height = 16, device = "cpu"}, opts = 1,
                     window = true},
  ["img:annotate"] = {img.annotate, img, {colorbar = true, tf = tf}, opts = 2},
  ["img:pixel"] = {img.pixel, img, 0, 0},
  ["img:save"] = {img.save, img, tmp .. "/i.png", {alpha = true}, opts = 3},
  ["img:size"] = {img.size, img},
  ["img:stats"] = {img.stats, img},
  ["p(t)"] = {path, 0.5},
  ["p:camera"] = {path.camera, path, 0.5, 8, 8},
  ["p:close"] = {skip = "closes (test_player.lua)"},
  ["p:run"] = {pl.run, pl, {frames = 1}, opts = 2},
  ["p:totable"] = {path.totable, path},
  ["policy(stats)"] = {skip = "a contract"},
  ["st:bench_decode"] = {st.bench_decode, st, 1, 1},
  ["st:bench_unpack"] = {st.bench_unpack, st, 1, 1},
  ["st:chunk"] = {st.chunk, st, 1, 1},
  ["st:level"] = {st.level, st, 0},
  ["st:close"] = {skip = "closes (test_store.lua)"},
  ["st:decode(t ["] = {st.decode, st, 1, 1, cpu, opts = 4},
  ["st:decode(t,"] = {skip = "the same function"},
  ["st:info"] = {st.info, st},
  ["st:variants"] = {st.variants, st},
  ["tf:lookup"] = {tf.lookup, tf, 0.5},
  ["tf:name"] = {tf.name, tf},
  ["tf:normalized"] = {tf.normalized, tf},
  ["tf:points"] = {tf.points, tf},
  ["tf:range"] = {tf.range, tf},
  ["tf:save"] = {tf.save, tf, tmp .. "/tf.lua"},
  ["tf:shade"] = {tf.shade, tf},
  ["tf:unit"] = {tf.unit, tf},
  ["v:bounds"] = {vol.bounds, vol},
  ["v:bytes"] = {vol.bytes, vol},
  ["v:dims"] = {vol.dims, vol},
  ["v:direction"] = {vol.direction, vol},
  ["v:frame"] = {vol.frame, vol, 1, 1},
  ["v:get"] = {vol.get, vol, 1, 1, 1, 1},
  ["v:info"] = {vol.info, vol},
  ["v:origin"] = {vol.origin, vol},
  ["v:quantize"] = {vol.quantize, vol, {lo = 0, hi = 1}, opts = 2},
  ["v:range"] = {vol.range, vol},
  ["v:save_raw"] = {vol.save_raw, vol, tmp .. "/w.raw", {endian = "big"}, opts = 3},
  ["v:save"] = {vol.save, vol, tmp .. "/w.nrrd", {compress = true}, opts = 3},
  ["v:set"] = {vol.set, cdvr.volume{dims = {4, 4, 4}}, 1, 1, 1, 1, 7},
  ["v:spacing"] = {vol.spacing, vol},
  ["v:times"] = {vol.times, vol},
  ["v:timesteps"] = {vol.timesteps, vol},
  ["v:to_world"] = {vol.to_world, vol, 1, 2, 3},
  ["v:type"] = {vol.type, vol},
  ["v:window"] = {vol.window, vol},
  ["w:camera"] = {window = true, method = "camera"},
  ["w:close"] = {skip = "closes (test_window.sh)"},
  ["w:frame"] = {window = true, method = "frame"},
  ["w:read"] = {window = true, method = "read"},
  ["w:set"] = {window = true, method = "set", args = {{t = 1}}, opts = 2,
               keys = {"volume", "store", "tf", "camera", "method", "device", "overlay", "t", "variant",
                       "step", "playing", "fps", "policy", "min_psnr", "callback_limit"}},
  ["w:state"] = {window = true, method = "state"},
  ["w:screenshot"] = {window = true, method = "screenshot", args = {tmp .. "/shot.png", {scale = 1}}, opts = 3},
}

-- help line -> its key in calls: the name, or the longest key the line starts with
local function entry_of(line)
  local best
  for key in pairs(calls) do
    if line:sub(1, #key) == key and (not best or #key > #best) then best = key end
  end
  return best
end

local wrong = {n = 8, nil, true, "zz", {}, function() end, 0 / 0, -1, 1e300}
-- A number where a path goes is a path (Lua's string coercion, as io.open takes it): the
-- writers called with one leave files named after it in the working directory; those this
-- test made are removed at its end.
local number_paths = {}
for _, w in ipairs{tostring(0 / 0), tostring(-1), tostring(1e300)} do
  local f = io.open(w, "rb")
  if f then f:close() else number_paths[#number_paths + 1] = w end
end
local function show(v)
  if type(v) == "function" then return "function" end
  if type(v) == "table" then return "{}" end
  if type(v) == "string" then return ("%q"):format(v) end
  return tostring(v)
end

local calls_made, messages = 0, 0
-- One call; a message must name the function (short name: the part after '.' or ':') and the
-- option when one was given, with no "#-1" and no "'?'".
local function try(label, short, option, f, args, n, e)
  calls_made = calls_made + 1
  local ok, msg = pcall(f, table.unpack(args, 1, n))
  if ok then return end
  messages = messages + 1
  msg = tostring(msg)
  local why
  if msg:find("#-1", 1, true) then
    why = "has '#-1'"
  elseif msg:find("'?'", 1, true) then
    why = "has '?'"
  elseif option and e.allow and e.allow[option] and msg:sub(1, #e.allow[option]) == e.allow[option] then
    why = nil -- a known message, reported (see the entry)
  elseif e.lua then
    why = nil -- share/lua: only the two checks above (see lua_modules)
  elseif not msg:find("%f[%w_]" .. short .. "%f[^%w_]") and
         not (e.loader and type(args[1]) ~= "nil" and msg:find(tostring(args[1]), 1, true)) then
    why = "does not name " .. short
  elseif option and not msg:find("%f[%w_]" .. option .. "%f[^%w_]") then
    why = "does not name option " .. option
  end
  check(not why, ("%s: message %s: %s"):format(label, why, msg))
end

local function copy(t)
  local c = {}
  for k, v in pairs(t) do c[k] = v end
  return c
end

-- cdvr.help() prints; its entries are the registry's "cdvr.help" (name -> description)
local help = debug.getregistry()["cdvr.help"]
local lines = {}
for name, desc in pairs(help) do lines[#lines + 1] = name .. " " .. desc end
table.sort(lines)
local covered = {}
for _, line in ipairs(lines) do
  local key = entry_of(line)
  check(key, "help line without an entry in test_messages.lua: " .. line)
  local e = key and calls[key]
  if e and not e.skip and not covered[key] and (not e.window or win) then
    covered[key] = true
    local f, args, n
    if e.method then
      f, args = win[e.method], {win, table.unpack(e.args or {})}
    else
      f, args = e[1], {table.unpack(e, 2)}
    end
    n = #args
    local short = (key:match("[%.:]([%w_]+)[^%w_]*$") or key:match("^([%w_.]+)")):match("([%w_]+)$")
    if key == "p(t)" then short = "path" end
    if key:find("^cdvr%.camera") then short = "camera" end
    if key:find("^cdvr%.render") then short = "render" end
    if key:find("^st:decode") then short = "decode" end
    e.lua = e.lua or key:find("^cdvr%.path") or key:find("^cdvr%.policy") or key:find("^cdvr%.schedule") or
            key:find("^p[:(]") or key == "cdvr.save_lua" or key == "cdvr.load_lua"
    e.loader = key:find("^cdvr%.load") or key:find("^cdvr%.open") or key:find("^cdvr%.camera%(path") or
               key:find("^cdvr%.plugin")
    try(key, short, nil, f, args, n, e)
    for i = 1, n do
      for w = 1, wrong.n do
        local a = copy(args)
        a[i] = wrong[w]
        try(("%s arg %d = %s"):format(key, i, show(wrong[w])), short, nil, f, a, n, e)
      end
    end
    if e.opts then
      local keys, seen = {}, {}
      local function add(k) if not seen[k] then seen[k] = true; keys[#keys + 1] = k end end
      for k in line:gmatch("%f[%w_]([%a_][%w_]*)=") do add(k) end
      for k in pairs(args[e.opts]) do if type(k) == "string" then add(k) end end
      for _, k in ipairs(e.keys or {}) do add(k) end
      for _, k in ipairs(keys) do
        for w = 1, wrong.n do
          if wrong[w] ~= nil then
            local a = copy(args)
            a[e.opts] = copy(args[e.opts])
            a[e.opts][k] = wrong[w]
            try(("%s option %s = %s"):format(key, k, show(wrong[w])), short, k, f, a, n, e)
          end
        end
      end
    end
  end
end
print(("%d calls, %d messages checked%s"):format(calls_made, messages, win and " (window too)" or ""))

-- ---- the cases of the issue ----------------------------------------------------------------
local function raises(want, f, ...)
  local ok, msg = pcall(f, ...)
  msg = tostring(msg)
  check(not ok and msg:find(want, 1, true), ("expected an error with '%s', got %s"):format(want, msg))
  check(not msg:find("#-1", 1, true) and not msg:find("'?'", 1, true), "unnamed: " .. msg)
  return msg
end
raises("cdvr.plugin.load", cdvr.plugin.load, nil)
raises("cdvr.Volume.get", vol.get, 3)
raises("cdvr.tf: option 'volume': cdvr.Volume expected, got number", cdvr.tf, "hot", {range = "auto", volume = 3})
raises("img:annotate: option 'volume': cdvr.Volume expected, got boolean", img.annotate, img, {volume = true})
raises("cdvr.codec_chunk: dims[2]: number expected, got string", cdvr.codec_chunk, "pvtc", {}, {1, "x", 1})
if win then raises("option 'store'", win.set, win, {store = false}) end
-- spacing 1e300: the box, not "up parallel"
do
  local big = cdvr.volume{dims = {4, 4, 4}}
  local raw = tmp .. "/big.raw"
  assert(big:save_raw(raw))
  local ok, v = pcall(cdvr.load, raw, {dims = {4, 4, 4}, type = "u8", spacing = {1e300, 1e300, 1e300}})
  if ok then
    local msg = raises("box", cdvr.orbit_camera, v, {width = 8, height = 8})
    check(not msg:find("parallel", 1, true), "spacing 1e300 reported as: " .. msg)
    msg = raises("box", cdvr.render, v, {tf = tf, device = "cpu"})
    check(not msg:find("parallel", 1, true), "spacing 1e300 reported as: " .. msg)
  else
    check(tostring(v):find("spacing", 1, true), "spacing 1e300 refused without naming spacing: " .. tostring(v))
  end
end
-- step=inf: finite
for _, f in ipairs{function(o) return cdvr.render(vol, o) end,
                   function(o) o.store, o.width, o.height = st, 8, 8; return cdvr.player(o) end} do
  for _, key in ipairs{"step", "unit"} do -- term >= 1 is "no early termination": inf is fine
    local o = {tf = tf, camera = cam, device = "cpu"}
    o[key] = math.huge
    local msg = raises(key, f, o)
    check(msg:find("finite", 1, true), key .. "=inf: " .. msg)
  end
end
-- help states the rule: every line of a loader, opener or saver says raise or nil, msg
for _, line in ipairs(lines) do
  if line:find("^cdvr%.open") or line:find("^cdvr%.load[%(_]") or line:find("^cdvr%.encode") or
     line:find(":save") or line:find("^cdvr%.camera%(path") or line:find("^cdvr%.tf%(") then
    check(line:find("raises", 1, true) or line:find("nil, msg", 1, true) or line:find("nil, message", 1, true),
          "help line does not say how it fails: " .. line)
  end
end
local help_of = function(name)
  for _, line in ipairs(lines) do if line:sub(1, #name + 1) == name .. "(" then return line end end
  return ""
end
-- cdvr.open raises, as its help says
raises(tmp .. "/missing.cdv", cdvr.open, tmp .. "/missing.cdv")
check(help_of("cdvr.open"):find("raises", 1, true), "cdvr.open's help: " .. help_of("cdvr.open"))
-- cdvr.encode raises on a path it cannot write, as its help says
raises(tmp .. "/no/dir/x.cdv", cdvr.encode, vol, {path = tmp .. "/no/dir/x.cdv", progress = false})
check(help_of("cdvr.encode"):find("raises", 1, true), "cdvr.encode's help: " .. help_of("cdvr.encode"))
-- savers return nil, msg
do
  local ok, msg = img:save(tmp .. "/no/dir/i.png")
  check(ok == nil and tostring(msg):find("i.png", 1, true), "img:save returns nil, msg: " .. tostring(msg))
end

-- error objects with __tostring keep their text: in callbacks and in the host
do
  local E = setmetatable({}, {__tostring = function() return "an error object's own text" end})
  local bad = cdvr.player{store = st, tf = tf, camera = cam, width = 8, height = 8, device = "cpu",
                          policy = function() error(E) end}
  local ok, msg = pcall(bad.run, bad, {frames = 1})
  check(not ok and tostring(msg):find("an error object's own text", 1, true), "policy error object: " .. tostring(msg))
  bad:close()
  raises("an error object's own text", cdvr.encode, vol, {path = tmp .. "/eo.cdv", progress = false,
                                                          schedule = function() error(E) end})
  local bin = os.getenv("CDVR_BINARY_DIR")
  if bin then
    local f = assert(io.popen(("%q -e %q 2>&1"):format(bin .. "/cdvr",
      'error(setmetatable({}, {__tostring = function() return "host error object" end}))')))
    local out = f:read("a")
    f:close()
    check(out:find("cdvr: host error object", 1, true) and out:find("stack traceback", 1, true) and
          not out:find("not a string", 1, true), "host error object: " .. out)
  end
end

if win then win:close() end
pl:close()
os.execute(("rm -rf %q"):format(tmp))
for _, path in ipairs(number_paths) do os.remove(path) end
checks.finish()
