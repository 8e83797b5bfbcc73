-- expect: error instruction budget (callback_limit = 100000 instructions)
-- issue 21 item 2: cdvr.encode's callback_limit= sets the schedule's instruction budget.
local vol = cdvr.generate("sphere", {dims = {12, 12, 12}, timesteps = 6})
local calls = 0
cdvr.encode(vol, {S = 4, T = 3, stage2 = "none", path = os.getenv("CDVR_ESCAPE_DIR") .. "/s.cdv",
                  progress = false, callback_limit = 100000,
                  schedule = function() calls = calls + 1; for _ = 1, 1e9 do end end})
