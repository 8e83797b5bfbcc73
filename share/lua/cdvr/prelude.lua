-- cdvr.prelude: the parts of the cdvr API written in Lua. The host requires this module
-- after the C functions are registered; each piece lives in its own module under
-- share/lua/cdvr/ and is attached to the cdvr table here.
local cdvr = require "cdvr"

-- Optional modules: attach them when present (they land with their issues).
local function attach(field, modname)
  local ok, mod = pcall(require, modname)
  if ok then
    cdvr[field] = mod
  elseif not tostring(mod):find("module '" .. modname .. "' not found", 1, true) then
    error(mod, 0)
  end
end

attach("path", "cdvr.path")
attach("policy", "cdvr.policy")

return cdvr
