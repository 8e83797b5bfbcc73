-- mpi_agree.lua WHAT DIR: run by tests/test_mpi.sh under `mpirun -np 2` (with a short
-- CDVR_MPI_TIMEOUT). The ranks disagree, and every rank must stop with an error naming what
-- differs (or, for a wait no other rank will end, the waiting rank must report itself):
--   mode    rank 0 distribute="time", rank 1 "bricks"
--   store   the ranks open different stores
--   camera  different cameras (bricks)
--   path    a camera path that gives rank 1 another camera from frame 3 (bricks; p:run strict)
--   frames  p:run{frames = 4 + rank}
--   barrier rank 1 calls one barrier more than rank 0
-- A rank that gets past the disagreement prints "should have stopped".
local what, dir = arg[1], arg[2]
local rank = cdvr.mpi.rank()
local a, b = dir .. "/agree_a.cdv", dir .. "/agree_b.cdv"
if rank == 0 then
  assert(cdvr.encode(cdvr.generate("sphere", {dims = {12, 12, 12}, timesteps = 4}),
                     {codec = "raw", bricks = {2, 1, 1}, path = a, progress = false})):close()
  assert(cdvr.encode(cdvr.generate("sphere", {dims = {14, 12, 12}, timesteps = 4}),
                     {codec = "raw", bricks = {2, 1, 1}, path = b, progress = false})):close()
end
cdvr.mpi.barrier()
if what == "barrier" then
  if rank == 1 then cdvr.mpi.barrier() end
  print("rank " .. rank .. " done")
  if rank == 1 then print("rank 1 passed its extra barrier: it should have stopped") end
  return
end
local st = assert(cdvr.open((what == "store" and rank == 1) and b or a))
local mode = (what == "mode" and rank == 1) and "bricks" or ((what == "camera" or what == "path") and "bricks" or "time")
local eye = (what == "camera" and rank == 1) and {6, -40, 9} or {6, -40, 6}
local ok, msg = pcall(function()
  local p = cdvr.player{store = st, tf = cdvr.tf("hot"), width = 16, height = 16, device = "cpu",
                        distribute = mode, loop = true, pipeline = false,
                        camera = what ~= "path" and cdvr.camera{eye = eye, center = {6, 6, 6}, up = {0, 0, 1}, fov = 30}
                                 or function(frame)
                                   local y = (rank == 1 and frame >= 3) and -50 or -40
                                   return {eye = {6, y, 6}, center = {6, 6, 6}, up = {0, 0, 1}, fov = 30}
                                 end}
  p:run{frames = what == "frames" and 4 + rank or 4, strict = true}
end)
assert(not ok, "rank " .. rank .. ": the run went on: it should have stopped")
error(msg, 0) -- the host reports it, naming the rank, and ends every rank
