-- expect: error not a regular file (a FIFO)
-- issue 11 item 5: a FIFO inside a series.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.load_series, {c.dir .. '/ok.nrrd', c.dir .. '/fifo.nrrd'})
