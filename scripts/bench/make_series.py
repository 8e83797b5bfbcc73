#!/usr/bin/python3
"""scripts/bench/make_series.py OUTDIR [--timesteps 60] [--size 256] [--type u8|f32]
                                      [--noise 0.4] [--data ../shared/data]

A large time series for the scale benchmark (scripts/bench/scale.lua), made from the real
viscous-fingers series (../shared/data/series/viscousfingers, 60 timesteps of 64^3 f32):
each output timestep k of N is a blend of the two source timesteps around position
k * 59 / (N - 1) (linear in time), upsampled to SIZE^3 by trilinear interpolation (voxel
centres aligned at both ends: output voxel i samples source coordinate i * 63 / (SIZE - 1)),
plus light Gaussian noise (sigma NOISE in data units, fixed seed, so a run is reproducible).
Writes OUTDIR/vf{SIZE}_t{k:03d}.raw (little endian, no header), one file per timestep:
u8 quantised over the fixed window [0, 125] (the series' values lie in 0 .. ~124), or f32
data values; prints the cdvr.load_series call that reads them. 60 timesteps of 256^3 u8 are
1.0 GB (f32: 4.0 GB): the script refuses to start when the free space of OUTDIR is below
the output size plus 1 GB. Never commit the output. Needs python3-numpy.
"""
import argparse
import gzip
import os
import shutil
import sys

try:
    import numpy as np
except ImportError:
    sys.exit("make_series.py needs numpy: apt-get install python3-numpy")

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
WINDOW = (0.0, 125.0)


def read_nrrd(path):
    """Attached-header NRRD (raw or gzip) -> numpy array indexed [z, y, x]."""
    with open(path, "rb") as f:
        raw = f.read()
    end = raw.index(b"\n\n")
    fields = {}
    for line in raw[:end].decode().splitlines()[1:]:
        if ":" in line and not line.startswith("#"):
            k, v = line.split(":", 1)
            fields[k.strip()] = v.strip()
    dims = [int(x) for x in fields["sizes"].split()]
    if fields["type"] not in ("float", "float32"):
        raise ValueError(f"{path}: expected float voxels, got {fields['type']}")
    dtype = np.dtype("<f4" if fields.get("endian", "little") == "little" else ">f4")
    data = raw[end + 2:]
    if fields.get("encoding") in ("gzip", "gz"):
        data = gzip.decompress(data)
    arr = np.frombuffer(data, dtype=dtype, count=int(np.prod(dims))).astype(np.float32)
    return arr.reshape(dims[2], dims[1], dims[0])


def upsample_axis(a, axis, size):
    """Linear interpolation along one axis to `size` samples, ends aligned."""
    n = a.shape[axis]
    pos = np.arange(size, dtype=np.float64) * (n - 1) / (size - 1)
    i0 = np.minimum(np.floor(pos).astype(np.int64), n - 2)
    w = (pos - i0).astype(np.float32)
    shape = [1] * a.ndim
    shape[axis] = size
    w = w.reshape(shape)
    lo = np.take(a, i0, axis=axis)
    hi = np.take(a, i0 + 1, axis=axis)
    return lo + (hi - lo) * w


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--timesteps", type=int, default=60)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--type", choices=("u8", "f32"), default="u8")
    ap.add_argument("--noise", type=float, default=0.4)
    ap.add_argument("--data", default=os.environ.get("CDVR_SHARED_DATA",
                                                      os.path.join(ROOT, "..", "shared", "data")))
    args = ap.parse_args()
    src_dir = os.path.join(args.data, "series", "viscousfingers")
    names = sorted(n for n in os.listdir(src_dir) if n.endswith(".nrrd"))
    if len(names) < 2:
        sys.exit(f"{src_dir}: the viscous-fingers series is missing")
    os.makedirs(args.outdir, exist_ok=True)
    bytes_per = args.size ** 3 * (1 if args.type == "u8" else 4)
    need = bytes_per * args.timesteps + (1 << 30)
    free = shutil.disk_usage(args.outdir).free
    if free < need:
        sys.exit(f"{args.outdir}: {free / 1e9:.1f} GB free, {need / 1e9:.1f} GB needed")
    rng = np.random.default_rng(20240607)
    tty = sys.stderr.isatty()
    cache = {}

    def source(i):
        if i not in cache:
            if len(cache) > 2:
                cache.clear()
            cache[i] = read_nrrd(os.path.join(src_dir, names[i]))
        return cache[i]

    n_src = len(names)
    for k in range(args.timesteps):
        s = k * (n_src - 1) / max(args.timesteps - 1, 1)
        i0 = min(int(np.floor(s)), n_src - 2)
        w = np.float32(s - i0)
        vol = source(i0) * (1 - w) + source(i0 + 1) * w
        for axis in (2, 1, 0):
            vol = upsample_axis(vol, axis, args.size)
        vol += rng.normal(0.0, args.noise, vol.shape).astype(np.float32)
        if args.type == "u8":
            lo, hi = WINDOW
            q = np.floor((vol - lo) * (255.0 / (hi - lo)) + 0.5)
            out = np.clip(q, 0, 255).astype(np.uint8)
        else:
            out = vol.astype("<f4")
        path = os.path.join(args.outdir, f"vf{args.size}_t{k:03d}.raw")
        out.tofile(path)
        if tty:
            sys.stderr.write(f"\r{path} ({k + 1}/{args.timesteps})")
            sys.stderr.flush()
    if tty:
        sys.stderr.write("\n")
    pattern = os.path.join(args.outdir, f"vf{args.size}_t%03d.raw")
    print(f'cdvr.load_series("{pattern}", {{first=0, count={args.timesteps}, '
          f'dims={{{args.size},{args.size},{args.size}}}, type="{args.type}"}})')


if __name__ == "__main__":
    main()
