-- expect: error /dev/zero: not a regular file (a character device)
-- issue 11 item 5: a .nhdr whose data file is /dev/zero (before: loaded zeros).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
c.refuse(cdvr.load, c.dir .. '/zero_data.nhdr')
