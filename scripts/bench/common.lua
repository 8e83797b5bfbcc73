-- scripts/bench/common.lua: helpers shared by the benchmark and report scripts.
local M = {}

-- ../shared/data relative to the repository (scripts are run from the repo root or build/).
function M.shared_data()
  local env = os.getenv("CDVR_SHARED_DATA")
  if env and env ~= "" then return env end
  local here = debug.getinfo(2, "S").source:match("^@(.*)/scripts/") or "."
  return here .. "/../shared/data"
end

-- Splits arg into positional arguments and "--name value" options (defaults in `opt`).
function M.parse_args(argv, opt)
  local positional = {}
  local i = 1
  while i <= #argv do
    local a = argv[i]
    if a:match("^%-%-") then
      opt[a:sub(3)] = argv[i + 1]
      i = i + 2
    else
      positional[#positional + 1] = a
      i = i + 1
    end
  end
  return positional, opt
end

function M.exists(path)
  local f = io.open(path, "rb")
  if f then f:close() return true end
  return false
end

-- Loads a dataset given as a directory of NRRD files, a printf pattern, a 4D NIfTI or any
-- single volume; returns the volume and a short name.
function M.load_dataset(spec)
  local name = spec:gsub("/+$", ""):match("([^/]+)$"):gsub("%.nii%.gz$", ""):gsub("%.%w+$", "")
  if spec:find("%%") then
    return assert(cdvr.load_series(spec, {})), name
  end
  local p = io.popen('ls "' .. spec .. '"/*.nrrd 2>/dev/null')
  local files = {}
  for line in p:lines() do files[#files + 1] = line end
  p:close()
  if #files > 0 then
    return assert(cdvr.load_series(files, {})), name
  end
  return assert(cdvr.load(spec)), name
end

function M.median(list)
  local s = {}
  for i, v in ipairs(list) do s[i] = v end
  table.sort(s)
  local n = #s
  if n == 0 then return 0 / 0 end
  if n % 2 == 1 then return s[(n + 1) // 2] end
  return 0.5 * (s[n // 2] + s[n // 2 + 1])
end

-- Progress on stderr, only when stderr is a terminal.
local tty = os.execute("test -t 2") == true
function M.progress(fmt, ...)
  if tty then io.stderr:write("\r\27[K" .. string.format(fmt, ...)) io.stderr:flush() end
end
function M.progress_done()
  if tty then io.stderr:write("\r\27[K") io.stderr:flush() end
end

-- Camera looking at the volume's box from azimuth az (degrees), z up.
function M.view(v, az, el, width, height)
  return cdvr.orbit_camera(v, {azimuth = az or 30, elevation = el or 20, width = width or 512,
                               height = height or 512})
end

return M
