-- expect: error fifo.raw: not a regular file (a FIFO)
-- issue 11 item 5: a detached .nhdr whose data file is a FIFO (before: blocked forever).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.load, c.dir .. '/fifo_data.nhdr')
