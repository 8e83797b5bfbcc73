-- tests/lua/test_stage2.lua: stage 2 beyond LZO from Lua (cdvr.encode stage2 = "none", "lzo",
-- "lz4", "zstd", "auto"; stage2_read_mbps=, stage2_segment=): every choice decodes to the same
-- voxels as no stage 2, the chunk listing names each chunk's codec, the variant counts them,
-- auto is the default and deterministic (cdvr.stage2_rates; its disk rate, by default the
-- store's filesystem's, measured once), and bad values raise listing the valid ones.
local failures = 0
local function check(cond, msg)
  if not cond then
    failures = failures + 1
    io.stderr:write("FAIL: ", msg, "\n", debug.traceback(), "\n")
  end
end
local function raises(pattern, f, ...)
  local ok, err = pcall(f, ...)
  check(not ok, "expected an error matching " .. pattern)
  check(ok or tostring(err):find(pattern, 1, true), "error '" .. tostring(err) .. "' lacks '" .. pattern .. "'")
end
local dir = os.tmpname()
os.remove(dir)
assert(os.execute("mkdir -p " .. dir))
local function tmp(name) return dir .. "/" .. name end

local src = cdvr.generate("sphere", {dims = {40, 36, 30}, timesteps = 4})
local ref = cdvr.encode(src, {path = tmp("none.cdv"), progress = false, variants = {
  {codec = "raw", stage2 = "none"}, {S = 4, T = 3, stage2 = "none"}}})
for _, s2 in ipairs({"none", "lzo", "lz4", "zstd", "auto"}) do
  local st = cdvr.encode(src, {path = tmp(s2 .. ".cdv"), progress = false, stage2 = s2,
                               lzo_min_saving = 0, stage2_segment = 4096, stage2_read_mbps = 200,
                               variants = {{codec = "raw"}, {S = 4, T = 3}}})
  local info = st:info()
  for v = 1, 2 do
    local vi = info.variants[v]
    check(vi.stage2 == s2, ("variant %d stage2 %s, asked %s"):format(v, tostring(vi.stage2), s2))
    check(vi.stage2_segment == 4096 and vi.stage2_read_mbps == 200, s2 .. ": recorded options")
    local counted = 0
    for _, c in ipairs({"none", "lzo", "lz4", "zstd"}) do counted = counted + vi.stage2_chunks[c] end
    check(counted == vi.chunks, s2 .. ": stage2_chunks add up to the chunks")
    for c = 1, vi.chunks do
      local _, ch = st:chunk(c, v)
      if s2 ~= "auto" then
        check(ch.stage2_codec == s2 or ch.stage2_codec == "none", s2 .. ": chunk codec " .. ch.stage2_codec)
      end
      check(ch.stage2 == (ch.stage2_codec ~= "none"), s2 .. ": stage2 flag")
      if ch.stage2_codec == "lz4" or ch.stage2_codec == "zstd" then
        check(ch.stage2_segmented, s2 .. ": lz4/zstd chunks are segmented")
      end
    end
    if s2 ~= "none" and s2 ~= "auto" and v == 1 then
      check(vi.stage2_chunks[s2] > 0 and vi.bytes < vi.payload_bytes, s2 .. ": raw sphere compresses")
    end
    for t = 1, 4 do
      check(cdvr.compare(st:decode(t, v), ref:decode(t, v)).mse == 0,
            ("%s variant %d t %d: decodes as without stage 2"):format(s2, v, t))
    end
  end
  st:close()
end
-- auto with a very slow disk packs (everything saves reading); with a very fast one the
-- unpack costs more than the read it saves, so it keeps the chunk as it is
local slow = cdvr.encode(src, {path = tmp("slow.cdv"), progress = false, codec = "raw", stage2 = "auto",
                               stage2_read_mbps = 0.001})
check(slow:info().variants[1].stage2_chunks.none == 0, "auto at 1 kB/s packs every chunk")
local fast = cdvr.encode(src, {path = tmp("fast.cdv"), progress = false, codec = "raw", stage2 = "auto",
                               stage2_read_mbps = 1e11})
check(fast:info().variants[1].stage2_chunks.none == fast:info().variants[1].chunks,
      "auto at 10^11 MB/s packs nothing")

-- auto is the default, and follows this machine's remembered unpack rates only: the
-- default encode equals an explicit auto one byte for byte
local rates = cdvr.stage2_rates()
check(rates.lzo > 0 and rates.lz4 > 0 and rates.zstd > 0 and rates.from_cache == true,
      ("stage2_rates: lzo %s lz4 %s zstd %s, remembered %s"):format(tostring(rates.lzo),
       tostring(rates.lz4), tostring(rates.zstd), tostring(rates.from_cache)))
local again = cdvr.stage2_rates()
check(again.lzo == rates.lzo and again.lz4 == rates.lz4 and again.zstd == rates.zstd, "rates remembered")
local function bytes(path)
  local f = assert(io.open(path, "rb"))
  local b = f:read("a")
  f:close()
  return b
end
local plain = cdvr.encode(src, {path = tmp("default.cdv"), progress = false, stage2_segment = 4096,
                                variants = {{codec = "raw"}, {S = 4, T = 3}}})
check(plain:info().variants[1].stage2 == "auto", "stage2 defaults to auto")
-- without stage2_read_mbps= auto models the rate the player will read the store at: this
-- small series fits in memory, so the page cache's of the store's filesystem, measured once
-- and remembered (cdvr.stage2_rates(path)), and records it
local disk = cdvr.stage2_rates(tmp("default.cdv"))
check(disk.read_disk and disk.read_disk >= 1 and disk.read_cache >= 1 and disk.read_from_cache == true,
      ("stage2_rates(path): disk %s cache %s MB/s, remembered %s"):format(tostring(disk.read_disk),
       tostring(disk.read_cache), tostring(disk.read_from_cache)))
check(plain:info().variants[1].stage2_read_mbps == disk.read_cache,
      ("the default store records the page cache's %s MB/s: %s"):format(tostring(disk.read_cache),
       tostring(plain:info().variants[1].stage2_read_mbps)))
check(rates.read_disk == nil, "stage2_rates() without a path measures no disk")
raises("/nonexistent-cdvr-dir", cdvr.stage2_rates, "/nonexistent-cdvr-dir/x.cdv")
plain:close()
cdvr.encode(src, {path = tmp("auto2.cdv"), progress = false, stage2 = "auto", stage2_segment = 4096,
                  variants = {{codec = "raw"}, {S = 4, T = 3}}}):close()
check(bytes(tmp("default.cdv")) == bytes(tmp("auto2.cdv")), "two auto encodes write the same bytes")

raises("option 'stage2': invalid value 'brotli' (expected none, lzo, lz4, zstd, auto)", cdvr.encode, src,
       {path = tmp("x.cdv"), stage2 = "brotli"})
raises("option 'stage2': invalid value 'LZ4'", cdvr.encode, src, {path = tmp("x.cdv"), variants = {{stage2 = "LZ4"}}})
raises("option 'stage2_segment': 10 bytes is not in 64..1073741824", cdvr.encode, src,
       {path = tmp("x.cdv"), stage2_segment = 10})
raises("option 'stage2_read_mbps'", cdvr.encode, src, {path = tmp("x.cdv"), stage2_read_mbps = 0})
raises("option 'stage2_read_mbps'", cdvr.encode, src, {path = tmp("x.cdv"), variants = {{stage2_read_mbps = -5}}})
raises("option 'stage2_read_mbps'", cdvr.encode, src, {path = tmp("x.cdv"), stage2_read_mbps = "fast"})
raises("stage2_segmentz", cdvr.encode, src, {path = tmp("x.cdv"), stage2_segmentz = 4096})
os.execute("rm -rf " .. dir)
if failures > 0 then
  print(failures .. " failures")
  os.exit(1)
end
print("ok")
