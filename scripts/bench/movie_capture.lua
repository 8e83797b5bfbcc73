-- scripts/bench/movie_capture.lua: capture cost (issue 24): N frames at each size played without
-- output, captured to PNG, to mp4 (H.264) and to mkv (FFV1), same run. The four cases are
-- interleaved (one run of each per round, the order rotated every round, `--repeats` rounds), so
-- load changes on the machine touch every case alike; prints per case the median wall time, the
-- median over rounds of its ratio to plain playback of the same round (the target for mp4: at most
-- 1.2x), and the 1-minute load average before and after. CSV on stdout, progress on stderr when
-- it is a terminal.
--   build/cdvr scripts/bench/movie_capture.lua [--frames 60] [--sizes 512,1024] [--repeats 3]
--                                              [--device cl|cpu] [--dir /tmp/cdvr_movie_bench]
local opt = {frames = "60", sizes = "512,1024", repeats = "3", device = nil, dir = "/tmp/cdvr_movie_bench"}
for i = 1, #arg, 2 do opt[(arg[i] or ""):gsub("^%-%-", "")] = arg[i + 1] end
os.execute(("mkdir -p %q"):format(opt.dir))
local function loadavg()
  local f = io.open("/proc/loadavg"); if not f then return "?" end
  local l = f:read("n"); f:close(); return ("%.2f"):format(l)
end
local tty = os.execute("test -t 2")
local vol = cdvr.generate("sphere", {dims = {96, 96, 96}, timesteps = 8})
local st = assert(cdvr.encode(vol, {path = opt.dir .. "/bench.cdv", variants = {{codec = "raw"}}, progress = false}))
local tf = cdvr.tf("hot")
local frames, repeats = tonumber(opt.frames), tonumber(opt.repeats)
local cases = {{"play", nil}, {"png", opt.dir .. "/png/%04d.png"}, {"mp4", opt.dir .. "/b.mp4"},
               {"mkv", opt.dir .. "/b.mkv"}}
local function median(t)
  local s = {table.unpack(t)}; table.sort(s)
  local n = #s; return n % 2 == 1 and s[(n + 1) // 2] or (s[n // 2] + s[n // 2 + 1]) / 2
end
print("size,output,frames,repeats,median_wall_ms,median_ratio_to_play,load_before,load_after")
for size in opt.sizes:gmatch("%d+") do
  size = tonumber(size)
  local cam = cdvr.path.orbit{center = {47.5, 47.5, 47.5}, distance = 250, elevation = 25, period = frames, fov = 30}
  local walls, ratios, before = {}, {}, loadavg()
  for _, c in ipairs(cases) do walls[c[1]], ratios[c[1]] = {}, {} end
  for r = 1, repeats do
    local round = {}
    for k = 0, #cases - 1 do
      local c = cases[(k + r - 1) % #cases + 1]
      if tty then io.stderr:write(("\r%d^2 round %d/%d: %-4s"):format(size, r, repeats, c[1])) end
      local p = cdvr.player{store = st, tf = tf, camera = cam, width = size, height = size, out = c[2], loop = true,
                            progress = c[2] and false or nil, device = opt.device}
      round[c[1]] = p:run{frames = frames}.wall_ms
      p:close()
    end
    for name, ms in pairs(round) do
      table.insert(walls[name], ms)
      table.insert(ratios[name], ms / round.play)
    end
  end
  if tty then io.stderr:write("\n") end
  local after = loadavg()
  for _, c in ipairs(cases) do
    print(("%d,%s,%d,%d,%.0f,%.2f,%s,%s"):format(size, c[1], frames, repeats, median(walls[c[1]]),
                                                 median(ratios[c[1]]), before, after))
  end
end
os.execute(("rm -rf %q"):format(opt.dir))
