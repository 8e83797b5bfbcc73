-- scripts/bench/splat.lua [--views N] [--dirs N] [--width W] [--orders dda,quicksort,sort,axis]
--                         [--sections order,fill,popping] [--datasets engine,neghip]
--                         [--engine PATH] [--neghip PATH]
-- Splatting with the seed's extended DDA (seed 003) against axis-aligned sheets and depth sorts.
-- Three sections, one CSV on stdout (progress on stderr only when it is a terminal):
--   order:   time to order every voxel of an n^3 grid (n = 64, 100, 128, 256), median over
--            --dirs random view directions (fixed seed; 256^3 quicksort over at most 3), and
--            copying the order's bytes (memcpy) as the floor; ratio = median / axis median.
--            The seed's Table 1 (Pentium 4 3.2 GHz) beside: seed_value ms, seed_ratio.
--   fill:    frames per second of the splat renderer (W x W, all cores) against the fill ratio
--            (voxels above a threshold) on the engine CT and neghip, median over --views views;
--            x = fill ratio measured, value = fps, ratio = fps / quicksort fps at that fill;
--            extra columns: median frame and ordering ms. The OpenCL ray cast (order
--            "raycast_cl"; the CPU one, "raycast_cpu", where this cdvr has no OpenCL) of the same
--            view with the TF's opacity zeroed up to the threshold, step 1, is interleaved with
--            the splat orders (every view renders each once, the order rotated per view, first
--            ray-cast frame untimed); metric fps_over_raycast = splat fps / ray-cast fps. Seed beside: Table 3 (skull 256^3)
--            for the engine, Table 2 (hydrogenAtom 128^3) for neghip, at the same row.
--   popping: PSNR (dB) between splat images at azimuths 44 and 46 degrees (elevation 10) per
--            order (metric psnr_44_46), the same for 44.9 and 45.1 (psnr_44.9_45.1: the view
--            barely moves, so a jump is the order switching), and of each order's image against
--            the exact sort at the same view (psnr_vs_sort, x = azimuth): the axis order
--            switches sheets at 45 degrees.
-- Columns: section,dataset,order,x,metric,value,ratio,frame_ms,order_ms,seed_value,seed_ratio
local common = dofile((arg and arg[0] and arg[0]:match("^(.*/)") or "./") .. "common.lua")

local _, opt = common.parse_args(arg, {views = "3", dirs = "15", width = "512",
                                       orders = "dda,quicksort,sort,axis",
                                       sections = "order,fill,popping",
                                       datasets = "engine,neghip"})
local VIEWS, DIRS, WIDTH = tonumber(opt.views), tonumber(opt.dirs), tonumber(opt.width)
local function list(s) local t = {} for w in s:gmatch("[^,]+") do t[#t + 1] = w end return t end
local ORDERS, SECTIONS, DATASETS = list(opt.orders), {}, {}
for _, s in ipairs(list(opt.sections)) do SECTIONS[s] = true end
for _, s in ipairs(list(opt.datasets)) do DATASETS[s] = true end
local clock = cdvr.clock or os.clock
local median, progress = common.median, common.progress

print("section,dataset,order,x,metric,value,ratio,frame_ms,order_ms,seed_value,seed_ratio")
local function row(section, dataset, order, x, metric, value, ratio, frame_ms, order_ms, seed, seed_ratio)
  local function f(v, fmt) return v and string.format(fmt or "%.4g", v) or "" end
  print(string.format("%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s", section, dataset, order, x, metric,
                      f(value), f(ratio, "%.3f"), f(frame_ms), f(order_ms), f(seed),
                      f(seed_ratio, "%.3f")))
end

-- ---- ordering time (Table 1) --------------------------------------------------------------
local SEED_T1 = { -- ms: axis, proposed (DDA), quicksort
  [64] = {axis = 0.352, dda = 0.982, quicksort = 73.1},
  [100] = {axis = 0.946, dda = 2.43, quicksort = 306},
  [128] = {axis = 2.82, dda = 5.67, quicksort = 615},
  [256] = {axis = 17.6, dda = 34.8, quicksort = 5120},
}

local function random_dirs(n)
  local dirs, state = {}, 12345
  local function rnd() state = (state * 1103515245 + 12345) % 2147483648 return state / 2147483648 end
  while #dirs < n do
    local d = {2 * rnd() - 1, 2 * rnd() - 1, 2 * rnd() - 1}
    local len = math.sqrt(d[1] ^ 2 + d[2] ^ 2 + d[3] ^ 2)
    if len > 0.1 and len <= 1 then dirs[#dirs + 1] = d end
  end
  return dirs
end

if SECTIONS.order then
  for _, n in ipairs{64, 100, 128, 256} do
    local dims, medians = {n, n, n}, {}
    for _, how in ipairs{"axis", "dda", "sort", "quicksort"} do
      local count = (how == "quicksort" and n >= 256) and math.min(3, DIRS) or DIRS
      local times = {}
      for i, d in ipairs(random_dirs(count)) do
        progress("order %d^3 %s %d/%d", n, how, i, count)
        local t0 = clock()
        local o <close> = cdvr.splat_order(dims, d, how)
        times[i] = (clock() - t0) * 1000
      end
      medians[how] = median(times)
    end
    if cdvr.bench_memcpy then
      local ms = 4 * n ^ 3 / (cdvr.bench_memcpy(4 * n ^ 3, 5) * 1e6) * 1000
      row("order", "grid", "memcpy", n, "median_ms", ms, ms / medians.axis)
    end
    local seed = SEED_T1[n]
    for _, how in ipairs{"axis", "dda", "sort", "quicksort"} do
      row("order", "grid", how, n, "median_ms", medians[how], medians[how] / medians.axis, nil, nil,
          seed[how], seed[how] and seed[how] / seed.axis)
    end
  end
end

-- ---- frames per second against fill ratio (Tables 2 and 3) -----------------------------------
local SEED_T2 = { -- hydrogenAtom 128^3: fill, DDA fps, quicksort fps
  {0.0103, 48.3, 59.9}, {0.0203, 39.3, 40.0}, {0.0400, 29.0, 21.3}, {0.0831, 21.0, 10.1},
  {0.135, 13.3, 6.29}, {0.204, 9.38, 4.19}, {0.327, 6.00, 2.57}}
local SEED_T3 = { -- skull 256^3
  {0.0144, 4.14, 7.28}, {0.0264, 4.00, 3.92}, {0.0423, 3.99, 2.41}, {0.0936, 2.67, 1.07},
  {0.123, 1.98, 0.82}, {0.257, 1.05, 0.38}}

local function find_path(given, rel_shared, rel_share)
  if given then return given end
  local p = common.shared_data() .. rel_shared
  if common.exists(p) then return p end
  if rel_share then
    p = cdvr.share_dir .. rel_share
    if common.exists(p) then return p end
  end
  return nil
end

-- The integer threshold whose fill (fraction of voxels above it) is nearest the target in
-- ratio: the smallest with fill <= target, or the one below it.
local function threshold_for(v, target)
  local dims = {v:dims()}
  local total = dims[1] * dims[2] * dims[3]
  local function fill(t)
    local o <close> = cdvr.splat_order(dims, {1, 0, 0}, "axis", {threshold = t, volume = v})
    return #o / total
  end
  local lo, hi = -1, 255
  while lo < hi do
    local mid = (lo + hi) // 2
    if fill(mid) <= target then hi = mid else lo = mid + 1 end
  end
  local f_at, f_below = fill(lo), lo > -1 and fill(lo - 1) or math.huge
  if f_at > 0 and target / f_at <= f_below / target then return lo, f_at end
  return lo - 1, f_below
end

-- Every value above 0 visible: the fill ratio is what the threshold leaves.
local FILL_TF = cdvr.tf{ {0, 0, 0, 0, 0}, {1, 0.3, 0.3, 0.6, 0.004}, {128, 0.9, 0.6, 0.3, 0.05},
                         {255, 1, 1, 1, 0.6} }

-- The OpenCL ray cast where this cdvr has it, else the CPU one.
local RAY_DEVICE = pcall(cdvr.render, cdvr.generate("box", {dims = {2, 2, 2}}),
                         {tf = FILL_TF, camera = cdvr.camera{eye = {0, 0, 5}, center = {0, 0, 0},
                                                             up = {0, 1, 0}, width = 4, height = 4},
                          device = "cl"}) and "cl" or "cpu"
local RAY = "raycast_" .. RAY_DEVICE

-- FILL_TF with zero opacity at and below the splat threshold (what the splatter drops).
local function thresholded_tf(thr)
  local pts = {{0, 0, 0, 0, 0}, {thr, 0, 0, 0, 0}}
  for _, p in ipairs{{thr + 1, 0.3, 0.3, 0.6, 0.004}, {128, 0.9, 0.6, 0.3, 0.05}, {255, 1, 1, 1, 0.6}} do
    if p[1] > thr then pts[#pts + 1] = p end
  end
  if #pts == 2 then pts[#pts + 1] = {255, 0, 0, 0, 0} end
  return cdvr.tf(pts)
end

local function fill_section(name, v, seed_table)
  for idx, s in ipairs(seed_table) do
    local thr, fill = threshold_for(v, s[1])
    local ray_tf = thresholded_tf(thr)
    local hows = {}
    for i, how in ipairs(ORDERS) do hows[i] = how end
    hows[#hows + 1] = RAY
    local frames, orders = {}, {}
    for _, how in ipairs(hows) do frames[how], orders[how] = {}, {} end
    for k = 1, VIEWS do
      local cam = common.view(v, 20 + 45 * (k - 1), 25, WIDTH, WIDTH)
      if k == 1 then cdvr.render(v, {tf = ray_tf, camera = cam, step = 1, device = RAY_DEVICE}) end
      for j = 0, #hows - 1 do
        local how = hows[(k - 1 + j) % #hows + 1]
        progress("fill %s %.3f %s view %d", name, fill, how, k)
        local st
        if how == RAY then
          _, st = cdvr.render(v, {tf = ray_tf, camera = cam, step = 1, device = RAY_DEVICE})
        else
          _, st = cdvr.render(v, {method = "splat", order = how, tf = FILL_TF, camera = cam,
                                  threshold = thr})
        end
        frames[how][k], orders[how][k] = st.ms, st.order_ms or 0
      end
    end
    local fps = {}
    for _, how in ipairs(hows) do
      local ms = median(frames[how])
      fps[how] = {1000 / ms, ms, median(orders[how])}
    end
    for _, how in ipairs(hows) do
      local f = fps[how]
      local seed = how == "dda" and s[2] or how == "quicksort" and s[3] or nil
      row("fill", name, how, string.format("%.4f", fill), "fps", f[1],
          fps.quicksort and f[1] / fps.quicksort[1], f[2], f[3], seed, seed and seed / s[3])
      if how ~= RAY then
        row("fill", name, how, string.format("%.4f", fill), "fps_over_raycast", f[1] / fps[RAY][1],
            nil, f[2], f[3])
      end
    end
    progress("")
    local _ = idx
  end
end

-- ---- popping near 45 degrees ------------------------------------------------------------------
local function popping_section(name, v, tf)
  local images, angles = {}, {44, 46, 44.9, 45.1}
  for _, az in ipairs(angles) do
    images[az] = {}
    local cam = common.view(v, az, 10, WIDTH, WIDTH)
    for _, how in ipairs{"axis", "dda", "sort"} do
      progress("popping %s %s %g", name, how, az)
      images[az][how] = cdvr.render(v, {method = "splat", order = how, tf = tf, camera = cam})
    end
  end
  for _, how in ipairs{"axis", "dda", "sort"} do
    row("popping", name, how, "44-46", "psnr_44_46", cdvr.compare(images[44][how], images[46][how]).psnr)
    row("popping", name, how, "44.9-45.1", "psnr_44.9_45.1",
        cdvr.compare(images[44.9][how], images[45.1][how]).psnr)
    for _, az in ipairs(angles) do
      if how ~= "sort" then
        row("popping", name, how, az, "psnr_vs_sort", cdvr.compare(images[az][how], images[az].sort).psnr)
      end
    end
  end
end

local engine_path = find_path(opt.engine, "/ct/engine_256x256x128_u8.nrrd")
local neghip_path = find_path(opt.neghip, "/sim/neghip_66x66x66_u8.nrrd", "/data/neghip_66x66x66_u8.nrrd")
local datasets = {}
if engine_path and DATASETS.engine then datasets[#datasets + 1] = {"engine", engine_path, SEED_T3, "ct_bone"} end
if neghip_path and DATASETS.neghip then datasets[#datasets + 1] = {"neghip", neghip_path, SEED_T2, nil} end
for _, d in ipairs(datasets) do
  local v = assert(cdvr.load(d[2]))
  if SECTIONS.fill then fill_section(d[1], v, d[3]) end
  if SECTIONS.popping then
    popping_section(d[1], v, d[4] and cdvr.tf(d[4]) or FILL_TF)
  end
end
common.progress_done()
