# scripts/bench/hostile_loaders.py DIR: hostile files of issue 21 items 4-5 (loader cases), written by hand so an old binary can be tried.
import struct, os, sys
d = sys.argv[1]; os.makedirs(d, exist_ok=True)
def nii(name, vox_offset=352.0, magic=b"n+1\0", pixdim=(1,1,1), sform=None, data=None, dims=(4,4,4)):
    h = bytearray(348)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, 3, dims[0], dims[1], dims[2], 1, 1, 1, 1)
    struct.pack_into("<hh", h, 70, 2, 8)         # uint8
    struct.pack_into("<8f", h, 76, 1.0, *pixdim, 1, 1, 1, 1)
    struct.pack_into("<f", h, 108, vox_offset)
    struct.pack_into("<f", h, 112, 0.0)
    if sform is not None:
        struct.pack_into("<h", h, 254, 1)
        struct.pack_into("<12f", h, 280, *sform)
    h[344:348] = magic
    n = dims[0]*dims[1]*dims[2]
    body = bytes(h) + b"\0\0\0\0" + (data if data is not None else bytes(range(n)))
    open(os.path.join(d, name), "wb").write(body + bytes(200))
nii("vox_1e18.nii", vox_offset=1e18)
nii("vox_100.nii", vox_offset=100.0)
nii("vox_352_5.nii", vox_offset=352.5)
nii("bad_magic.nii", magic=b"xyz\0")
nii("sform_zero.nii", sform=[0]*12)
nii("pixdim_0.nii", pixdim=(0,1,1))
nii("pixdim_nan.nii", pixdim=(float("nan"),1,1))
nii("pixdim_inf.nii", pixdim=(float("inf"),1,1))
def nrrd(name, fields, data=bytes(range(8)), typ="uchar"):
    hdr = "NRRD0004\ntype: %s\ndimension: 3\nsizes: 2 2 2\n%sencoding: raw\n\n" % (typ, fields)
    open(os.path.join(d, name), "wb").write(hdr.encode() + data)
nrrd("dirs_zero.nrrd", "space: left-posterior-superior\nspace directions: (0,0,0) (0,1,0) (0,0,1)\n")
nrrd("spacing_nan.nrrd", "spacings: nan 1 1\n")
nrrd("spacing_neg.nrrd", "spacings: -1 1 1\n")
nrrd("f64_1e300.nrrd", "", data=struct.pack("<8d", 1e300, 0, 1, 2, 3, 4, 5, 6), typ="double\nendian: little")
open(os.path.join(d, "header_5mib.nrrd"), "wb").write(b"NRRD0004\n" + b"#" + b"x" * (5 << 20) + b"\ntype: uchar\ndimension: 1\nsizes: 1\nencoding: raw\n\n\0")
os.makedirs(os.path.join(d, "a/b"), exist_ok=True)
open(os.path.join(d, "a/b/passwd_abs.nhdr"), "w").write("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 2 2\nencoding: raw\ndata file: /etc/passwd\n")
open(os.path.join(d, "a/b/passwd_rel.nhdr"), "w").write("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 2 2\nencoding: raw\ndata file: ../../../../../../etc/passwd\n")
