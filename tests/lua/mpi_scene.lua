-- mpi_scene.lua MODE DIR [DEVICE]: run by tests/test_mpi.sh under `mpirun -np N` (and alone).
-- Plays a small bricked store with cdvr.player{distribute=MODE} (MODE "time" or "bricks") for a
-- camera outside and one inside the volume, lossless and lossy variants, and checks every
-- frame against the one-process render of the same frame (image PSNR >= 50 dB), the gathered
-- rows on rank 0 and the numbered frames written to DIR. Any failure raises (and so ends
-- every rank through MPI_Abort). Prints "mpi_scene MODE N: ok, min psnr X dB" on rank 0.
local mode, dir, device = arg[1], arg[2], arg[3] or "cpu"
assert(mode == "time" or mode == "bricks", "usage: mpi_scene.lua time|bricks DIR [cpu|cl]")
local rank, size = cdvr.mpi.rank(), cdvr.mpi.size()
local FRAMES = 5

-- The store: written by rank 0, then opened by every rank.
local path = dir .. "/scene.cdv"
if rank == 0 then
  local vol = cdvr.generate("ml", {dims = {37, 33, 29}, timesteps = 4})
  assert(cdvr.encode(vol, {variants = {{codec = "raw"}, {codec = "pvtc", S = 1, T = 3}},
                           bricks = {4, 2, 2}, stage2 = "lzo", path = path})):close()
end
cdvr.mpi.barrier()
local st = assert(cdvr.open(path))

local tf = cdvr.tf{{0, 0, 0, 0, 0}, {60, .1, .2, .8, .01}, {140, .9, .5, .2, .05},
                   {255, 1, 1, .9, .12}}
local center = {18, 16, 14}
local scenes = {
  outside = function(frame)
    local a = 2 * math.pi * (frame - 1) / FRAMES + 0.3
    return {eye = {center[1] + 80 * math.cos(a), center[2] + 80 * math.sin(a), center[3] + 30},
            center = center, up = {0, 0, 1}, fov = 30}
  end,
  inside = function(frame)
    local a = 2 * math.pi * (frame - 1) / FRAMES
    return {eye = {center[1] + 4 * math.cos(a), center[2] + 4 * math.sin(a), center[3] + 2},
            center = {center[1] + 20 * math.cos(a + 2), center[2] + 20 * math.sin(a + 2), center[3] - 3},
            up = {0, 0, 1}, fov = 70}
  end,
}

local function play(opts)
  local images, rows = {}, nil
  opts.store, opts.device, opts.width, opts.height = st, device, 48, 40
  opts.loop, opts.threads = true, 1
  opts.frame = function(row, img) images[row.frame] = img end
  local p = cdvr.player(opts)
  rows = p:run{frames = FRAMES}
  p:close()
  return images, rows
end

-- Opaque: early termination off (term = 1), else a box stops on its own alpha only and a
-- pixel may keep up to 1 - term_alpha of colour the one-process ray dropped (cdvr/dist.h).
local opaque = cdvr.tf{{0, 0, 0, 0, 0}, {60, .1, .2, .8, .3}, {140, .9, .5, .2, .7},
                       {255, 1, 1, .9, .95}}
local runs = {}
for _, name in ipairs{"outside", "inside"} do
  for _, variant in ipairs{"raw", "S1T3"} do
    runs[#runs + 1] = {name = name, variant = variant, tf = tf}
  end
end
runs[#runs + 1] = {name = "outside", variant = "raw", tf = opaque, term = 1, tag = "_opaque"}

local min_psnr = math.huge
for _, run in ipairs(runs) do
  local name, variant = run.name, run.variant
  do
    local out = ("%s/%s_%s%s/%%02d.png"):format(dir, name, variant, run.tag or "")
    local got, report = play{camera = scenes[name], variant = variant, distribute = mode, out = out,
                             tf = run.tf, term = run.term}
    local ref = play{camera = scenes[name], variant = variant, tf = run.tf, term = run.term}
    local shown = 0
    for frame, img in pairs(got) do
      local r = cdvr.compare(img, ref[frame])
      min_psnr = math.min(min_psnr, r.psnr)
      assert(r.psnr >= 50, ("%s %s %s rank %d frame %d: %.2f dB against one process"):format(
        mode, name, variant, rank, frame, r.psnr))
      shown = shown + 1
    end
    if mode == "time" then
      local mine = 0
      for k = 1, FRAMES do if (k - 1) % size == rank then mine = mine + 1 end end
      assert(shown == mine, ("rank %d showed %d frames, expected %d"):format(rank, shown, mine))
    else
      assert(shown == (rank == 0 and FRAMES or 0), ("rank %d showed %d frames"):format(rank, shown))
    end
    cdvr.mpi.barrier()
    if rank == 0 then
      local per_frame = mode == "bricks" and size or 1
      assert(#report.frames == FRAMES * per_frame, ("%d rows"):format(#report.frames))
      assert(report.ranks == size and report.fps > 0)
      for i, row in ipairs(report.frames) do
        assert(not row.error, row.error)
        assert(row.frame == (i - 1) // per_frame + 1, "rows sorted by frame")
        if mode == "time" then
          assert(row.rank == (row.frame - 1) % size, ("frame %d from rank %d"):format(row.frame, row.rank))
        else
          assert(row.rank == (i - 1) % size, "one row per rank")
          assert(size == 1 or row.composite_ms > 0, "composite timed")
        end
      end
      for k = 1, FRAMES do   -- one numbered sequence, whoever rendered the frame
        assert(io.open(out:format(k), "rb"), "frame file " .. out:format(k)):close()
      end
    end
  end
end
st:close()
if rank == 0 then
  print(("mpi_scene %s %d: ok, min psnr %.1f dB"):format(mode, size, min_psnr))
end
