-- expect: error /dev/zero: not a regular file (a character device)
-- issue 11 item 5: a .nhdr whose data file is /dev/zero (before: loaded zeros).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
-- allow_outside: past the directory check (issue 21), the device itself is refused
c.refuse(cdvr.load, c.dir .. '/zero_data.nhdr', {allow_outside=true})
