-- expect: error not a regular file (a FIFO)
-- issue 11 item 5: a raw FIFO with dims and type (before: blocked forever in fopen).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.load, c.dir .. '/fifo.raw', {dims = {4, 4, 4}, type = 'u8'})
