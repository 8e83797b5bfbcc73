-- The player through the brick cache on the cpu device, synchronous and asynchronous
-- (cache=true, cache_async=true; cdvr/brick_cache.h, cdvr/player.h), no OpenCL needed:
--   - synchronous, lod_error 0, room for everything: every frame equals the cpu player's frame
--     without the cache and cdvr.render's cpu path through the cache, bit for bit; rows report
--     resident bytes, bricks per level and lod_error, and no chunk read by the player itself;
--   - asynchronous: the first frame renders every brick at the pinned coarsest level (rows:
--     bricks_coarser = every brick, bricks_pending > 0) and equals the synchronous render with
--     every brick at the coarsest level (no hole); the same view played again converges to
--     bricks_coarser = 0, and that frame equals the synchronous frame bit for bit; a camera
--     jump (far -> near) plays its first frame from the coarser resident bricks;
--   - a policy's third result sets lod_error per group (stats show levels and lod_error);
--   - a budget below the coarsest level fails every frame, naming it;
--   - cache_async without cache is refused.
local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))
local vol = cdvr.generate("sphere", {dims = {41, 36, 29}, timesteps = 2, radius = 0.6})
local st = cdvr.encode(vol, {path = tmp .. "/c.cdv", progress = false, levels = 3,
                             bricks = {3, 2, 2}, variants = {{codec = "raw", name = "raw"}}})
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {60, 1, .6, .2, .3}, {255, 1, 1, 1, .9}}
local near = cdvr.orbit_camera(vol, {azimuth = 35, elevation = 20, width = 40, height = 32})
local far = cdvr.camera{eye = {20 + 500, 18, 14}, center = {20, 18, 14}, up = {0, 0, 1},
                        fov = 30, width = 40, height = 32}

-- plays frames of p and returns its rows and images
local function play(opts, frames, first)
  local images = {}
  opts.frame = function(row, img) images[#images + 1] = img end
  local p = cdvr.player(opts)
  local r = p:run{frames = frames, first = first}
  return p, r.frames, images
end

local function same(a, b) return cdvr.compare(a, b).maxerr == 0 end

-- synchronous
do
  local base = {store = st, tf = tf, camera = near, device = "cpu", pipeline = false}
  local p0, _, plain = play(base, 2)
  p0:close()
  local o = {store = st, tf = tf, camera = near, device = "cpu", pipeline = false, cache = true,
             lod_error = 0, budget_mb = 64}
  local p, rows, imgs = play(o, 2)
  p:close()
  for i = 1, 2 do
    local row = rows[i]
    assert(not row.error, row.error)
    assert(row.bricks_level0 == 12 and row.bricks_level2 == 0 and row.resident_bytes > 0 and
           row.lod_error == 0 and row.bricks_coarser == 0 and row.bricks_pending == 0,
           "synchronous rows: every brick at level 0, nothing coarser or pending")
    assert(row.bricks_read == 0 and row.bytes == 0, "the cache reads what it needs itself: " ..
           "the player reads no chunk (" .. row.bricks_read .. " bricks, " .. row.bytes .. " bytes)")
    assert(same(imgs[i], plain[i]), "frame " .. i .. ": through the cache = without it")
    local ref = cdvr.render(st, {t = i, tf = tf, camera = near, device = "cpu", cache = true,
                                 lod_error = 0, budget_mb = 64})
    assert(same(imgs[i], ref), "frame " .. i .. ": = cdvr.render's cpu path through the cache")
  end
end

-- asynchronous: coarsest first, then refined to the synchronous frame
local function sync_render(cam, lod)
  return cdvr.render(st, {t = 1, tf = tf, camera = cam, device = "cpu", cache = true,
                          lod_error = lod, budget_mb = 64})
end
local refined_after
do
  local p, rows, imgs = play({store = st, tf = tf, camera = near, device = "cpu", cache = true,
                              cache_async = true, lod_error = 0, budget_mb = 64}, 1)
  local r1 = rows[1]
  assert(not r1.error, r1.error)
  assert(r1.bricks_level2 == 12 and r1.bricks_coarser == 12 and r1.bricks_pending > 0,
         ("first frame: %d at level 2, %d coarser, %d pending"):format(r1.bricks_level2,
         r1.bricks_coarser, r1.bricks_pending))
  assert(same(imgs[1], sync_render(near, 1e6)), "first frame = the synchronous coarsest frame")
  assert(not same(imgs[1], sync_render(near, 0)), "coarse and fine frames differ")
  -- the same view again until the worker's bricks are resident (each run is one frame) and
  -- it has nothing left to decode: pending also counts the bricks of the next timestep that
  -- each frame asks for (cdvr_brick_cache_set_next), which a loaded machine may still be
  -- decoding when this view's bricks are all resident
  local last
  for k = 1, 400 do
    local r = p:run{frames = 1}
    last = r.frames[1]
    if last.bricks_coarser == 0 and not refined_after then refined_after = k end
    if last.bricks_coarser == 0 and last.bricks_pending == 0 then break end
  end
  assert(refined_after, "the async cache refines the view")
  assert(last.bricks_level0 == 12 and last.bricks_pending == 0, "refined: level 0 everywhere")
  assert(same(imgs[#imgs], sync_render(near, 0)), "refined frame = the synchronous frame")
  p:close()
end

-- a camera jump far -> near: the first near frame uses the coarser bricks resident from afar
do
  local calls = 0 -- frame numbers restart with each p:run: count the camera's calls instead
  local p, rows = play({store = st, tf = tf, device = "cpu", cache = true, cache_async = true,
                        lod_error = 1, budget_mb = 64, pipeline = false, loop = true, width = 40, height = 32,
                        camera = function()
                          calls = calls + 1
                          return calls == 1 and far or near
                        end}, 1)
  assert(rows[1].bricks_level2 == 12, "far: the coarsest level")
  local r = p:run{frames = 1}.frames[1]
  assert(r.bricks_coarser > 0 and r.bricks_level0 == 0,
         ("right after the jump: %d bricks coarser than chosen, none at level 0"):format(r.bricks_coarser))
  assert(r.bricks_level0 + r.bricks_level1 + r.bricks_level2 == 12, "every brick has a level")
  p:close()
end

-- a policy sees the levels and sets lod_error per group (its third result)
do
  local seen = {}
  local p, rows = play({store = st, tf = tf, camera = near, device = "cpu", cache = true,
                        lod_error = 0, budget_mb = 64, pipeline = false,
                        policy = function(stats)
                          seen[#seen + 1] = {stats.lod_error, stats.lod_base, stats.levels}
                          if stats.t == 1 then return "raw", "start" end
                          return "raw", "coarser", 1e6
                        end}, 2)
  assert(seen[1][1] == 0 and seen[1][2] == 0 and seen[1][3] == 3, "stats: lod_error, lod_base, levels")
  assert(seen[2][1] == 0, "lod_error unchanged until the policy sets it")
  assert(rows[1].lod_error == 0 and rows[1].bricks_level0 == 12, "group 1 at lod_error 0")
  assert(rows[2].lod_error == 1e6 and rows[2].bricks_level2 == 12, "group 2 at the policy's lod_error")
  p:close()
  local function bad_lod(lod, cache)
    local q = cdvr.player{store = st, tf = tf, camera = near, device = "cpu", cache = cache,
                          pipeline = false, policy = function() return "raw", "x", lod end}
    local ok, err = pcall(q.run, q, {frames = 1})
    q:close()
    return not ok and err or "no error"
  end
  assert(bad_lod(2, false):find("only with cache=true", 1, true), "lod_error without the cache")
  assert(bad_lod("fine", true):find("a number >= 0 expected", 1, true), "lod_error not a number")
  assert(bad_lod(-1, true):find("lod_error", 1, true), "lod_error < 0")
end

-- a budget below the coarsest level: every frame fails, naming it (never a silent fallback)
do
  local p = cdvr.player{store = st, tf = tf, camera = near, device = "cpu", cache = true,
                        cache_async = true, budget_mb = 1e-4, pipeline = false}
  local r = p:run{frames = 2}
  for i = 1, 2 do
    local e = r.frames[i].error
    assert(e and e:find("coarsest level", 1, true), "frame " .. i .. ": " .. tostring(e))
  end
  p:close()
end

assert(not pcall(cdvr.player, {store = st, tf = tf, device = "cpu", cache_async = true}),
       "cache_async needs cache=true")
st:close()
os.execute(("rm -rf %q"):format(tmp))
print(("test_player_cache: ok (async refined after %d one-frame runs)"):format(refined_after))
