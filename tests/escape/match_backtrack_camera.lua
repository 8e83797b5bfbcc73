-- expect: error instruction budget
-- issue 21 item 2: string.match / gmatch backtracking in a camera callback (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.play(nil, function(t, cam)
  local s = string.rep("a", 40)
  for _ in s:gmatch(string.rep("a*", 20) .. "b") do end
  s:match(string.rep("a*", 20) .. "b")
  return cdvr.camera(c.camera)
end)
