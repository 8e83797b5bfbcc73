#!/usr/bin/python3
"""scripts/bench/look_vtk.py [--volumes engine,colin27] [--repeats 5] [--size 512] [--cdvr build/cdvr]
                             [--out out/look_vtk] [--gpu]

Shading and MIP against VTK (issue 22), in one run: the engine CT and Colin27 (../shared/data),
rendered with the same camera (cdvr.orbit_camera's, azimuth 45, elevation 25), transfer function
(scripts/bench/look.lua's), opacity unit (1 world unit) and sample distance (0.5) by VTK's
vtkFixedPointVolumeRayCastMapper (and vtkGPUVolumeRayCastMapper with --gpu, when it works
under Xvfb/Mesa) and by cdvr (device cl and cpu), for four cases: composite unshaded, composite
with ShadeOn and VTK's default ambient 0.1, diffuse 0.7, specular 0.2, power 10 (cdvr: shade=true
with the same numbers, headlight), SetBlendModeToMaximumIntensity (cdvr blend="max") and
SetBlendModeToMinimumIntensity (blend="min"). cdvr runs as a subprocess that renders on request,
so the renderers are interleaved: each round renders every (renderer, case) once, and the median
of the rounds is reported. CSV on stdout; images in --out (VTK's ray-cast image before its
display resampling, see vs_vtk.py, and cdvr's), PSNR of each cdvr image against VTK's image of
the same case (and against vtkGPUVolumeRayCastMapper's window image with --gpu: its shading is
the gradient of the data at each sample, as cdvr's, where the fixed-point mapper shades with
quantised precomputed normals). Installs and re-executes as vs_vtk.py does (python3-vtk9 under xvfb-run).
Run from the repository root after building.
"""
import argparse
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import vs_vtk  # noqa: E402  (ensure_packages, save_raycast_image, write_png, psnr)

DATA = os.environ.get("CDVR_SHARED_DATA", os.path.join(ROOT, "..", "shared", "data"))
# The TFs of scripts/bench/look.lua: value, r, g, b, opacity per unit length.
VOLUMES = {
    "engine": (os.path.join(DATA, "ct", "engine_256x256x128_u8.nrrd"),
               [(0, 0, 0, 0, 0), (80, 0.6, 0.3, 0.1, 0.0), (120, 0.8, 0.5, 0.2, 0.02),
                (180, 0.9, 0.9, 0.9, 0.3), (255, 1.0, 1.0, 1.0, 0.9)]),
    "colin27": (os.path.join(DATA, "mri", "colin27_t1_301x370x316_u8.nii.gz"),
                [(0, 0, 0, 0, 0), (35, 0, 0, 0, 0), (60, 0.8, 0.45, 0.35, 0.03),
                 (90, 1.0, 0.85, 0.7, 0.3), (130, 1, 1, 1, 0.8)]),
}
STEP = 0.5
SHADE = dict(ambient=0.1, diffuse=0.7, specular=0.2, specular_power=10.0)
CASES = ["composite", "composite_shaded", "max", "min"]

# The cdvr side: loads the volume, prints its grid and camera, writes its voxels for VTK, then
# renders one case per request line "<case> <device> <png or ->" and answers the milliseconds.
SERVER = r"""
local path, size, step, raw = arg[1], tonumber(arg[2]), tonumber(arg[3]), arg[4]
local tfpoints = load("return " .. arg[5])()
local v = assert(cdvr.load(path))
local tf = cdvr.tf(tfpoints)
local cam = cdvr.orbit_camera(v, {azimuth = 45, elevation = 25, width = size, height = size})
local nx, ny, nz = v:dims()
local ox, oy, oz = v:origin()
local sx, sy, sz = v:spacing()
v:save_raw(raw)
print(("grid %d %d %d %.17g %.17g %.17g %.17g %.17g %.17g"):format(nx, ny, nz, ox, oy, oz, sx, sy, sz))
print(("camera %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g"):format(
  cam.eye[1], cam.eye[2], cam.eye[3], cam.center[1], cam.center[2], cam.center[3],
  cam.up[1], cam.up[2], cam.up[3], cam.fov))
io.stdout:flush()
local shade = {shade = true, ambient = %AMB%, diffuse = %DIF%, specular = %SPE%, specular_power = %POW%}
for line in io.lines() do
  local case, dev, png = line:match("^(%S+) (%S+) (%S+)$")
  local o = {tf = tf, camera = cam, step = step, device = dev, background = {0, 0, 0, 1}}
  if case == "composite_shaded" then for k, x in pairs(shade) do o[k] = x end
  elseif case == "max" or case == "min" then o.blend = case end
  local t0 = cdvr.clock()
  local img = cdvr.render(v, o)
  local ms = (cdvr.clock() - t0) * 1e3
  if png ~= "-" then img:save(png) end
  print(("%.3f"):format(ms))
  io.stdout:flush()
end
"""


class Cdvr:
    def __init__(self, exe, path, size, tf, raw, script):
        lua = (SERVER.replace("%AMB%", str(SHADE["ambient"])).replace("%DIF%", str(SHADE["diffuse"]))
               .replace("%SPE%", str(SHADE["specular"])).replace("%POW%", str(SHADE["specular_power"])))
        pts = "{" + ", ".join("{%r, %r, %r, %r, %r}" % p for p in tf) + ", unit = 1}"
        with open(script, "w") as f:  # a script file: `cdvr -e` takes no arguments
            f.write(lua)
        self.p = subprocess.Popen([exe, script, path, str(size), str(STEP), raw, pts],
                                  stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        grid = self._line().split()
        camera = self._line().split()
        if grid[0] != "grid" or camera[0] != "camera":
            raise RuntimeError("cdvr server: unexpected answer")
        self.dims = [int(x) for x in grid[1:4]]
        self.origin = [float(x) for x in grid[4:7]]
        self.spacing = [float(x) for x in grid[7:10]]
        c = [float(x) for x in camera[1:]]
        self.eye, self.center, self.up, self.fov = c[0:3], c[3:6], c[6:9], c[9]

    def _line(self):
        line = self.p.stdout.readline()
        if not line:
            raise RuntimeError("cdvr server exited (see its error above)")
        return line.strip()

    def render(self, case, device, png="-"):
        self.p.stdin.write(f"{case} {device} {png}\n")
        self.p.stdin.flush()
        return float(self._line())

    def close(self):
        self.p.stdin.close()
        self.p.wait()


class Vtk:
    def __init__(self, kind, raw, grid, tf, size, cam):
        import numpy as np
        import vtk
        from vtk.util.numpy_support import numpy_to_vtk
        self.kind = kind
        arr = np.fromfile(raw, dtype=np.uint8)
        image = vtk.vtkImageData()
        image.SetDimensions(*grid.dims)
        image.SetOrigin(*grid.origin)
        image.SetSpacing(*grid.spacing)
        image.GetPointData().SetScalars(numpy_to_vtk(arr, deep=True))
        color, opacity = vtk.vtkColorTransferFunction(), vtk.vtkPiecewiseFunction()
        for v, r, g, b, a in tf:
            color.AddRGBPoint(v, r, g, b)
            opacity.AddPoint(v, a)
        self.prop = prop = vtk.vtkVolumeProperty()
        prop.SetColor(color)
        prop.SetScalarOpacity(opacity)
        prop.SetScalarOpacityUnitDistance(1.0)
        prop.SetInterpolationTypeToLinear()
        prop.SetAmbient(SHADE["ambient"])
        prop.SetDiffuse(SHADE["diffuse"])
        prop.SetSpecular(SHADE["specular"])
        prop.SetSpecularPower(SHADE["specular_power"])
        if kind == "fixed_point":
            m = vtk.vtkFixedPointVolumeRayCastMapper()
            m.SetInteractiveSampleDistance(STEP)
            m.SetImageSampleDistance(1.0)
            m.SetNumberOfThreads(os.cpu_count() or 1)
        else:
            m = vtk.vtkGPUVolumeRayCastMapper()
        m.SetInputData(image)
        m.SetSampleDistance(STEP)
        m.AutoAdjustSampleDistancesOff()
        self.mapper = m
        volume = vtk.vtkVolume()
        volume.SetMapper(m)
        volume.SetProperty(prop)
        ren = vtk.vtkRenderer()
        ren.AddVolume(volume)
        ren.SetBackground(0, 0, 0)
        c = ren.GetActiveCamera()
        c.SetPosition(*cam.eye)
        c.SetFocalPoint(*cam.center)
        c.SetViewUp(*cam.up)
        c.SetViewAngle(cam.fov)
        ren.ResetCameraClippingRange()
        self.win = win = vtk.vtkRenderWindow()
        win.SetOffScreenRendering(1)
        win.AddRenderer(ren)
        win.SetSize(size, size)
        self.size = size
        self.case = None

    def set_case(self, case):
        if case == self.case:
            return
        self.case = case
        if case == "composite_shaded":
            self.prop.ShadeOn()
        else:
            self.prop.ShadeOff()
        {"max": self.mapper.SetBlendModeToMaximumIntensity,
         "min": self.mapper.SetBlendModeToMinimumIntensity}.get(
            case, self.mapper.SetBlendModeToComposite)()
        self.win.Render()  # the first frame of a case builds its tables: not timed

    def render(self, case, png=None):
        self.set_case(case)
        t0 = time.perf_counter()
        self.win.Render()
        ms = (time.perf_counter() - t0) * 1e3
        if png:
            if self.kind == "fixed_point":
                vs_vtk.save_raycast_image(self.mapper, self.size, png)
            else:
                import vtk
                w2i = vtk.vtkWindowToImageFilter()
                w2i.SetInput(self.win)
                w2i.ReadFrontBufferOff()
                w2i.Update()
                writer = vtk.vtkPNGWriter()
                writer.SetFileName(png)
                writer.SetInputConnection(w2i.GetOutputPort())
                writer.Write()
        return ms


def loadavg():
    try:
        with open("/proc/loadavg") as f:
            return f.read().split()[0]
    except OSError:
        return "nan"


def fmt_db(x):
    return "inf" if x == float("inf") else "nan" if x != x else f"{x:.2f}"


def median(xs):
    s = sorted(xs)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--volumes", default="engine,colin27")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--cdvr", default=os.path.join(ROOT, "build", "cdvr"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "look_vtk"))
    ap.add_argument("--gpu", action="store_true", help="also vtkGPUVolumeRayCastMapper")
    args = ap.parse_args()
    vs_vtk.ensure_packages()
    os.makedirs(args.out, exist_ok=True)
    tty = sys.stderr.isatty()
    print("volume,case,renderer,size,step,repeats,median_ms,time_ratio_to_vtk_fixed_point,"
          "psnr_vs_vtk_fixed_point_db,psnr_vs_vtk_gpu_db,load_before,load_after")
    for name in args.volumes.split(","):
        path, tf = VOLUMES[name]
        raw = os.path.join(args.out, f"{name}.raw")
        cd = Cdvr(os.path.abspath(args.cdvr), path, args.size, tf, raw,
                  os.path.join(args.out, "look_vtk_server.lua"))
        renderers = {"vtk_fixed_point": Vtk("fixed_point", raw, cd, tf, args.size, cd)}
        if args.gpu:
            try:
                g = Vtk("gpu", raw, cd, tf, args.size, cd)
                g.set_case("composite")
                renderers["vtk_gpu"] = g
            except Exception as e:  # noqa: BLE001
                print(f"# vtk_gpu unavailable: {e}", file=sys.stderr)
        cdvr_devices = ["cl", "cpu"]
        for dev in cdvr_devices:
            for case in CASES:
                cd.render(case, dev)  # warm-up: kernels, uploads
        times = {}
        load_before = loadavg()
        for rnd in range(args.repeats):
            last = rnd == args.repeats - 1
            for case in CASES:
                for rname, r in renderers.items():
                    if tty:
                        sys.stderr.write(f"\r\033[K{name} round {rnd + 1}/{args.repeats}: {rname} {case}")
                    png = os.path.join(args.out, f"{name}_{case}_{rname}.png") if last else None
                    times.setdefault((case, rname), []).append(r.render(case, png))
                for dev in cdvr_devices:
                    png = os.path.join(args.out, f"{name}_{case}_cdvr_{dev}.png") if last else "-"
                    times.setdefault((case, "cdvr_" + dev), []).append(cd.render(case, dev, png))
        if tty:
            sys.stderr.write("\r\033[K")
        load_after = loadavg()
        cd.close()
        os.remove(raw)
        for case in CASES:
            ref_ms = median(times[(case, "vtk_fixed_point")])
            ref_png = os.path.join(args.out, f"{name}_{case}_vtk_fixed_point.png")
            for rname in list(renderers) + ["cdvr_" + d for d in cdvr_devices]:
                ms = median(times[(case, rname)])
                png = os.path.join(args.out, f"{name}_{case}_{rname}.png")
                p = vs_vtk.psnr(png, ref_png)
                gpu_png = os.path.join(args.out, f"{name}_{case}_vtk_gpu.png")
                g = vs_vtk.psnr(png, gpu_png) if "vtk_gpu" in renderers else float("nan")
                print(f"{name},{case},{rname},{args.size},{STEP},{args.repeats},{ms:.2f},"
                      f"{ms / ref_ms:.3f},{fmt_db(p)},{fmt_db(g)},{load_before},{load_after}")
                sys.stdout.flush()
    print(f"# images in {args.out}; {os.cpu_count()} cores", file=sys.stderr)


if __name__ == "__main__":
    main()
