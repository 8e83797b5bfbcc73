-- Multi-resolution stores (issue 26 item 1; store.h, core/store/levels.c): cdvr.encode with
-- levels= and level_variants= writes each level with the documented dims, spacing and tent
-- filter (checked voxel for voxel against a Lua reimplementation of the rule through a raw
-- variant), its own codec per level, the brick grid capped per level, and the error against
-- level 0 (checked against a Lua trilinear upsampling); st:info().levels lists them; the
-- file reopens; a corrupt level directory is refused; stores without levels list one level.
local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))
local path = tmp .. "/levels.cdv"

local X, Y, Z, T = 13, 10, 7, 2
local vol = cdvr.volume{dims = {X, Y, Z}, type = "u8", timesteps = T}
for t = 1, T do
  for z = 0, Z - 1 do for y = 0, Y - 1 do for x = 0, X - 1 do
    vol:set(x, y, z, t, (x * 37 + y * 11 + z * 53 + t * 71 + (x * y * z) % 17) % 256)
  end end end
end

local st = cdvr.encode(vol, {path = path, progress = false, levels = 3, bricks = {3, 2, 1},
  variants = {{codec = "raw", name = "exact"}, {codec = "pvtc", S = 1, T = 2, name = "lossy"}},
  level_variants = {{{codec = "raw"}, {codec = "raw"}},
                    {{codec = "raw"}, {codec = "pvtc", S = 4, T = 2}}}})

-- the level rule: n -> n // 2 + 1 (1 stays 1); tent (1 2 1)/4 at 2i, clamped, (sum + 32) >> 6
local function down(get, dims)
  local d = {}
  for a = 1, 3 do d[a] = dims[a] > 1 and dims[a] // 2 + 1 or 1 end
  local out = {}
  local function c(i, n) return i < 0 and 0 or (i >= n and n - 1 or i) end
  for k = 0, d[3] - 1 do for j = 0, d[2] - 1 do for i = 0, d[1] - 1 do
    local sum = 0
    for dz = -1, 1 do for dy = -1, 1 do for dx = -1, 1 do
      local w = (dx == 0 and 2 or 1) * (dy == 0 and 2 or 1) * (dz == 0 and 2 or 1)
      sum = sum + w * get(c(2 * i + dx, dims[1]), c(2 * j + dy, dims[2]), c(2 * k + dz, dims[3]))
    end end end
    out[i + d[1] * (j + d[2] * k)] = (sum + 32) >> 6
  end end end
  return out, d
end

local info = st:info()
assert(#info.levels == 3, "three levels listed")
local want_dims = {{13, 10, 7}, {7, 6, 4}, {4, 4, 3}}
for l = 0, 2 do
  local li = info.levels[l + 1]
  assert(li.level == l, "level numbers from 0")
  for a = 1, 3 do
    assert(li.dims[a] == want_dims[l + 1][a], ("level %d dims %d"):format(l, a))
    assert(li.spacing[a] == 2 ^ l, "spacing doubles per level")
  end
  assert(li.bytes > 0 and li.bytes == li.variants[1].bytes + li.variants[2].bytes, "bytes add up")
  assert(li.variants[1].name == "exact" and li.variants[2].name == "lossy", "names of level 0")
end
assert(info.levels[2].brick_grid[1] == 3 and info.levels[3].brick_grid[1] == 3 and
       info.levels[3].brick_grid[2] == 2, "brick grids: each axis capped at the level's cells")
assert(info.levels[3].variants[2].codec == "pvtc" and info.levels[2].variants[2].codec == "raw",
       "a codec per level")
assert(info.levels[1].variants[1].psnr == math.huge and info.levels[1].variants[1].maxerr == 0,
       "level 0 raw is exact")

-- the raw levels hold exactly the filtered source, level by level
for t = 1, T do
  local prev = function(x, y, z) return vol:get(x, y, z, t) end
  local dims = {X, Y, Z}
  for l = 1, 2 do
    local ref, d = down(prev, dims)
    local lv = st:level(l)
    local dec = lv:decode(t, "exact")
    local dx, dy, dz = dec:dims()
    assert(dx == d[1] and dy == d[2] and dz == d[3], "decoded level dims")
    for k = 0, d[3] - 1 do for j = 0, d[2] - 1 do for i = 0, d[1] - 1 do
      assert(dec:get(i, j, k) == ref[i + d[1] * (j + d[2] * k)],
             ("level %d t %d voxel %d %d %d"):format(l, t, i, j, k))
    end end end
    local dd = d
    prev = function(x, y, z) return ref[x + dd[1] * (y + dd[2] * z)] end
    dims = d
  end
end

-- the error against level 0: the level upsampled trilinearly (x / 2^l), max over everything
for l = 1, 2 do
  local maxerr = 0
  for t = 1, T do
    local dec = st:level(l):decode(t, "exact")
    local cx, cy, cz = dec:dims()
    local s = 1 / 2 ^ l
    local function lerp(a, b, f) return a + f * (b - a) end
    for z = 0, Z - 1 do for y = 0, Y - 1 do for x = 0, X - 1 do
      local gx, gy, gz = x * s, y * s, z * s
      local x0, y0, z0 = math.floor(gx), math.floor(gy), math.floor(gz)
      local x1, y1, z1 = math.min(x0 + 1, cx - 1), math.min(y0 + 1, cy - 1), math.min(z0 + 1, cz - 1)
      local fx, fy, fz = gx - x0, gy - y0, gz - z0
      local function g(i, j, k) return dec:get(i, j, k) end
      local v = lerp(lerp(lerp(g(x0, y0, z0), g(x1, y0, z0), fx), lerp(g(x0, y1, z0), g(x1, y1, z0), fx), fy),
                     lerp(lerp(g(x0, y0, z1), g(x1, y0, z1), fx), lerp(g(x0, y1, z1), g(x1, y1, z1), fx), fy), fz)
      maxerr = math.max(maxerr, math.abs(v - vol:get(x, y, z, t)))
    end end end
  end
  local got = info.levels[l + 1].variants[1]
  assert(math.abs(got.maxerr - maxerr) < 1e-3, ("level %d maxerr %g, expected %g"):format(l, got.maxerr, maxerr))
  assert(got.psnr > 0 and got.psnr < math.huge, "finite PSNR")
end

-- reopening gives the same levels; level 0 of st:level is the store
st:close()
st = cdvr.open(path)
local again = st:info()
assert(#again.levels == 3 and again.levels[3].bytes == info.levels[3].bytes, "reopened")
assert(cdvr.compare(st:level(0):decode(1, "lossy"), st:decode(1, "lossy")).maxerr == 0, "level 0")
assert(not pcall(st.level, st, 3) and not pcall(st.level, st, -1), "levels out of range")
local img = cdvr.render(st:level(2), {tf = cdvr.tf("hot"), device = "cpu",
                                     camera = cdvr.orbit_camera(vol, {width = 16, height = 16})})
assert(img, "a level renders as a store")

-- a corrupt level directory is refused
st:close()
local f = assert(io.open(path, "rb"))
local bytes = f:read("a")
f:close()
local bad = tmp .. "/bad.cdv"
local pos = #bytes - 6
f = assert(io.open(bad, "wb"))
f:write(bytes:sub(1, pos - 1), string.char((bytes:byte(pos) + 1) % 256), bytes:sub(pos + 1))
f:close()
local ok, err = pcall(cdvr.open, bad)
assert(not ok and err:find("level directory"), "corrupt directory: " .. tostring(err))

-- stores without levels (today's and the old fixtures) list one level
local data = os.getenv("CDVR_SOURCE_DIR")
for _, name in ipairs{"v1_store.cdv", "v2_lzo_store.cdv"} do
  local p = (data or ".") .. "/tests/data/" .. name
  local fh = io.open(p, "rb")
  if fh then
    fh:close()
    local old = cdvr.open(p)
    local oi = old:info()
    assert(#oi.levels == 1 and oi.levels[1].dims[1] == oi.dims[1], name .. ": one level")
    old:close()
  end
end
local plain = cdvr.encode(vol, {path = tmp .. "/plain.cdv", progress = false, codec = "raw"})
assert(#plain:info().levels == 1, "a store without levels= has one level")
assert(not pcall(cdvr.encode, vol, {path = tmp .. "/x.cdv", levels = 17}), "levels <= 16")
assert(not pcall(cdvr.encode, vol, {path = tmp .. "/x.cdv", levels = 2, level_variants = {}}),
       "level_variants must list levels - 1 lists")
plain:close()
os.execute(("rm -rf %q"):format(tmp))
print("test_store_levels: ok")
