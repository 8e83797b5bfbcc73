-- The brick cache and level of detail (issue 26 items 2-4; cdvr/brick_cache.h): a bricked
-- multi-resolution store rendered on cl through the cache (cache=true) with lod_error=0 and a
-- budget that holds everything equals the dense render of the same store bit for bit, for a
-- lossless and two lossy variants (hvq decodes the bricks' overlap voxels differently from
-- their owners: the cache takes the owners') and for two timesteps (the LRU keeps them);
-- with a far camera and lod_error=1 coarser levels are chosen; a small budget coarsens the
-- farthest bricks until the frame fits (resident bytes <= budget, PSNR against the full
-- render reported > 20 dB here), and a budget below the coarsest level is an error naming it.
-- On cl the ray caster marches brick by brick (cache_path "march", the default) and equals the
-- dense render at level 0 also unskipped, shaded and in max blend; fetch="sample" reads every
-- voxel through the page table and fetch="bulk" renders a dense frame assembled from the cache
-- (the same images at level 0). With coarse levels the march (coarse bricks at their own
-- resolution and step) stays close to the page table's image (upsampled voxels at the level-0
-- step) and to the CPU reference (which renders the page table's definition).
-- The CPU reference through the cache (cache=true, device="cpu") equals the CPU render of the
-- store at level 0 and agrees with cl (>= 50 dB) with coarse levels.
if not cdvr.cl_info() then
  print("skip: no OpenCL device")
  os.exit(77)
end
local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))
local vol = cdvr.generate("sphere", {dims = {45, 38, 31}, timesteps = 2, radius = 0.6})
local st = cdvr.encode(vol, {path = tmp .. "/c.cdv", progress = false, levels = 3,
                             bricks = {3, 2, 2},
                             variants = {{codec = "raw", name = "raw"}, {S = 4, T = 2, name = "pvtc"},
                                         {codec = "hvq", name = "hvq"}}})
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {60, 1, .6, .2, .3}, {255, 1, 1, 1, .9}}
local near = cdvr.orbit_camera(vol, {azimuth = 35, elevation = 20, width = 48, height = 40})

for _, variant in ipairs{"raw", "pvtc", "hvq"} do
  for t = 1, 2 do
    local o = {t = t, variant = variant, tf = tf, camera = near, device = "cl"}
    local dense = cdvr.render(st, o)
    o.cache, o.lod_error, o.budget_mb = true, 0, 64
    local img, stats = cdvr.render(st, o)
    local c = cdvr.compare(img, dense)
    assert(c.maxerr == 0, ("%s t=%d: cache at level 0 differs from the dense render by %g"):format(
           variant, t, c.maxerr))
    assert(stats.bricks_level0 == 12 and stats.bricks_level1 == 0 and stats.bricks_level2 == 0,
           "every brick at level 0")
    assert(stats.cache_path == "march", "the brick march by default: " .. tostring(stats.cache_path))
    o.fetch = "sample" -- the page table on every device
    local img2, stats2 = cdvr.render(st, o)
    assert(stats2.cache_path == "page_table" and cdvr.compare(img2, dense).maxerr == 0,
           "the page-table path equals the dense render too")
    o.fetch = "bulk"
    local img3, stats3 = cdvr.render(st, o)
    assert(stats3.cache_path == "dense" and cdvr.compare(img3, dense).maxerr == 0,
           "the assembled dense frame equals the dense render too")
    o.fetch = nil
    for _, look in ipairs{{skip = false}, {shade = true}, {blend = "max"},
                          {gradient_opacity = {{0, 0}, {20, 1}}}} do
      local a = {t = t, variant = variant, tf = tf, camera = near, device = "cl"}
      for k, val in pairs(look) do a[k] = val end
      local ref_look = cdvr.render(st, a)
      a.cache, a.lod_error, a.budget_mb = true, 0, 64
      local got = cdvr.render(st, a)
      local key = next(look)
      assert(cdvr.compare(got, ref_look).maxerr == 0, ("%s t=%d %s: the march differs from the "
             .. "dense render by %g"):format(variant, t, key, cdvr.compare(got, ref_look).maxerr))
    end
    assert(stats.resident_bytes >= 45 * 38 * 31 and stats.resident_bytes <= 64e6, "resident bytes")
    -- the CPU reference renders the same voxels (the cache's C fetch over every voxel)
    local ref = cdvr.render(st:decode(t, variant), {tf = tf, camera = near, device = "cpu"})
    assert(cdvr.compare(img, ref).psnr >= 50, "cl cache against the cpu reference")
    local cpu, cs = cdvr.render(st, {t = t, variant = variant, tf = tf, camera = near,
                                     device = "cpu", cache = true, lod_error = 0, budget_mb = 64})
    assert(cdvr.compare(cpu, ref).maxerr == 0 and cs.bricks_level0 == 12,
           "cpu through the cache at level 0 equals the cpu render of the store")
  end
end

-- far away, lod_error 1: coarser levels; still the whole volume covered (no holes: every
-- brick has a level)
local far = cdvr.camera{eye = {22 + 400, 19, 15}, center = {22, 19, 15}, up = {0, 0, 1},
                        fov = 30, width = 48, height = 40}
local _, fs = cdvr.render(st, {variant = "raw", tf = tf, camera = far, device = "cl", cache = true,
                                lod_error = 1, budget_mb = 64})
assert(fs.bricks_level2 == 12, "far bricks at the coarsest level: " .. tostring(fs.bricks_level2))

-- a budget that does not hold level 0: the farthest bricks coarsen until it fits
local full = cdvr.render(st, {variant = "raw", tf = tf, camera = near, device = "cl"})
local budget = 0.5 * 45 * 38 * 31 / 1e6
local img, bs = cdvr.render(st, {variant = "raw", tf = tf, camera = near, device = "cl",
                                 cache = true, lod_error = 0, budget_mb = budget})
assert(bs.resident_bytes <= budget * 1e6, "resident within the budget: " .. bs.resident_bytes)
assert(bs.cache_path == "march", "the brick march")
assert(bs.bricks_level0 > 0 and bs.bricks_level0 < 12, "some bricks coarser, the near ones fine")
local psnr = cdvr.compare(img, full).psnr
local paged, ps = cdvr.render(st, {variant = "raw", tf = tf, camera = near, device = "cl",
                                   cache = true, lod_error = 0, budget_mb = budget,
                                   fetch = "sample"})
local march_vs_page = cdvr.compare(img, paged).psnr
assert(ps.bricks_level0 == bs.bricks_level0 and march_vs_page >= 30,
       "the march's coarse bricks against the page table's upsampled voxels: " .. march_vs_page)
assert(bs.samples < ps.samples, ("coarse bricks take fewer samples: %d against %d"):format(
       bs.samples, ps.samples))
-- skipping on and off agree at coarse levels up to where the groups start; max blend
local lod_o = {variant = "raw", tf = tf, camera = near, device = "cl", cache = true, lod_error = 0,
               budget_mb = budget, skip = false}
local noskip = cdvr.render(st, lod_o)
local skip_vs_noskip = cdvr.compare(img, noskip).psnr
assert(skip_vs_noskip >= 40, "coarse march, skipping on against off: " .. skip_vs_noskip)
lod_o.skip, lod_o.blend = nil, "max"
local mip = cdvr.render(st, lod_o)
lod_o.fetch = "sample"
local mip_paged = cdvr.render(st, lod_o)
local mip_psnr = cdvr.compare(mip, mip_paged).psnr
assert(mip_psnr >= 30, "coarse max blend, march against page table: " .. mip_psnr)
local ok_bulk, bulk_err = pcall(cdvr.render, st, {variant = "raw", tf = tf, camera = near,
                                device = "cl", cache = true, lod_error = 0, budget_mb = budget,
                                fetch = "bulk"})
assert(ok_bulk, bulk_err)
local cpu_lod, cs = cdvr.render(st, {variant = "raw", tf = tf, camera = near, device = "cpu",
                                     cache = true, lod_error = 0, budget_mb = budget})
local cpu_vs_cl = cdvr.compare(cpu_lod, img).psnr
assert(cs.bricks_level0 == bs.bricks_level0 and cpu_vs_cl >= 30,
       "cpu and cl through the cache pick the same levels and agree: " .. cpu_vs_cl)
assert(cdvr.compare(cpu_lod, paged).psnr >= 50, "cpu and cl's page table agree")
assert(psnr > 20, "coarser far bricks stay close to the full render: " .. psnr)
local ok, err = pcall(cdvr.render, st, {variant = "raw", tf = tf, camera = near, device = "cl",
                                        cache = true, budget_mb = 0.0001})
assert(not ok and err:find("coarsest level"), "a budget below the coarsest level: " .. tostring(err))
-- the player through the cache: rows report resident bytes and bricks per level, and at
-- lod_error 0 with room for everything it plays exactly the frames of the player without it
local function slurp(file)
  local fh = assert(io.open(file, "rb"))
  local data = fh:read("a")
  fh:close()
  return data
end
for _, cached in ipairs{false, true} do
  local out = ("%s/p_%s_%%d.png"):format(tmp, tostring(cached))
  local p = cdvr.player{store = st, tf = tf, camera = near, device = "cl", variant = "pvtc",
                        cache = cached, lod_error = 0, budget_mb = 64, out = out}
  local r = p:run{frames = 2}
  for i, row in ipairs(r.frames) do
    assert(not row.error, row.error)
    if cached then
      assert(row.resident_bytes > 0 and row.resident_bytes <= 64e6 and row.bricks_level0 == 12
             and row.bricks_level2 == 0, "player row: resident bytes and bricks per level")
      assert(slurp(out:format(i)) == slurp((tmp .. "/p_false_%d.png"):format(i)),
             "player frame " .. i .. " through the cache equals the frame without it")
    else
      assert(row.resident_bytes == nil, "no cache figures without the cache")
    end
  end
  p:close()
end
local small = cdvr.player{store = st, tf = tf, camera = near, device = "cl", variant = "raw",
                          cache = true, lod_error = 0, budget_mb = budget}
local sr = small:run{frames = 2}
assert(sr.frames[1].bricks_level0 < 12 and sr.frames[1].resident_bytes <= budget * 1e6,
       "the player's cache keeps to the budget")
small:close()
-- the cpu device plays through the cache too: tests/lua/test_player_cache.lua
cdvr.player{store = st, tf = tf, device = "cpu", cache = true}:close()
st:close()
os.execute(("rm -rf %q"):format(tmp))
print(("test_brick_cache: ok (budget %.3f MB: %d/%d/%d bricks at levels 0/1/2, %.1f dB against "
       .. "the full render, march against page table %.1f dB, against cpu %.1f dB, samples "
       .. "%d against %d, skipping on against off %.1f dB, max blend against page table %.1f dB)"):format(
       budget, bs.bricks_level0, bs.bricks_level1, bs.bricks_level2, psnr, march_vs_page,
       cpu_vs_cl, bs.samples, ps.samples, skip_vs_noskip, mip_psnr))
