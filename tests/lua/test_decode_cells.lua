-- tests/lua/test_decode_cells.lua - the player's decode of only the cells a composite render
-- reads (player.h decode_whole, codec.h decode_cells; zfp implements it) gives the very frames
-- of the whole-frame decode: real data with empty space (neghip, dims 66 = not a multiple of
-- zfp's 4^3 blocks; the 25-timestep ASL MRI series, so a decode slot holds another timestep's
-- voxels outside the decoded cells), unshaded and shaded (gradients read one voxel further),
-- several cameras (inside the volume too), range tables of 4^3 and 16^3 bricks, and hvq decoded on
-- the host (fetch="bulk"). Each case checks
-- that only part of the frame was decoded (decoded_share below 1), so the partial path ran,
-- and that it took no more samples than the whole decode (fewer with 16^3 tables where the
-- frame is dense: the partial decode refines the visible bricks' ranges, cdvr_skip_refine;
-- tests/test_cl_layouts.sh runs this file with dense frames).
-- Max and iso renders decode whole frames. cdvr.render of a store chunk on cl decodes by cells
-- too (cdvr/visible.h; its section below). Skips (77) without OpenCL or the zfp plugin.
local have_zfp = false
for _, c in ipairs(cdvr.codecs()) do have_zfp = have_zfp or c.name == "zfp" end
if not have_zfp or not cdvr.cl_info() then
  print("skip: needs OpenCL and the zfp plugin")
  os.exit(77)
end

local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check = checks.check

local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))

local function read(path)
  local f = assert(io.open(path, "rb"))
  local s = f:read("a")
  f:close()
  return s
end

-- plays `frames` frames of the zfp variant with decode_whole false and true and compares the
-- captured PNGs byte for byte; returns the partial run's largest decoded_share, its shares
-- and the samples each run took (cells, whole)
local function compare(name, st, opts, frames)
  local shares, samples = {}, {cells = 0, whole = 0}
  for _, whole in ipairs{false, true} do
    local o = {store = st, variant = "zfp", device = "cl", decode_whole = whole, pace = false,
               out = ("%s/%s_%s_%%03d.png"):format(tmp, name, whole and "whole" or "cells")}
    for k, v in pairs(opts) do o[k] = v end
    local p = cdvr.player(o)
    local r = p:run{frames = frames}
    p:close()
    for i, row in ipairs(r.frames) do
      check(not row.error, name .. ": " .. tostring(row.error))
      if not whole then shares[i] = row.decoded_share end
      samples[whole and "whole" or "cells"] = samples[whole and "whole" or "cells"] + row.samples
      if whole then check(row.decoded_share == 1, name .. ": whole decode share " .. row.decoded_share) end
    end
  end
  local most = 0
  for i = 1, frames do
    local a = read(("%s/%s_cells_%03d.png"):format(tmp, name, i))
    local b = read(("%s/%s_whole_%03d.png"):format(tmp, name, i))
    check(a == b, ("%s: frame %d differs from the whole-frame decode (decoded share %.3f)"):format(
      name, i, shares[i] or -1))
    most = math.max(most, shares[i] or 1)
  end
  -- a dense frame decoded in part gets the exact ranges of the bricks that coarser tables
  -- kept visible (cdvr_skip_refine): never more samples than the whole decode's grid from
  -- the tables
  check(samples.cells <= samples.whole, ("%s: %d samples, the whole decode %d"):format(
    name, samples.cells, samples.whole))
  return most, shares, samples
end
local dense = cdvr.cl_info().frames == "dense"

local data = os.getenv("CDVR_SOURCE_DIR") or "."
local function share_data(file)
  for _, dir in ipairs{data .. "/share/data/", "../share/data/", "share/data/"} do
    local f = io.open(dir .. file)
    if f then f:close() return dir .. file end
  end
  error("share/data/" .. file .. " not found")
end

-- neghip: one timestep, two range-table brick sizes, shaded and not, three cameras
local neghip = cdvr.load(share_data("neghip_66x66x66_u8.nrrd"))
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {60, 0.9, 0.4, 0.1, 0}, {120, 1, 0.8, 0.3, 0.2}, {255, 1, 1, 1, 0.9}}
local c = 32.5
local cams = {
  cdvr.camera{eye = {c + 150, c - 90, c + 80}, center = {c, c, c}, up = {0, 0, 1}, fov = 30, width = 64, height = 64},
  cdvr.camera{eye = {c - 20, c + 170, c - 60}, center = {c, c, c}, up = {1, 0, 0}, fov = 25, width = 48, height = 56},
  cdvr.camera{eye = {c + 5, c - 3, c + 2}, center = {c + 40, c, c}, up = {0, 0, 1}, fov = 60, width = 40, height = 40},
}
for _, shift in ipairs{2, 4} do
  local st = assert(cdvr.encode(neghip, {path = ("%s/neghip%d.cdv"):format(tmp, shift), progress = false,
    range_brick = 1 << shift, variants = {{codec = "zfp", rate = 2, name = "zfp"}}}))
  for ci, cam in ipairs(cams) do
    for _, shade in ipairs{false, true} do
      local name = ("neghip_b%d_c%d_%s"):format(shift, ci, shade and "shaded" or "plain")
      local most, _, samples = compare(name, st, {tf = tf, camera = cam, shade = shade}, 1)
      check(most < 1 and most > 0, name .. ": decoded share " .. most .. " (expected part of the frame)")
      -- 16^3 tables seen from outside, decoded into a dense frame (not a shaded render, which
      -- casts from tiles): their bricks refined to 4^3 skip more
      check(not dense or shade or shift == 2 or ci == 3 or samples.cells < samples.whole,
            ("%s: %d samples, as many as the whole decode's"):format(name, samples.cells))
    end
  end
  -- a TF transparent below and above a band: with 4^3 tables the invisible bricks' ranges lie
  -- on both sides of it, no fill keeps all their samples transparent, so the frame is decoded
  -- whole (with 16^3 tables every invisible brick lies below the band: decoded in part)
  local band = cdvr.tf{{0, 0, 0, 0, 0}, {70, 1, 0.5, 0.2, 0}, {100, 1, 0.8, 0.3, 0.4},
                       {130, 1, 1, 1, 0}, {255, 1, 1, 1, 0}}
  local bname = ("neghip_b%d_band"):format(shift)
  local most = compare(bname, st, {tf = band, camera = cams[1]}, 1)
  check(shift ~= 2 or most == 1, bname .. ": decoded share " .. most .. " (expected whole)")
  -- max and iso read other bricks than the TF's visible ones: whole frames
  for _, look in ipairs{{blend = "max"}, {iso = {value = 100}}} do
    local o = {store = st, variant = "zfp", device = "cl", tf = tf, camera = cams[1], pace = false}
    for k, v in pairs(look) do o[k] = v end
    local p = cdvr.player(o)
    local r = p:run{frames = 1}
    p:close()
    check(r.frames[1].decoded_share == 1, "max/iso: whole frames, share " .. r.frames[1].decoded_share)
  end
end

-- hvq (a fetch-mode codec) decoded on the host (fetch="bulk"): blocks and residual voxels of
-- the needed cells, tiled, against its whole decode
do
  local st = assert(cdvr.encode(neghip, {path = tmp .. "/neghip_hvq.cdv", progress = false,
    variants = {{codec = "hvq", name = "zfp"}}})) -- named "zfp" for compare()
  for _, shade in ipairs{false, true} do
    local name = "hvq_" .. (shade and "shaded" or "plain")
    local most = compare(name, st, {tf = tf, camera = cams[1], shade = shade, fetch = "bulk"}, 1)
    check(most < 1 and most > 0, name .. ": decoded share " .. most .. " (expected part of the frame)")
  end
end

-- cdvr.render of a store chunk on cl (cdvr/visible.h): zfp (no device code) and hvq on its
-- bulk path decode only the cells the render reads, into a linear frame whose grid is refined:
-- the image of the decoded volume's render, byte for byte, with no more samples; a TF whose
-- fill cannot be transparent, max, skip=false and hvq's per-sample fetch decode whole frames
-- (no decoded_share in the stats). The ASL series is rendered timestep by timestep below,
-- each decode reusing the frame that held another timestep.
local function render_cells(name, st, variant, opts, expect_cells)
  local o = {variant = variant, device = "cl"}
  for k, v in pairs(opts) do o[k] = v end
  local img, stats = cdvr.render(st, o)
  o.variant, o.fetch, o.t = nil, nil, nil
  local ref, ref_stats = cdvr.render(st:decode(opts.t or 1, variant), o)
  check(cdvr.compare(img, ref).maxerr == 0, name .. ": differs from the decoded volume's render")
  if expect_cells == nil then -- either path (the frame's TF decides): the same image
    return stats.decoded_share or 1
  elseif expect_cells then
    check(stats.decoded_share and stats.decoded_share > 0 and stats.decoded_share < 1,
          name .. ": decoded share " .. tostring(stats.decoded_share) .. " (expected part)")
    check(stats.samples <= ref_stats.samples, ("%s: %d samples, the decoded volume %d"):format(
      name, stats.samples, ref_stats.samples))
  else
    check(stats.decoded_share == nil, name .. ": decoded by cells (share " ..
          tostring(stats.decoded_share) .. "), expected whole")
  end
end
for _, shift in ipairs{2, 4} do
  local st = cdvr.open(("%s/neghip%d.cdv"):format(tmp, shift))
  for ci, cam in ipairs(cams) do
    for _, shade in ipairs{false, true} do
      render_cells(("render_b%d_c%d_%s"):format(shift, ci, shade and "shaded" or "plain"), st,
                   "zfp", {tf = tf, camera = cam, shade = shade}, true)
    end
  end
  local band = cdvr.tf{{0, 0, 0, 0, 0}, {70, 1, 0.5, 0.2, 0}, {100, 1, 0.8, 0.3, 0.4},
                       {130, 1, 1, 1, 0}, {255, 1, 1, 1, 0}}
  render_cells(("render_b%d_band"):format(shift), st, "zfp", {tf = band, camera = cams[1]},
               shift ~= 2)
  render_cells(("render_b%d_max"):format(shift), st, "zfp", {tf = tf, camera = cams[1], blend = "max"}, false)
  render_cells(("render_b%d_noskip"):format(shift), st, "zfp", {tf = tf, camera = cams[1], skip = false}, false)
end
do
  local st = cdvr.open(tmp .. "/neghip_hvq.cdv")
  for _, shade in ipairs{false, true} do
    render_cells("render_hvq_" .. (shade and "shaded" or "plain"), st, "zfp",
                 {tf = tf, camera = cams[1], shade = shade, fetch = "bulk"}, true)
  end
  render_cells("render_hvq_sample", st, "zfp", {tf = tf, camera = cams[1], fetch = "sample"}, false)
end

-- the ASL series: 25 timesteps played in turn, each slot reused with other voxels
local asl = cdvr.load(share_data("mpld_asl_64x64x24x25_f32.nii.gz"))
local st = assert(cdvr.encode(asl, {path = tmp .. "/asl.cdv", progress = false,
  variants = {{codec = "zfp", rate = 1, name = "zfp"}}}))
local atf = cdvr.tf{{0, 0, 0, 0, 0}, {90, 0.2, 0.3, 0.9, 0}, {160, 0.9, 0.8, 0.3, 0.3}, {255, 1, 1, 1, 0.9}}
local acam = cdvr.orbit_camera(asl, {azimuth = 35, elevation = 25, width = 64, height = 64})
for _, shade in ipairs{false, true} do
  local name = "asl_" .. (shade and "shaded" or "plain")
  local most, shares = compare(name, st, {tf = atf, camera = acam, shade = shade}, 25)
  local least = 1
  for _, s in ipairs(shares) do least = math.min(least, s) end
  check(least < 1, name .. ": every frame decoded whole (least share " .. least .. ")")
end
local least = 1
for t = 1, 25 do
  least = math.min(least, render_cells("render_asl_t" .. t, st, "zfp", {t = t, tf = atf, camera = acam}, nil))
end
check(least < 1, "render_asl: every timestep decoded whole")

os.execute(("rm -rf %q"):format(tmp))
checks.finish()
