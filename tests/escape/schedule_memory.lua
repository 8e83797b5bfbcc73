-- expect: error callback exceeded its memory budget (callback_memory = 8 MB)
-- issue 21 item 2: an encode schedule that allocates without bound, callback_memory = 8 MB
-- (before: no budget, ran out of memory).
local vol = cdvr.generate("sphere", {dims = {12, 12, 12}, timesteps = 6})
cdvr.encode(vol, {S = 4, T = 3, stage2 = "none", path = os.getenv("CDVR_ESCAPE_DIR") .. "/s.cdv",
                  progress = false, callback_memory = 8,
                  schedule = function() local t = {} while true do t[#t + 1] = {} end end})
