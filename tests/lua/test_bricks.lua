-- Bricked stores end to end through Lua, for every registered codec: encode with bricks,
-- st:info() lists the grid and the boxes, the assembled decode matches the unbricked store's
-- quality (raw: exact), st:decode(t, v, {brick=b}) gives the brick's own voxels placed where
-- it lies, and reading one brick reads only its chunk (a corrupt chunk of another brick does
-- not disturb it).
local tmpdir = os.tmpname()
os.remove(tmpdir)
assert(os.execute(("mkdir -p %q"):format(tmpdir)))

local dims, T = {23, 19, 17}, 5
local vol = cdvr.generate("sphere", {dims = dims, timesteps = T})

-- Every codec the registry has (cdvr.codecs() once plugins register themselves), with the
-- PVTC parameter space spelled out: both packings, S in {1, 4}, T in {2, 3}.
local variants = {
  {codec = "raw"},
  {codec = "pvtc", S = 4, T = 3}, {codec = "pvtc", S = 1, T = 3},
  {codec = "pvtc", S = 4, T = 2}, {codec = "pvtc", S = 1, T = 2, pack = "space"},
  {codec = "pvtc", S = 4, T = 3, pack = "space"},
}
if cdvr.codecs then
  for _, c in ipairs(cdvr.codecs()) do
    local name = type(c) == "table" and c.name or c
    if name ~= "raw" and name ~= "pvtc" then variants[#variants + 1] = {codec = name} end
  end
end

local grid = {3, 2, 2}
local bricked = assert(cdvr.encode(vol, {variants = variants, bricks = grid, stage2 = "none",
                                         path = tmpdir .. "/b.cdv"}))
local whole = assert(cdvr.encode(vol, {variants = variants, stage2 = "none",
                                       path = tmpdir .. "/w.cdv"}))
local info = bricked:info()
assert(info.brick_grid[1] == 3 and info.brick_grid[2] == 2 and info.brick_grid[3] == 2)
assert(#info.bricks == 12, "12 bricks listed")
assert(#whole:info().bricks == 1 and whole:info().brick_grid[1] == 1, "unbricked = {1,1,1}")

-- the boxes tile the volume with a one-voxel overlap: every cell in exactly one brick
local owner = {}
for b, box in ipairs(info.bricks) do
  for a = 1, 3 do assert(box.dims[a] >= 2 and box.lo[a] + box.dims[a] <= dims[a]) end
  for z = box.lo[3], box.lo[3] + box.dims[3] - 2 do
    for y = box.lo[2], box.lo[2] + box.dims[2] - 2 do
      for x = box.lo[1], box.lo[1] + box.dims[1] - 2 do
        local k = x + dims[1] * (y + dims[2] * z)
        assert(not owner[k], "cell in two bricks")
        owner[k] = b
      end
    end
  end
end
local cells = 0
for _ in pairs(owner) do cells = cells + 1 end
assert(cells == (dims[1] - 1) * (dims[2] - 1) * (dims[3] - 1), "cells covered")

-- Does brick box own voxel (x, y, z)? The lower brick owns a shared boundary voxel.
local function owns(box, x, y, z)
  local p = {x, y, z}
  for a = 1, 3 do
    local lo, hi = box.lo[a], box.lo[a] + box.dims[a] - 1
    if p[a] > hi or p[a] < lo or (p[a] == lo and lo > 0) then return false end
  end
  return true
end

for vi, var in ipairs(info.variants) do
  assert(var.chunks == 12 * var.groups, var.name .. ": one chunk per brick and group")
  local wvar = whole:info().variants[vi]
  for t = 1, T do
    local full = bricked:decode(t, vi)
    local ref = whole:decode(t, vi)
    local err_b = cdvr.compare(full, vol:frame(t))
    if var.codec == "raw" then
      assert(err_b.psnr == math.huge, "raw bricked round trip is exact")
    else
      -- bricks are coded on their own: quality close to the unbricked store's
      local err_w = cdvr.compare(ref, vol:frame(t))
      assert(err_b.psnr >= math.min(err_w.psnr, 1e9) - 3, ("%s t=%d: bricked %.2f dB, whole %.2f dB"):format(
        var.name, t, err_b.psnr, err_w.psnr))
    end
    for b, box in ipairs(info.bricks) do
      local bv = bricked:decode(t, vi, {brick = b})
      local bd = {bv:dims()}
      assert(bd[1] == box.dims[1] and bd[2] == box.dims[2] and bd[3] == box.dims[3])
      local o = {bv:origin()}
      assert(o[1] == box.lo[1] and o[2] == box.lo[2] and o[3] == box.lo[3], "brick placed")
      for z = 0, bd[3] - 1 do
        for y = 0, bd[2] - 1 do
          for x = 0, bd[1] - 1 do
            local X, Y, Z = x + box.lo[1], y + box.lo[2], z + box.lo[3]
            if var.codec == "raw" or owns(box, X, Y, Z) then
              assert(bv:get(x, y, z) == full:get(X, Y, Z), ("%s t=%d brick %d voxel %d,%d,%d"):format(
                var.name, t, b, X, Y, Z))
            end
          end
        end
      end
    end
  end
  assert(wvar.psnr ~= nil)
end

-- misuse
local ok, msg = pcall(bricked.decode, bricked, 1, 1, {brick = 13})
assert(not ok and msg:find("brick 13 out of range"), msg)
ok, msg = pcall(bricked.decode, bricked, 1, 1, {brik = 1})
assert(not ok and msg:find("did you mean 'brick'"), msg)

-- Reading one brick reads only its chunk: flip a byte inside raw brick 5 of timestep 2.
do
  local ci = (2 - 1) * 12 + 5                     -- raw: one timestep per group
  local bytes, cinfo = bricked:chunk(ci, "raw")
  assert(cinfo.brick == 5 and cinfo.t0 == 2 and not cinfo.stage2)
  local f = assert(io.open(tmpdir .. "/b.cdv", "rb"))
  local data = f:read("a")
  f:close()
  local at = assert(data:find(bytes, 1, true))
  local pos = at + #bytes // 2
  f = assert(io.open(tmpdir .. "/bad.cdv", "wb"))
  f:write(data:sub(1, pos - 1), string.char(data:byte(pos) ~ 0x5a), data:sub(pos + 1))
  f:close()
  local bad = assert(cdvr.open(tmpdir .. "/bad.cdv"))
  for b = 1, 12 do
    if b ~= 5 then
      local good = bad:decode(2, "raw", {brick = b})
      assert(cdvr.compare(good, bricked:decode(2, "raw", {brick = b})).psnr == math.huge)
    end
  end
  ok, msg = pcall(bad.decode, bad, 2, "raw", {brick = 5})
  assert(not ok and msg:find("chunk " .. ci) and msg:find("bad.cdv", 1, true), msg)
  ok, msg = pcall(bad.decode, bad, 2, "raw")
  assert(not ok and msg:find("chunk " .. ci), msg)
  bad:close()
end

-- The player skips bricks a TF hides, with the same frames: a ramp along x, a TF that hides
-- its lower half; rows report bricks_read and bricks_skipped.
do
  local ramp = cdvr.generate("ramp", {dims = {33, 17, 9}, timesteps = 3})
  local st = assert(cdvr.encode(ramp, {codec = "raw", bricks = {4, 1, 1}, stage2 = "none",
                                       path = tmpdir .. "/ramp.cdv"}))
  local lo, hi = ramp:range()
  local mid = math.floor((lo + hi) / 2)
  local tf = cdvr.tf{{0, 0, 0, 0, 0}, {mid, 0, 0, 0, 0}, {mid + 1, 1, .6, .2, .05}, {255, 1, 1, 1, .4}}
  local cam = cdvr.orbit_camera(ramp, {azimuth = 30, elevation = 20, width = 40, height = 32})
  local function capture(skip, dir)
    local p = cdvr.player{store = st, tf = tf, camera = cam, device = "cpu", brick_skip = skip,
                          out = tmpdir .. "/" .. dir .. "/%02d.png"}
    local r = p:run{frames = 3}
    p:close()
    return r
  end
  local on, off = capture(true, "on"), capture(false, "off")
  for i = 1, 3 do
    local row = on.frames[i]
    assert(row.bricks_read + row.bricks_skipped == 4 and row.bricks_skipped >= 1,
           ("frame %d: %d read, %d skipped"):format(i, row.bricks_read, row.bricks_skipped))
    assert(off.frames[i].bricks_skipped == 0 and off.frames[i].bricks_read == 4)
    assert(on.frames[i].rank == 0 and on.frames[i].composite_ms == 0)
    local a = assert(io.open(("%s/on/%02d.png"):format(tmpdir, i), "rb")):read("a")
    local b = assert(io.open(("%s/off/%02d.png"):format(tmpdir, i), "rb")):read("a")
    assert(a == b, "brick skipping changed frame " .. i)
  end
  st:close()
end

bricked:close()
whole:close()
os.execute(("rm -rf %q"):format(tmpdir))
print("test_bricks: ok")
