-- scripts/bench/common.lua: helpers shared by the benchmark and report scripts.
local M = {}

-- ../shared/data relative to the repository (scripts are run from the repo root or build/).
function M.shared_data()
  local env = os.getenv("CDVR_SHARED_DATA")
  if env and env ~= "" then return env end
  local here = debug.getinfo(2, "S").source:match("^@(.*)/scripts/") or "."
  return here .. "/../shared/data"
end

-- Splits arg into positional arguments and options (defaults in `opt`): "--name value",
-- "--name=value", and "--name" alone (a flag: value "1") when no value follows it.
function M.parse_args(argv, opt)
  local positional = {}
  local i = 1
  while i <= #argv do
    local a = argv[i]
    local key, value = a:match("^%-%-([^=]+)=(.*)$")
    if key then -- --key=value
      opt[key] = value
      i = i + 1
    elseif a:match("^%-%-") then
      local nxt = argv[i + 1]
      if nxt == nil or nxt:match("^%-%-") then -- a flag (--keep): no value follows
        opt[a:sub(3)] = "1"
        i = i + 1
      else
        opt[a:sub(3)] = nxt
        i = i + 2
      end
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

-- A short readable name for a dataset spec: the file or directory name without extension;
-- for a printf pattern, without its conversion ("vf_t%03d.nrrd" -> "vf_t").
function M.dataset_name(spec)
  local base = spec:gsub("/+$", ""):match("([^/]+)$") or spec
  base = base:gsub("%.nii%.gz$", ""):gsub("%.%w+$", "")
  local stripped = base:gsub("%%0?%d*[diu]", ""):gsub("[_%-]+$", "")
  return stripped ~= "" and stripped or base
end

-- Loads a dataset given as a directory of NRRD files, a printf pattern (from index
-- opts.first, default 0, and opts.count files or as many as exist), a 4D NIfTI or any single
-- volume; returns the volume and a short name. Raises naming the dataset when it cannot.
function M.load_dataset(spec, opts)
  opts = opts or {}
  local name = M.dataset_name(spec)
  if spec:find("%%") then
    return cdvr.load_series(spec, {first = tonumber(opts.first) or 0, count = tonumber(opts.count)}), name
  end
  local p = io.popen('ls "' .. spec .. '"/*.nrrd 2>/dev/null')
  local files = {}
  for line in p:lines() do files[#files + 1] = line end
  p:close()
  if #files > 0 then
    return cdvr.load_series(files, {}), name
  end
  return cdvr.load(spec), name
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

-- The line of /proc/loadavg ("?" where there is none).
function M.loadavg()
  local f = io.open("/proc/loadavg")
  local s = f and f:read("l") or "?"
  if f then f:close() end
  return s
end

-- The working directory a script was given, made if absent; with none a new temporary one,
-- and own = true (the script removes it at the end).
function M.work_dir(dir)
  local own = dir == ""
  if own then
    dir = os.tmpname()
    os.remove(dir)
  end
  assert(os.execute(("mkdir -p %q"):format(dir)))
  return dir, own
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

-- A number for a CSV cell: "inf" for math.huge, else 4 decimals.
-- A variant's stage 2 for a table: its setting, and for "auto" what its chunks took
-- ("auto:lz4=58/none=2", from st:info().variants[i]).
function M.stage2_label(var)
  if var.stage2 ~= "auto" then return var.stage2 end
  local parts = {}
  for _, c in ipairs{"none", "lzo", "lz4", "zstd"} do
    if var.stage2_chunks[c] > 0 then parts[#parts + 1] = c .. "=" .. var.stage2_chunks[c] end
  end
  return "auto:" .. table.concat(parts, "/")
end

function M.csv_number(x) return x == math.huge and "inf" or ("%.4f"):format(x) end

-- Writes DIR/NAME (header, then row_line(r) for each row), echoes it on stdout, and records the
-- datasets that failed in DIR/failed.txt (removed when none did). Exits 1, naming the script,
-- when no row was measured.
function M.write_results(dir, name, header, rows, row_line, failures, script)
  local path = dir .. "/" .. name
  local csv = assert(io.open(path, "w"))
  csv:write(header, "\n")
  for _, r in ipairs(rows) do csv:write(row_line(r), "\n") end
  csv:close()
  io.write(io.open(path):read("a"))
  local failed_path = dir .. "/failed.txt"
  if #failures > 0 then
    local f = assert(io.open(failed_path, "w"))
    f:write(table.concat(failures, "\n"), "\n")
    f:close()
  else
    os.remove(failed_path)
  end
  if #rows == 0 then
    io.stderr:write(script .. ": no dataset could be measured\n")
    os.exit(1)
  end
end

return M
