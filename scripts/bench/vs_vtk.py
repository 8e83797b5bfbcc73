#!/usr/bin/python3
"""scripts/bench/vs_vtk.py [--volume PATH] [--repeats N] [--size 512] [--cdvr build/cdvr]

Renders the engine CT (256x256x128, ../shared/data) with the same camera, transfer function
and sample distance in VTK's vtkFixedPointVolumeRayCastMapper (offscreen, under xvfb-run) and in
cdvr (device cl and cpu), in one run; prints median frame times, their ratios, and the image
PSNR of each cdvr image against VTK's. Installs python3-vtk9, python3-numpy and xvfb with apt-get when
missing, and re-executes itself under xvfb-run when no display is set.
Run from the repository root after building (build/cdvr, or the executable given by --cdvr).
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
        os.execvpe("xvfb-run", ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24",
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


def main():
    ap = argparse.ArgumentParser()
    default = os.path.join(os.environ.get("CDVR_SHARED_DATA", os.path.join(ROOT, "..", "shared", "data")),
                           "ct", "engine_256x256x128_u8.nrrd")
    ap.add_argument("--volume", default=default)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--cdvr", default=os.path.join(ROOT, "build", "cdvr"),
                    help="cdvr executable to benchmark")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "vs_vtk"))
    args = ap.parse_args()
    ensure_packages()
    os.makedirs(args.out, exist_ok=True)
    vtk_png = os.path.join(args.out, "vtk.png")
    raw_png = os.path.join(args.out, "vtk_raycast.png")
    vtk_ms = render_vtk(args.volume, args.size, args.repeats, vtk_png, raw_png)
    # image_psnr_vs_vtk_db: against the window VTK shows; psnr_vs_vtk_raycast_db: against the
    # mapper's ray-cast image before VTK's display resampling (see save_raycast_image)
    print("renderer,median_ms,fps,speedup_vs_vtk,image_psnr_vs_vtk_db,psnr_vs_vtk_raycast_db")
    print(f"vtk_fixed_point,{vtk_ms:.2f},{1e3 / vtk_ms:.2f},1.00,inf,{psnr(vtk_png, raw_png):.2f}")
    for device in ("cl", "cpu"):
        png = os.path.join(args.out, f"cdvr_{device}.png")
        try:
            ms = render_cdvr(os.path.abspath(args.cdvr), args.volume, args.size, args.repeats, device, png)
        except RuntimeError as e:
            print(f"cdvr_{device},nan,nan,nan,nan,nan  # {e}")
            continue
        print(f"cdvr_{device},{ms:.2f},{1e3 / ms:.2f},{vtk_ms / ms:.2f},{psnr(png, vtk_png):.2f},"
              f"{psnr(png, raw_png):.2f}")
    print(f"# images in {args.out}; {os.cpu_count()} cores; step {STEP}, {args.size}x{args.size}",
          file=sys.stderr)


if __name__ == "__main__":
    main()
