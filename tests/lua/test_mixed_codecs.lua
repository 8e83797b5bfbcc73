-- A store mixing PVTC and zfp variants (zfp from the plugin, decoded on the CPU and uploaded)
-- plays under closed_loop on every device: every frame renders, every group start records a
-- decision naming one of the store's variants, and each frame's image matches the render of
-- that variant's decoded timestep. Skips (77) when the zfp plugin is not loaded.
local have_zfp = false
for _, c in ipairs(cdvr.codecs()) do have_zfp = have_zfp or c.name == "zfp" end
if not have_zfp then
  print("skip: the zfp plugin is not loaded (CDVR_PLUGIN_PATH)")
  os.exit(77)
end

local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))
local vol = cdvr.generate("ml", {dims = {24, 20, 18}, timesteps = 9})
local st = assert(cdvr.encode(vol, {path = tmp .. "/mixed.cdv", progress = false,
  variants = {{codec = "pvtc", S = 4, T = 3}, {codec = "zfp", rate = 1}, {codec = "zfp", rate = 4},
              {codec = "raw"}}}))
local info = st:info()
assert(info.variants[2].name == "zfp1" and info.variants[2].codec == "zfp" and
       info.variants[2].rate == 1, "zfp variant listed with its parameters")
assert(info.variants[3].psnr > info.variants[2].psnr, "zfp4 better than zfp1")

local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(vol, {azimuth = 20, elevation = 30, width = 32, height = 32})
local names = {}
for _, v in ipairs(info.variants) do names[v.name] = true end
local devices = {"cpu"}
if cdvr.cl_info() then devices[2] = "cl" end
for _, dev in ipairs(devices) do
  for _, target in ipairs{2000, 5} do -- a target every variant meets, and one none does
    local p = cdvr.player{store = st, tf = tf, camera = cam, device = dev,
                          policy = "closed_loop", target_fps = target, pace = false}
    local r = p:run{frames = 9}
    assert(#r.frames == 9, dev .. ": rows")
    assert(r.group_length == 3, "group = lcm(3, 1, 1, 1)")
    for i, row in ipairs(r.frames) do
      assert(not row.error, row.error)
      assert(names[row.variant], "unknown variant " .. tostring(row.variant))
      if (i - 1) % 3 == 0 then assert(row.reason and row.reason:find("closed_loop"), "decision") end
    end
    p:close()
  end
  -- each variant plays its own data: a fixed zfp variant renders its decoded timesteps
  local p = cdvr.player{store = st, tf = tf, camera = cam, device = dev, variant = "zfp1",
                        out = tmp .. "/" .. dev .. "_%02d.png"}
  p:run{frames = 3}
  p:close()
  for t = 1, 3 do
    local want = cdvr.render(st:decode(t, "zfp1"), {tf = tf, camera = cam, device = dev})
    local got = assert(io.open(("%s/%s_%02d.png"):format(tmp, dev, t), "rb")):read("a")
    local path = ("%s/want_%02d.png"):format(tmp, t)
    want:save(path)
    assert(got == io.open(path, "rb"):read("a"), dev .. ": captured zfp frame " .. t)
  end
end
os.execute(("rm -rf %q"):format(tmp))
print("test_mixed_codecs: ok")
