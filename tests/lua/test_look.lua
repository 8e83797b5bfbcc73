-- tests/lua/test_look.lua - blend modes and shading from Lua (cdvr.render, cdvr.player), through
-- the method table.
-- Proves: the look options reach the renderers (shade, MIP, iso change the image; iso= implies
-- blend "iso"); the player's frames equal the renders of their timesteps alone for every look,
-- on a bricked store with brick skipping on, on the cpu and cl devices (shading reads the 26
-- neighbours of every brick it renders, so a skipped brick never feeds a gradient; max, min
-- and iso do not skip by the TF); bad and unsupported options are refused naming them;
-- cdvr.methods() lists raycast's blend modes and shading; the player refuses what bricks mode
-- cannot composite; on cl, skip=false turns off max, min and average's skipping (same image,
-- every sample read, as on cpu), and max and average between their entry and exit bounds (and
-- min, skipping brick by brick) give the image of skip=false from outside and inside a volume of
-- zeros around a hollow block.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises

local v = cdvr.load(cdvr.share_dir .. "/data/neghip_66x66x66_u8.nrrd")
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {60, 0, 0, 0, 0}, {120, 0.9, 0.6, 0.3, 0.5}, {255, 1, 1, 1, 1}}
local cam = cdvr.orbit_camera(v, {azimuth = 30, elevation = 20, width = 64, height = 64})
local devices = {"cpu"}
if cdvr.cl_info() then devices[2] = "cl" end

local function render(opts)
  local o = {tf = tf, camera = cam, device = "cpu"}
  for k, x in pairs(opts) do o[k] = x end
  return cdvr.render(v, o)
end

local plain = render{}
check(cdvr.compare(plain, render{shade = true}).psnr < 40, "shading changes the image")
check(cdvr.compare(plain, render{blend = "max"}).psnr < 40, "max changes the image")
local iso = render{iso = {value = 120, color = {0.9, 0.8, 0.6}}}
check(cdvr.compare(iso, render{blend = "iso", iso = {value = 120, color = {0.9, 0.8, 0.6}}}).psnr == math.huge,
      "iso= implies blend iso")
check(cdvr.compare(iso, render{iso = {value = 120, color = {0.9, 0.8, 0.6}}, shade = false}).psnr < 60,
      "iso surfaces are shaded unless shade=false")
local _, stats = render{shade = true, light = {dir = {1, 0, 0}}, specular = 0.5, specular_power = 20}
check(stats.method == "raycast" and stats.device == "cpu", "stats name method and device")

-- the player: every look, bricked store, skipping on: frames equal the renders alone
local path = os.tmpname()
local st = cdvr.encode(v, {variants = {{codec = "raw"}}, bricks = {4, 4, 4}, path = path})
local looks = {{}, {shade = true}, {shade = true, gradient_opacity = {{0, 0}, {30, 1}}},
               {blend = "max"}, {blend = "min"}, {blend = "average"}, {iso = {value = 120}}}
for _, dev in ipairs(devices) do
  for _, look in ipairs(looks) do
    local got
    local o = {store = st, tf = tf, camera = cam, device = dev, frame = function(_, img) got = img end}
    local r = {tf = tf, camera = cam, device = dev}
    local name = {}
    for k, x in pairs(look) do o[k] = x; r[k] = x; name[#name + 1] = k end
    local p = cdvr.player(o)
    local rep = p:run{frames = 1}
    p:close()
    local alone = cdvr.render(st:decode(1), r)
    local what = dev .. " " .. (table.concat(name, "+") ~= "" and table.concat(name, "+") or "plain")
    check(got and cdvr.compare(got, alone).psnr == math.huge,
          what .. ": the played frame equals the render alone (" .. (got and cdvr.compare(got, alone).psnr or "no frame") .. " dB)")
    check(rep.frames[1].error == nil, what .. ": no error " .. tostring(rep.frames[1].error))
  end
end
os.remove(path)

-- hvq in the compressed domain (cl reads every sample, gradients too, through its fetch)
if devices[2] then
  local hpath = os.tmpname()
  local hst = cdvr.encode(v, {variants = {{codec = "hvq"}}, path = hpath})
  for _, look in ipairs{{shade = true}, {blend = "max"}, {iso = {value = 120}}} do
    local a = cdvr.render(hst, {tf = tf, camera = cam, device = "cl", shade = look.shade, blend = look.blend, iso = look.iso})
    local b = cdvr.render(hst, {tf = tf, camera = cam, device = "cpu", shade = look.shade, blend = look.blend, iso = look.iso})
    check(cdvr.compare(a, b).psnr >= 50, "hvq on cl (fetch) against its cpu decode: " .. cdvr.compare(a, b).psnr .. " dB")
  end
  os.remove(hpath)
end

-- iso on cl skips the bricks that cannot hold the iso code (flags for the codes around it):
-- the same image and sample count as with skip=false, at whole, fractional and out-of-range
-- values, from three sides; a composite render after them is unchanged (its own flags)
if devices[2] then
  local before = render{device = "cl"}
  for _, az in ipairs{30, 150, 260} do
    local c = cdvr.orbit_camera(v, {azimuth = az, elevation = 20, width = 64, height = 64})
    for _, value in ipairs{40, 120, 120.5, 200, 300, -3} do
      for _, shade in ipairs{false, true} do
        local o = {tf = tf, camera = c, device = "cl", iso = {value = value}, shade = shade}
        local a = cdvr.render(v, o)
        o.skip = false
        local b = cdvr.render(v, o)
        local what = ("iso %g from %d%s"):format(value, az, shade and ", shaded" or "")
        check(cdvr.compare(a, b).maxerr == 0, what .. ": skipping changes nothing")
        check(a:stats().samples == b:stats().samples, what .. ": samples " .. a:stats().samples ..
              " with skipping, " .. b:stats().samples .. " without")
        if not shade then
          o.skip, o.device = nil, "cpu"
          check(cdvr.compare(a, cdvr.render(v, o)).maxerr == 0, what .. ": cl equals cpu")
        end
      end
    end
  end
  check(cdvr.compare(before, render{device = "cl"}).maxerr == 0, "composite after iso renders")
  -- the render of o on cl, then with skip=false on cl and on cpu
  local function skip_noskip_cpu(vol, o)
    local a, p = cdvr.render(vol, o), {}
    for k, x in pairs(o) do p[k] = x end
    p.skip = false
    local b = cdvr.render(vol, p)
    p.device = "cpu"
    return a, b, cdvr.render(vol, p)
  end
  -- cl reads fewer samples than skip=false (max reads a sparse pass first, some samples
  -- twice, and counts the samples of flat bricks as taken)
  local function fewer_samples(blend, a, b, what)
    local fewer = blend == "max" and a:stats().samples <= 1.25 * b:stats().samples or
                  a:stats().samples < b:stats().samples
    check(fewer, what .. ": samples read " .. a:stats().samples .. " of " .. b:stats().samples)
  end
  -- max, min and average skip by the brick ranges unless skip=false: the same image, and
  -- without skipping every sample is taken (as on cpu)
  for _, blend in ipairs{"max", "min", "average"} do
    local a, b, c = skip_noskip_cpu(v, {tf = tf, camera = cam, device = "cl", blend = blend})
    check(cdvr.compare(a, b).maxerr == 0, blend .. " on cl: skipping changes nothing")
    check(b:stats().samples == c:stats().samples, blend .. " on cl, skip=false: samples " ..
          b:stats().samples .. ", cpu " .. c:stats().samples)
    fewer_samples(blend, a, b, blend .. " on cl")
  end
  -- max and average read only the samples between the entry and exit bounds of the bricks
  -- above 0 (a block with a hollow inside a volume of zeros): the image of skip=false from
  -- outside (perspective, orthographic, along axes) and from inside the volume (no bounds); min
  -- too (it skips brick by brick)
  local dims = {40, 36, 30}
  local box = cdvr.volume{dims = dims}
  for x = 8, 30 do for y = 6, 27 do for z = 5, 22 do
    local hollow = x > 14 and x < 24 and y > 12 and y < 21 and z > 10 and z < 17
    box:set(x, y, z, hollow and 0 or (x * 7 + y * 3 + z * 11) % 200 + 20)
  end end end
  local views = {
    {"perspective", cdvr.orbit_camera(box, {azimuth = 35, elevation = 20, width = 61, height = 47})},
    {"orthographic", cdvr.camera{eye = {-40, -50, 45}, center = {19.5, 17.5, 14.5}, up = {0, 0, 1},
                                 orthographic = true, ortho_height = 60, width = 48, height = 48}},
    {"along x", cdvr.camera{eye = {-60, 17.5, 14.5}, center = {19.5, 17.5, 14.5}, up = {0, 0, 1},
                            fov = 30, width = 40, height = 36}},
    {"inside", cdvr.camera{eye = {19.5, 17.5, 14.5}, center = {40, 30, 20}, up = {0, 0, 1},
                           fov = 60, width = 40, height = 40}},
    -- few samples per brick: a bound a few samples too tight or too loose changes the image
    {"along x, step 3", cdvr.camera{eye = {-60, 17.5, 14.5}, center = {19.5, 17.5, 14.5},
                                    up = {0, 0, 1}, fov = 30, width = 40, height = 36}, 3},
    {"along -y, step 2.5", cdvr.camera{eye = {19.5, 90, 14.5}, center = {19.5, 17.5, 14.5},
                                       up = {0, 0, 1}, fov = 30, width = 40, height = 36}, 2.5},
  }
  local ramp = cdvr.tf{{0, 0.1, 0.1, 0.3, 0.05}, {64, 1, 0.6, 0.3, 0.5}, {255, 1, 1, 1, 1}}
  local black = cdvr.volume{dims = dims}
  for _, blend in ipairs{"average", "max", "min"} do
    for _, view in ipairs(views) do
      local what = blend .. ", " .. view[1]
      local o = {tf = ramp, camera = view[2], device = "cl", blend = blend, step = view[3]}
      local a, b, c = skip_noskip_cpu(box, o)
      check(cdvr.compare(a, b).maxerr == 0, what .. ": the image of skip=false")
      check(cdvr.compare(a, c).psnr >= 80, what .. ": cl against cpu " .. cdvr.compare(a, c).psnr .. " dB")
      if blend ~= "min" then -- min: 0 on every ray through the zeros
        check(cdvr.compare(a, cdvr.render(black, o)).psnr < 30, what .. ": a picture of the block")
      end
      fewer_samples(blend, a, b, what)
    end
  end
end

-- annotate= in cdvr.render and the player: the same pixels as img:annotate of the plain image
local ann = {colorbar = true, axes = true, title = "neghip", time = true}
local annotated = render{annotate = ann}
check(cdvr.compare(annotated, plain).psnr < 40, "annotate= draws onto the image")
local by_hand = render{}
by_hand:annotate{colorbar = true, axes = true, title = "neghip", time = "t = 1 / 1", tf = tf, volume = v, camera = cam}
check(cdvr.compare(annotated, by_hand).psnr == math.huge, "annotate= equals img:annotate of the same scene")
do
  local path2 = os.tmpname()
  local st2 = cdvr.encode(v, {variants = {{codec = "raw"}}, path = path2})
  local got
  local p = cdvr.player{store = st2, tf = tf, camera = cam, device = "cpu", annotate = ann,
                        frame = function(_, img) got = img end}
  p:run{frames = 1}
  p:close()
  check(got and cdvr.compare(got, annotated).psnr == math.huge, "the player's frames carry the same annotations")
  os.remove(path2)
end
raises(function() render{annotate = {colourbar = true}} end, "annotate: unknown option 'colourbar'", "annotate keys")

-- the player's callbacks run under callback_memory as well as callback_limit
do
  local mpath = os.tmpname()
  local mst = cdvr.encode(v, {variants = {{codec = "raw"}}, path = mpath})
  local p = cdvr.player{store = mst, tf = tf, width = 16, height = 16, device = "cpu", callback_memory = 8,
                        policy = function(s) local t = {} for i = 1, 1e7 do t[i] = i end return s.variants[1].name end}
  raises(function() p:run{frames = 1} end, "callback exceeded its memory budget (callback_memory = 8 MB)",
         "player policy over its memory budget")
  p:close()
  raises(function() cdvr.player{store = mst, tf = tf, callback_memory = 0} end, "option 'callback_memory'",
         "callback_memory checked")
  os.remove(mpath)
end

-- refusals, naming the option
raises(function() render{blend = "maximum"} end, "option 'blend': unknown mode 'maximum'", "unknown blend")
raises(function() render{blend = "iso"} end, "blend 'iso' needs iso={value=, color=}", "iso without value")
raises(function() render{iso = {value = 1}, blend = "max"} end, "option 'iso' is for blend 'iso'", "iso with max")
raises(function() render{iso = {colour = {1, 1, 1}, value = 3}} end, "iso: unknown option 'colour'", "iso keys")
raises(function() render{shade = true, ambient = -1} end, "option 'ambient'", "negative ambient")
raises(function() render{shade = true, light = {dir = {0, 0, 0}}} end, "light dir (0, 0, 0)", "zero light")
raises(function() render{gradient_opacity = {{5, 1}, {1, 0}}} end, "sorted by magnitude", "unsorted gradient opacity")
raises(function() render{method = "splat", shade = true} end, "method 'splat' does not shade", "splat shading")
raises(function() render{method = "splat", blend = "max"} end, "method 'splat' has no blend mode 'max'", "splat max")

-- cdvr.methods() says what each method supports
for _, m in ipairs(cdvr.methods()) do
  if m.name == "raycast" then
    check(m.shading == true and #m.blends == 5 and m.blends[2] == "max", "raycast: shading and 5 blend modes")
  else
    check(m.shading == false and #m.blends == 1, m.name .. ": composite only")
  end
end

checks.finish()
