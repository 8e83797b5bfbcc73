-- tests/lua/test_errors.lua - errors, not nils (issue 10, item 7): cdvr.load, cdvr.load_series
-- and cdvr.open raise an error naming the file and the reason; img:save refuses an extension it
-- does not write; PNGs are RGB unless alpha is asked for; a camera whose view misses the
-- volume gives the image plus a one-line warning on stderr.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check = checks.check
local function raises(parts, what, f, ...)
  local ok, msg = pcall(f, ...)
  check(not ok, what .. ": expected an error, got " .. tostring(msg))
  for _, part in ipairs(parts) do
    check(not ok and tostring(msg):find(part, 1, true), what .. ": '" .. tostring(msg) .. "' lacks '" .. part .. "'")
  end
end
local tmpdir = os.getenv("CDVR_BINARY_DIR") or "."

raises({"nowhere/skull.nrrd", "No such file"}, "cdvr.load of a missing file", cdvr.load, "nowhere/skull.nrrd")
raises({"nowhere/vorts3.raw", "no such file"}, "cdvr.load_series of a missing pattern",
       cdvr.load_series, "nowhere/vorts%d.raw", {first = 3, dims = {4, 4, 4}, type = "f32"})
raises({"nowhere/a.nii"}, "cdvr.load_series of a missing list", cdvr.load_series, {"nowhere/a.nii", "nowhere/b.nii"})
raises({"nowhere/out.cdv"}, "cdvr.open of a missing store", cdvr.open, "nowhere/out.cdv")
local junk = tmpdir .. "/test_errors_junk.cdv"
local fh = assert(io.open(junk, "wb"))
fh:write("this is not a store")
fh:close()
raises({junk}, "cdvr.open of a non-store", cdvr.open, junk)
os.remove(junk)
-- a script that forgets to check gets the reason, not "attempt to index a nil value"
local ok, msg = pcall(function() return cdvr.load("nowhere/x.nii.gz"):dims() end)
check(not ok and not tostring(msg):find("nil value", 1, true) and tostring(msg):find("nowhere/x.nii.gz", 1, true),
      "chained call names the file: " .. tostring(msg))

-- img:save: PNG or JPEG by the extension (test_presets.lua writes JPEG); RGB unless alpha=true
local v = cdvr.generate("sphere", {dims = {16, 16, 16}})
local img = cdvr.render(v, {tf = "hot", camera = cdvr.orbit_camera(v, {width = 24, height = 20})})
for _, name in ipairs{"frame.gif", "frame.tiff", "frame", "frame.png.bak"} do
  raises({name, "PNG"}, "img:save " .. name, img.save, img, tmpdir .. "/" .. name)
  check(not io.open(tmpdir .. "/" .. name), name .. " not written")
end
local function png_colour_type(path)
  local f = assert(io.open(path, "rb"))
  local head = f:read(26)
  f:close()
  return head:byte(26) -- IHDR colour type: 2 = RGB, 6 = RGBA
end
local rgb, rgba = tmpdir .. "/test_errors_rgb.png", tmpdir .. "/test_errors_rgba.PNG"
check(img:save(rgb) == true and png_colour_type(rgb) == 2, "default PNG is RGB")
check(img:save(rgba, {alpha = true}) == true and png_colour_type(rgba) == 6, "alpha=true gives RGBA")
os.remove(rgb)
os.remove(rgba)

-- a camera that looks away: the image (background only) and one warning line
local script = tmpdir .. "/test_errors_miss.lua"
fh = assert(io.open(script, "w"))
fh:write([[
local v = cdvr.generate("box", {dims = {8, 8, 8}})
local away = cdvr.camera{eye = {100, 100, 100}, center = {200, 100, 100}, width = 16, height = 12}
local img = cdvr.render(v, {tf = "grayscale", camera = away})
print("image", img:size())
cdvr.render(v, {tf = "grayscale", camera = cdvr.orbit_camera(v, {width = 16, height = 12})})
print("done")
]])
fh:close()
local exe = arg and arg[-1] or "cdvr"
local p = assert(io.popen(("%q %q 2>&1"):format(exe, script)))
local out = p:read("a")
p:close()
os.remove(script)
local warnings = select(2, out:gsub("warning", "warning"))
check(out:find("image\t16\t12", 1, true) and out:find("done", 1, true), "render still returns the image: " .. out)
check(warnings == 1 and out:find("cdvr: warning: cdvr.render: the camera's view misses the volume", 1, true),
      "exactly one warning, for the camera that misses: " .. out)

checks.finish()
