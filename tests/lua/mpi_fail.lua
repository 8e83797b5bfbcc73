-- mpi_fail.lua WHAT DIR [MODE]: run by tests/test_mpi.sh under `mpirun -np 2`. Rank 1 fails
-- while rank 0 waits for it in a collective call: WHAT = "open" (a store that does not exist,
-- rank 0 waits in a barrier) or "raise" (rank 1's camera callback raises during a
-- distributed run with distribute=MODE; rank 0 waits for it at the end of the run or, with
-- "bricks", in every frame's composite). Every rank must exit, non-zero, with rank 1's
-- message: the host reports it and calls MPI_Abort.
local what, dir, mode = arg[1], arg[2], arg[3] or "time"
local rank = cdvr.mpi.rank()
if what == "open" then
  if rank == 1 then
    assert(cdvr.open(dir .. "/no_such_store.cdv"))
  end
  cdvr.mpi.barrier()
  error("rank " .. rank .. " passed the barrier: rank 1 should have stopped the run")
end
local path = dir .. "/fail.cdv"
if rank == 0 then
  local vol = cdvr.generate("sphere", {dims = {17, 15, 13}, timesteps = 4})
  assert(cdvr.encode(vol, {codec = "raw", bricks = {2, 1, 1}, path = path})):close()
end
cdvr.mpi.barrier()
local st = assert(cdvr.open(path))
local p = cdvr.player{store = st, tf = cdvr.tf("hot"), width = 16, height = 16, device = "cpu",
                      distribute = mode, loop = true, pipeline = false,
                      camera = function(frame)
                        if rank == 1 and frame >= 2 then error("camera broke on purpose") end
                        return {eye = {8, -40, 6}, center = {8, 7, 6}, up = {0, 0, 1}, fov = 30}
                      end}
p:run{frames = 8}
error("rank " .. rank .. " finished the run: rank 1 should have stopped it")
