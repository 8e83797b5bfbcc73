-- expect: error not a regular file (a FIFO)
-- issue 11 item 5: cdvr.open on a FIFO (before: blocked forever).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.open, c.dir .. '/fifo.cdv')
