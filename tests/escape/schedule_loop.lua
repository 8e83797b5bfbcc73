-- expect: error instruction budget (callback_limit = 50000000 instructions)
-- issue 21 item 2: an encode schedule that loops (before: no budget at all, hang).
local vol = cdvr.generate("sphere", {dims = {12, 12, 12}, timesteps = 6})
cdvr.encode(vol, {S = 4, T = 3, stage2 = "none", path = os.getenv("CDVR_ESCAPE_DIR") .. "/s.cdv",
                  progress = false,
                  schedule = function() while true do end end})
