-- scripts/movie.lua: a series (a .cdv store, a 4D file, or a file pattern) to a movie in one
-- line, along a camera orbit, with a TF preset and annotations (cdvr.player's capture, out=).
--   build/cdvr scripts/movie.lua SERIES OUT.mp4|.webm|.mkv|.gif [--frames N] [--fps F]
--        [--width W] [--height H] [--tf PRESET] [--turns T] [--elevation DEG] [--crf C]
--        [--preset P] [--annotate] [--variant NAME]
-- SERIES: store.cdv (opened), a 4D file (cdvr.load), or a pattern with * or %d
-- (cdvr.load_series); anything but a store is encoded first to a temporary raw store. Defaults:
-- frames = the timesteps, fps 25, 512x512, TF "hot", one turn, elevation 25.
local usage = "usage: cdvr scripts/movie.lua SERIES OUT.mp4 [--frames N] [--fps F] [--width W] [--height H] " ..
              "[--tf PRESET] [--turns T] [--elevation DEG] [--crf C] [--preset P] [--annotate] [--variant NAME]"
local series, out = arg[1], arg[2]
if not series or not out then io.stderr:write(usage, "\n"); os.exit(2) end
local opt, i = {}, 3
while i <= #arg do
  local k = arg[i]:match("^%-%-(.+)$")
  if not k then io.stderr:write("movie.lua: unexpected argument '", arg[i], "'\n", usage, "\n"); os.exit(2) end
  if k == "annotate" then opt.annotate = true; i = i + 1 else opt[k] = arg[i + 1]; i = i + 2 end
end
local known = {frames = 1, fps = 1, width = 1, height = 1, tf = 1, turns = 1, elevation = 1, crf = 1,
               preset = 1, annotate = 1, variant = 1}
for k in pairs(opt) do
  if not known[k] then io.stderr:write("movie.lua: unknown option --", k, "\n", usage, "\n"); os.exit(2) end
end
local function num(k, def)
  if opt[k] == nil then return def end
  return tonumber(opt[k]) or error(("movie.lua: --%s %s: a number expected"):format(k, opt[k]), 0)
end

local st, tmp
if series:match("%.cdv$") then
  st = assert(cdvr.open(series))
else
  local vol = series:match("[*%%]") and assert(cdvr.load_series(series)) or assert(cdvr.load(series))
  tmp = os.tmpname()
  st = assert(cdvr.encode(vol, {path = tmp .. ".cdv", variants = {{codec = "raw", stage2 = "lzo"}}, progress = false}))
end
local info = st:info()
local frames = math.floor(num("frames", info.timesteps))
local width, height = math.floor(num("width", 512)), math.floor(num("height", 512))
local x0, x1, y0, y1, z0, z1 = st:decode(1):bounds()
local turns = num("turns", 1)
local camera = cdvr.path.orbit{center = {(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2},
                               distance = 1.9 * math.max(x1 - x0, y1 - y0, z1 - z0),
                               elevation = num("elevation", 25), period = frames / turns, fov = 30}
local p = cdvr.player{store = st, tf = cdvr.tf(opt.tf or "hot"), camera = camera, width = width, height = height,
                      out = out, fps = num("fps", nil), crf = opt.crf and math.floor(num("crf")) or nil,
                      preset = opt.preset, annotate = opt.annotate, variant = opt.variant, loop = true}
local report = p:run{frames = frames}
p:close()
st:close()
if tmp then os.remove(tmp .. ".cdv"); os.remove(tmp) end
print(("movie.lua: %s: %d frames, %dx%d, captured at %.1f fps"):format(out, #report.frames, width, height, report.fps))
