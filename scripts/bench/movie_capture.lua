-- scripts/bench/movie_capture.lua: capture cost (issue 24): N frames at each size played without
-- output, captured to PNG, to mp4 (H.264) and to mkv (FFV1), same run; prints wall times and
-- each capture's ratio to plain playback (the target for mp4: at most 1.2x).
--   build/cdvr scripts/bench/movie_capture.lua [--frames 60] [--sizes 512,1024] [--dir /tmp/cdvr_movie_bench]
local opt = {frames = "60", sizes = "512,1024", dir = "/tmp/cdvr_movie_bench"}
for i = 1, #arg, 2 do opt[(arg[i] or ""):gsub("^%-%-", "")] = arg[i + 1] end
os.execute(("mkdir -p %q"):format(opt.dir))
local vol = cdvr.generate("sphere", {dims = {96, 96, 96}, timesteps = 8})
local st = assert(cdvr.encode(vol, {path = opt.dir .. "/bench.cdv", variants = {{codec = "raw"}}, progress = false}))
local tf = cdvr.tf("hot")
local frames = tonumber(opt.frames)
print("size,output,wall_ms,ratio_to_play")
for size in opt.sizes:gmatch("%d+") do
  size = tonumber(size)
  local cam = cdvr.path.orbit{center = {47.5, 47.5, 47.5}, distance = 250, elevation = 25, period = frames, fov = 30}
  local base
  for _, o in ipairs{{"play", nil}, {"png", opt.dir .. "/png/%04d.png"}, {"mp4", opt.dir .. "/b.mp4"},
                     {"mkv", opt.dir .. "/b.mkv"}} do
    local p = cdvr.player{store = st, tf = tf, camera = cam, width = size, height = size, out = o[2], loop = true,
                          progress = o[2] and false or nil}
    local r = p:run{frames = frames}
    p:close()
    base = base or r.wall_ms
    print(("%d,%s,%.0f,%.2f"):format(size, o[1], r.wall_ms, r.wall_ms / base))
  end
end
os.execute(("rm -rf %q"):format(opt.dir))
