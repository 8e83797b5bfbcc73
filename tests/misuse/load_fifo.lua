-- expect: error not a regular file (a FIFO)
-- issue 11 item 5: cdvr.load on a FIFO named like a NRRD.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.load, c.dir .. '/fifo.nrrd')
