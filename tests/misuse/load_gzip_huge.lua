-- expect: error gzip expands at most 1032 times
-- issue 11 item 5: a 116-byte gzip NRRD claiming 8 GB (before: 8 GB allocated, 25 s).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.load, c.dir .. '/gz_huge.nrrd')
