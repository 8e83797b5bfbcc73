#!/usr/bin/python3
"""scripts/bench/vs_vtk.py [--volumes engine,colin27] [--tfs ours,slicer] [--steps 0.5,1.0]
                          [--sizes 512,1024] [--repeats 7] [--devices cl,cpu] [--cdvr build/cdvr]
                          [--old OLD_CDVR] [--out out/vs_vtk] [--sequential]

cdvr against VTK's vtkFixedPointVolumeRayCastMapper (offscreen, under xvfb-run), same camera
(cdvr.orbit_camera's: azimuth 45, elevation 25), transfer function, opacity unit (1 world unit)
and sample distance, one ray per pixel.

Alternating mode (the default): one long-lived VTK renderer and one long-lived cdvr process per
binary (this build, and --old's when given) per volume; for each case (volume, TF, step, size)
every renderer first renders one untimed frame (VTK builds its tables, cdvr builds kernels and
uploads), then --repeats rounds request one frame from each renderer in turn, the order rotated
by one every round. VTK's time is the mapper's: from the start of the window's Render() to the
end of the ray casting (vtkCommand::VolumeMapperRenderEndEvent), without the step that draws the
ray-cast image into the window (vtk_cast_ms, the ray casting alone, is printed beside it);
cdvr's is the cdvr.render call. Per renderer: the median frame time and the median over rounds
of the per-round ratio VTK time / renderer time (its speed-up: > 1 is faster than VTK), and the
PSNR of its last image against VTK's ray-cast image before display (see save_raycast_image).
TFs: "ours" (scripts/bench/look.lua's, per volume) and "slicer" (3D Slicer's MR-Default preset,
share/tf/MR-Default.lua, absolute values, which suit both 8-bit volumes; unshaded here).
CSV on stdout, with the load average before and after each case.

--sequential: the old measurement (all VTK frames, then all cdvr frames, window time), on the
engine CT with the first volume's TF, kept for comparison with earlier notes.

Installs python3-vtk9, python3-numpy and xvfb with apt-get when missing, and re-executes itself
under xvfb-run when no display is set. Run from the repository root after building.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

# One transfer function for both: value, r, g, b, opacity per unit length. The engine's
# metal (values above ~180) is opaque and bright; the casing is faint.
TF = [(0, 0, 0, 0, 0), (80, 0.6, 0.3, 0.1, 0.0), (120, 0.8, 0.5, 0.2, 0.02),
      (180, 0.9, 0.9, 0.9, 0.3), (255, 1.0, 1.0, 1.0, 0.9)]
EYE, CENTER, UP, FOV = (560.0, -330.0, 330.0), (127.5, 127.5, 63.5), (0.0, 0.0, 1.0), 30.0
STEP = 0.5


def ensure_packages():
    try:
        import vtk  # noqa: F401
        have_vtk = True
    except ImportError:
        have_vtk = False
    need = [] if have_vtk else ["python3-vtk9"]
    try:
        import numpy  # noqa: F401
    except ImportError:
        need.append("python3-numpy")
    if not shutil.which("xvfb-run"):
        need.append("xvfb")
    if need:
        sudo = [] if os.geteuid() == 0 else ["sudo"]
        subprocess.check_call(sudo + ["apt-get", "update", "-qq"])
        subprocess.check_call(sudo + ["apt-get", "install", "-y", "-qq"] + need,
                              env=dict(os.environ, DEBIAN_FRONTEND="noninteractive"))
    if not os.environ.get("DISPLAY") and not os.environ.get("CDVR_UNDER_XVFB"):
        env = dict(os.environ, CDVR_UNDER_XVFB="1")
        # -noreset: the server otherwise resets when its last client leaves, and a window
        # opened meanwhile (look_vtk.py's next volume) fails with "bad X server connection"
        os.execvpe("xvfb-run", ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24 -noreset",
                                "/usr/bin/python3"] + sys.argv, env)


def read_nrrd(path):
    """Attached-header NRRD (raw or gzip encoding) -> vtkImageData. VTK's own vtkNrrdReader
    resolves to the MPI-parallel reader in Debian's build and fails without MPI."""
    import gzip
    import numpy as np
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk
    with open(path, "rb") as f:
        raw = f.read()
    end = raw.index(b"\n\n")
    fields = {}
    for line in raw[:end].decode().splitlines()[1:]:
        if ":" in line and not line.startswith("#"):
            k, v = line.split(":", 1)
            fields[k.strip()] = v.strip()
    dims = [int(x) for x in fields["sizes"].split()]
    types = {"uchar": np.uint8, "unsigned char": np.uint8, "uint8": np.uint8,
             "ushort": np.uint16, "unsigned short": np.uint16, "uint16": np.uint16,
             "short": np.int16, "int16": np.int16, "float": np.float32}
    dtype = np.dtype(types[fields["type"]])
    if fields.get("endian", "little") == "big":
        dtype = dtype.newbyteorder(">")
    data = raw[end + 2:]
    if fields.get("encoding") in ("gzip", "gz"):
        data = gzip.decompress(data)
    arr = np.frombuffer(data, dtype=dtype, count=int(np.prod(dims))).astype(dtype.newbyteorder("="))
    img = vtk.vtkImageData()
    img.SetDimensions(*dims[:3])
    img.SetSpacing(1, 1, 1)
    img.GetPointData().SetScalars(numpy_to_vtk(arr, deep=True))
    return img


def render_vtk(path, size, repeats, out_png, raw_png):
    import vtk
    image = read_nrrd(path)
    color = vtk.vtkColorTransferFunction()
    opacity = vtk.vtkPiecewiseFunction()
    for v, r, g, b, a in TF:
        color.AddRGBPoint(v, r, g, b)
        opacity.AddPoint(v, a)
    prop = vtk.vtkVolumeProperty()
    prop.SetColor(color)
    prop.SetScalarOpacity(opacity)
    prop.SetScalarOpacityUnitDistance(1.0)
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOff()
    mapper = vtk.vtkFixedPointVolumeRayCastMapper()
    mapper.SetInputData(image)
    mapper.SetSampleDistance(STEP)
    mapper.SetInteractiveSampleDistance(STEP)
    mapper.AutoAdjustSampleDistancesOff()
    mapper.SetImageSampleDistance(1.0)
    mapper.SetNumberOfThreads(os.cpu_count() or 1)
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    ren = vtk.vtkRenderer()
    ren.AddVolume(volume)
    ren.SetBackground(0, 0, 0)
    cam = ren.GetActiveCamera()
    cam.SetPosition(*EYE)
    cam.SetFocalPoint(*CENTER)
    cam.SetViewUp(*UP)
    cam.SetViewAngle(FOV)
    ren.ResetCameraClippingRange()
    win = vtk.vtkRenderWindow()
    win.SetOffScreenRendering(1)
    win.AddRenderer(ren)
    win.SetSize(size, size)
    win.Render()  # first frame builds the mapper's tables
    times = []
    for _ in range(repeats):
        # no volume.Modified(): it makes VTK rebuild its tables and inflates its frame time
        t0 = time.perf_counter()
        win.Render()
        times.append((time.perf_counter() - t0) * 1e3)
    save_raycast_image(mapper, size, raw_png)
    w2i = vtk.vtkWindowToImageFilter()
    w2i.SetInput(win)
    w2i.ReadFrontBufferOff()
    w2i.Update()
    png = vtk.vtkPNGWriter()
    png.SetFileName(out_png)
    png.SetInputConnection(w2i.GetOutputPort())
    png.Write()
    return sorted(times)[len(times) // 2]


def save_raycast_image(mapper, size, out_png):
    """The mapper's own ray-cast image, before VTK displays it. vtkOpenGLRayCastImageDisplayHelper
    draws that image as a texture whose n texel centres are stretched over n pixels (texture
    coordinates inset by half a texel, linear filtering): a resampling by n/(n-1) that blurs
    and shifts edges by up to half a pixel. Comparing against the undisplayed image measures
    the ray casters alone. Pixels are premultiplied 15-bit fixed point (display scale 2/65535),
    rows from the bottom, placed at the image origin; outside is the black background."""
    import ctypes
    import numpy as np
    rc = mapper.GetRayCastImage()
    mem, use, origin = rc.GetImageMemorySize(), rc.GetImageInUseSize(), rc.GetImageOrigin()
    if tuple(rc.GetImageViewportSize()) != (size, size) or rc.GetImageSampleDistance() != 1.0:
        raise RuntimeError("ray-cast image does not cover the viewport one ray per pixel")
    addr = int(str(rc.GetImage()).split("_")[1], 16)  # SWIG-style "_<hex>_p_void"
    raw = np.ctypeslib.as_array((ctypes.c_ushort * (mem[0] * mem[1] * 4)).from_address(addr))
    raw = raw.reshape(mem[1], mem[0], 4)[:use[1], :use[0], :3].astype(np.float64)
    full = np.zeros((size, size, 3))
    full[origin[1]:origin[1] + use[1], origin[0]:origin[0] + use[0]] = raw * 255.0 * 2.0 / 65535.0
    write_png(np.flipud(np.clip(np.rint(full), 0, 255)).astype(np.uint8), out_png)


def write_png(rgb, path):
    """Top-down uint8 HxWx3 array -> PNG through VTK (whose rows start at the bottom)."""
    import numpy as np
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk
    h, w, _ = rgb.shape
    img = vtk.vtkImageData()
    img.SetDimensions(w, h, 1)
    img.GetPointData().SetScalars(numpy_to_vtk(np.ascontiguousarray(np.flipud(rgb)).reshape(-1, 3),
                                               deep=True))
    png = vtk.vtkPNGWriter()
    png.SetFileName(path)
    png.SetInputData(img)
    png.Write()


def render_cdvr(exe, path, size, repeats, device, out_png):
    pts = ", ".join("{%g, %g, %g, %g, %g}" % p for p in TF)
    lua = f"""
local v = assert(cdvr.load({path!r}))
local tf = cdvr.tf{{ {pts}, unit = 1 }}
local cam = cdvr.camera{{eye={{{EYE[0]},{EYE[1]},{EYE[2]}}}, center={{{CENTER[0]},{CENTER[1]},{CENTER[2]}}},
                         up={{0,0,1}}, fov={FOV}, width={size}, height={size}}}
local opts = {{tf=tf, camera=cam, step={STEP}, device={device!r}, background={{0,0,0,1}}}}
local img = cdvr.render(v, opts)   -- warm-up (kernel build, upload)
local ms = {{}}
for i = 1, {repeats} do
  local t0 = cdvr.clock()
  img = cdvr.render(v, opts)
  ms[#ms + 1] = (cdvr.clock() - t0) * 1e3
end
table.sort(ms)
img:save({out_png!r})
print(ms[#ms // 2 + 1])
"""
    res = subprocess.run([exe, "-e", lua], capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"cdvr ({device}) failed: {res.stderr.strip()}")
    return float(res.stdout.strip().splitlines()[-1])


def psnr(png_a, png_b):
    import numpy as np
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    def load(p):
        r = vtk.vtkPNGReader()
        r.SetFileName(p)
        r.Update()
        img = r.GetOutput()
        w, h, _ = img.GetDimensions()
        arr = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, -1)[:, :, :3]
        return np.flipud(arr).astype(np.float64)  # VTK rows start at the bottom

    a, b = load(png_a), load(png_b)
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


DATA = os.environ.get("CDVR_SHARED_DATA", os.path.join(ROOT, "..", "shared", "data"))
VOLUMES = {
    "engine": os.path.join(DATA, "ct", "engine_256x256x128_u8.nrrd"),
    "colin27": os.path.join(DATA, "mri", "colin27_t1_301x370x316_u8.nii.gz"),
}
# value, r, g, b, opacity per unit: "ours" are scripts/bench/look.lua's, "slicer" is 3D Slicer's
# MR-Default (share/tf/MR-Default.lua) for both volumes.
SLICER_MR_DEFAULT = [(0, 0, 0, 0, 0), (20, 0.168627, 0, 0, 0),
                     (40, 0.403922, 0.145098, 0.0784314, 0.15),
                     (120, 0.780392, 0.607843, 0.380392, 0.3),
                     (220, 0.847059, 0.835294, 0.788235, 0.375), (1024, 1, 1, 1, 0.5)]
TFS = {
    ("engine", "ours"): TF,
    ("colin27", "ours"): [(0, 0, 0, 0, 0), (35, 0, 0, 0, 0), (60, 0.8, 0.45, 0.35, 0.03),
                          (90, 1.0, 0.85, 0.7, 0.3), (130, 1, 1, 1, 0.8)],
    ("engine", "slicer"): SLICER_MR_DEFAULT,
    ("colin27", "slicer"): SLICER_MR_DEFAULT,
}

# The cdvr side: loads the volume, writes its voxels for VTK (unless "-"), then answers
# "camera <size>" with the camera and "render <tf> <step> <size> <device> <png or ->" with the
# milliseconds of the cdvr.render call.
SERVER = r"""
local path, raw = arg[1], arg[2]
local tfs = load("return " .. arg[3])()
local v = assert(cdvr.load(path))
for k, pts in pairs(tfs) do tfs[k] = cdvr.tf(pts) end
local nx, ny, nz = v:dims()
local ox, oy, oz = v:origin()
local sx, sy, sz = v:spacing()
if raw ~= "-" then v:save_raw(raw) end
print(("grid %d %d %d %.17g %.17g %.17g %.17g %.17g %.17g"):format(nx, ny, nz, ox, oy, oz, sx, sy, sz))
io.stdout:flush()
local cams = {}
local function camera(size)
  cams[size] = cams[size] or cdvr.orbit_camera(v, {azimuth = 45, elevation = 25, width = size, height = size})
  return cams[size]
end
for line in io.lines() do
  local words = {}
  for w in line:gmatch("%S+") do words[#words + 1] = w end
  if words[1] == "camera" then
    local c = camera(tonumber(words[2]))
    print(("camera %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g"):format(
      c.eye[1], c.eye[2], c.eye[3], c.center[1], c.center[2], c.center[3],
      c.up[1], c.up[2], c.up[3], c.fov))
  else
    local tf, step, size, dev, png = words[2], tonumber(words[3]), tonumber(words[4]), words[5], words[6]
    local o = {tf = tfs[tf], camera = camera(size), step = step, device = dev, background = {0, 0, 0, 1}}
    local t0 = cdvr.clock()
    local img = cdvr.render(v, o)
    local ms = (cdvr.clock() - t0) * 1e3
    if png ~= "-" then img:save(png) end
    print(("%.3f"):format(ms))
  end
  io.stdout:flush()
end
"""


class CdvrServer:
    """One long-lived cdvr process rendering one volume on request."""

    def __init__(self, exe, path, raw, tfs, script):
        pts = "{" + ", ".join(
            "[%r] = {%s, unit = 1}" % (name, ", ".join("{%r, %r, %r, %r, %r}" % p for p in tf))
            for name, tf in tfs.items()) + "}"
        with open(script, "w") as f:  # a script file: `cdvr -e` takes no arguments
            f.write(SERVER)
        self.p = subprocess.Popen([exe, script, path, raw, pts], stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, text=True)
        grid = self._line().split()
        if grid[0] != "grid":
            raise RuntimeError("cdvr server: unexpected answer")
        self.dims = [int(x) for x in grid[1:4]]
        self.origin = [float(x) for x in grid[4:7]]
        self.spacing = [float(x) for x in grid[7:10]]

    def _line(self):
        line = self.p.stdout.readline()
        if not line:
            raise RuntimeError("cdvr server exited (see its error above)")
        return line.strip()

    def _ask(self, line):
        self.p.stdin.write(line + "\n")
        self.p.stdin.flush()
        return self._line()

    def camera(self, size):
        c = [float(x) for x in self._ask(f"camera {size}").split()[1:]]
        return c[0:3], c[3:6], c[6:9], c[9]

    def render(self, tf, step, size, device, png="-"):
        return float(self._ask(f"render {tf} {step} {size} {device} {png}"))

    def close(self):
        self.p.stdin.close()
        self.p.wait()


class VtkFixedPoint:
    """A long-lived vtkFixedPointVolumeRayCastMapper scene; render() returns the mapper's time
    without the display step and the ray casting alone (ms)."""

    def __init__(self, raw, grid):
        import numpy as np
        import vtk
        from vtk.util.numpy_support import numpy_to_vtk
        image = vtk.vtkImageData()
        image.SetDimensions(*grid.dims)
        image.SetOrigin(*grid.origin)
        image.SetSpacing(*grid.spacing)
        image.GetPointData().SetScalars(numpy_to_vtk(np.fromfile(raw, dtype=np.uint8), deep=True))
        self.color, self.opacity = vtk.vtkColorTransferFunction(), vtk.vtkPiecewiseFunction()
        prop = vtk.vtkVolumeProperty()
        prop.SetColor(self.color)
        prop.SetScalarOpacity(self.opacity)
        prop.SetScalarOpacityUnitDistance(1.0)
        prop.SetInterpolationTypeToLinear()
        prop.ShadeOff()
        m = self.mapper = vtk.vtkFixedPointVolumeRayCastMapper()
        m.SetInputData(image)
        m.AutoAdjustSampleDistancesOff()
        m.SetImageSampleDistance(1.0)
        m.SetNumberOfThreads(os.cpu_count() or 1)
        self.marks = {}
        m.AddObserver(vtk.vtkCommand.VolumeMapperRenderStartEvent, self._mark("start"))
        m.AddObserver(vtk.vtkCommand.VolumeMapperRenderEndEvent, self._mark("end"))
        volume = vtk.vtkVolume()
        volume.SetMapper(m)
        volume.SetProperty(prop)
        self.ren = vtk.vtkRenderer()
        self.ren.AddVolume(volume)
        self.ren.SetBackground(0, 0, 0)
        self.win = vtk.vtkRenderWindow()
        self.win.SetOffScreenRendering(1)
        self.win.AddRenderer(self.ren)
        self.case = None

    def _mark(self, name):
        def cb(obj, event):
            self.marks[name] = time.perf_counter()
        return cb

    def set_case(self, tf, step, size, cam):
        if (tuple(tf), step, size) == self.case:
            return
        self.case = (tuple(tf), step, size)
        self.color.RemoveAllPoints()
        self.opacity.RemoveAllPoints()
        for v, r, g, b, a in tf:
            self.color.AddRGBPoint(v, r, g, b)
            self.opacity.AddPoint(v, a)
        self.mapper.SetSampleDistance(step)
        self.mapper.SetInteractiveSampleDistance(step)
        eye, center, up, fov = cam
        c = self.ren.GetActiveCamera()
        c.SetPosition(*eye)
        c.SetFocalPoint(*center)
        c.SetViewUp(*up)
        c.SetViewAngle(fov)
        self.ren.ResetCameraClippingRange()
        self.win.SetSize(size, size)
        self.size = size
        self.win.Render()  # the first frame of a case builds the mapper's tables: not timed

    def render(self, png=None):
        self.marks.clear()
        t0 = time.perf_counter()
        self.win.Render()
        if "end" not in self.marks:
            raise RuntimeError("VTK did not ray cast (no VolumeMapperRenderEndEvent)")
        mapper_ms = (self.marks["end"] - t0) * 1e3
        cast_ms = (self.marks["end"] - self.marks["start"]) * 1e3
        if png:
            save_raycast_image(self.mapper, self.size, png)
        return mapper_ms, cast_ms


def loadavg():
    try:
        with open("/proc/loadavg") as f:
            return f.read().split()[0]
    except OSError:
        return "nan"


def median(xs):
    s = sorted(xs)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def fmt_db(x):
    return "inf" if x == float("inf") else "nan" if x != x else f"{x:.2f}"


def run_alternating(args):
    servers = [("new", os.path.abspath(args.cdvr))]
    if args.old:
        servers.append(("old", os.path.abspath(args.old)))
    devices = [d for d in args.devices.split(",") if d]
    tfnames = [t for t in args.tfs.split(",") if t]
    steps = [float(x) for x in args.steps.split(",")]
    sizes = [int(x) for x in args.sizes.split(",")]
    tty = sys.stderr.isatty()
    print("volume,tf,step,size,renderer,repeats,median_ms,speedup_vs_vtk_median,speedup_min,"
          "speedup_max,psnr_vs_vtk_raycast_db,vtk_mapper_ms,vtk_cast_ms,load_before,load_after")
    for vname in args.volumes.split(","):
        path = VOLUMES[vname]
        raw = os.path.join(args.out, f"{vname}.raw")
        tfs = {t: TFS[(vname, t)] for t in tfnames}
        cds = {}
        for i, (label, exe) in enumerate(servers):
            cds[label] = CdvrServer(exe, path, raw if i == 0 else "-", tfs,
                                    os.path.join(args.out, f"vs_vtk_server_{label}.lua"))
        grid = cds["new"]
        vt = VtkFixedPoint(raw, grid)
        os.remove(raw)
        renderers = ["vtk"] + [f"cdvr_{label}_{d}" for label, _ in servers for d in devices]
        for tname in tfnames:
            for step in steps:
                for size in sizes:
                    cam = grid.camera(size)
                    for label in cds:
                        if label != "new":
                            cds[label].camera(size)
                    vt.set_case(tfs[tname], step, size, cam)
                    for r in renderers[1:]:  # first frame: kernels, uploads; not timed
                        _, label, dev = r.split("_")
                        cds[label].render(tname, step, size, dev)
                    tag = f"{vname}_{tname}_s{step:g}_{size}"
                    times = {r: [] for r in renderers}
                    cast = []
                    load_before = loadavg()
                    for rnd in range(args.repeats):
                        last = rnd == args.repeats - 1
                        k = rnd % len(renderers)
                        for r in renderers[k:] + renderers[:k]:
                            if tty:
                                sys.stderr.write(f"\r\033[K{tag} round {rnd + 1}/{args.repeats}: {r}")
                            png = os.path.join(args.out, f"{tag}_{r}.png") if last else None
                            if r == "vtk":
                                mapper_ms, cast_ms = vt.render(png)
                                times[r].append(mapper_ms)
                                cast.append(cast_ms)
                            else:
                                _, label, dev = r.split("_")
                                times[r].append(cds[label].render(tname, step, size, dev, png or "-"))
                    if tty:
                        sys.stderr.write("\r\033[K")
                    load_after = loadavg()
                    ref_png = os.path.join(args.out, f"{tag}_vtk.png")
                    vms, cms = median(times["vtk"]), median(cast)
                    for r in renderers:
                        ratios = [a / b for a, b in zip(times["vtk"], times[r])]
                        p = psnr(os.path.join(args.out, f"{tag}_{r}.png"), ref_png)
                        print(f"{vname},{tname},{step:g},{size},{r},{args.repeats},"
                              f"{median(times[r]):.2f},{median(ratios):.3f},{min(ratios):.3f},"
                              f"{max(ratios):.3f},{fmt_db(p)},{vms:.2f},{cms:.2f},{load_before},"
                              f"{load_after}")
                        sys.stdout.flush()
        for c in cds.values():
            c.close()
    print(f"# images in {args.out}; {os.cpu_count()} cores", file=sys.stderr)


def run_sequential(args):
    vtk_png = os.path.join(args.out, "vtk.png")
    raw_png = os.path.join(args.out, "vtk_raycast.png")
    volume = VOLUMES[args.volumes.split(",")[0]]
    vtk_ms = render_vtk(volume, args.size, args.repeats, vtk_png, raw_png)
    # image_psnr_vs_vtk_db: against the window VTK shows; psnr_vs_vtk_raycast_db: against the
    # mapper's ray-cast image before VTK's display resampling (see save_raycast_image)
    print("renderer,median_ms,fps,speedup_vs_vtk,image_psnr_vs_vtk_db,psnr_vs_vtk_raycast_db")
    print(f"vtk_fixed_point,{vtk_ms:.2f},{1e3 / vtk_ms:.2f},1.00,inf,{psnr(vtk_png, raw_png):.2f}")
    for device in ("cl", "cpu"):
        png = os.path.join(args.out, f"cdvr_{device}.png")
        try:
            ms = render_cdvr(os.path.abspath(args.cdvr), volume, args.size, args.repeats, device, png)
        except RuntimeError as e:
            print(f"cdvr_{device},nan,nan,nan,nan,nan  # {e}")
            continue
        print(f"cdvr_{device},{ms:.2f},{1e3 / ms:.2f},{vtk_ms / ms:.2f},{psnr(png, vtk_png):.2f},"
              f"{psnr(png, raw_png):.2f}")
    print(f"# images in {args.out}; {os.cpu_count()} cores; step {STEP}, {args.size}x{args.size}",
          file=sys.stderr)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--volumes", default="engine,colin27")
    ap.add_argument("--tfs", default="ours,slicer")
    ap.add_argument("--steps", default="0.5,1.0")
    ap.add_argument("--sizes", default="512,1024")
    ap.add_argument("--devices", default="cl,cpu")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--size", type=int, default=512, help="--sequential only")
    ap.add_argument("--cdvr", default=os.path.join(ROOT, "build", "cdvr"),
                    help="cdvr executable to benchmark")
    ap.add_argument("--old", help="a second cdvr executable, interleaved as well")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "vs_vtk"))
    ap.add_argument("--sequential", action="store_true")
    args = ap.parse_args()
    ensure_packages()
    os.makedirs(args.out, exist_ok=True)
    if args.sequential:
        run_sequential(args)
    else:
        run_alternating(args)


if __name__ == "__main__":
    main()
