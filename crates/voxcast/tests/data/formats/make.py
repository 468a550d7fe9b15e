#!/usr/bin/env python3
"""Writes the reference files of tests/formats.rs with the tools that write
these formats (nibabel for NIfTI-2, Analyze 7.5 and MGH/MGZ; minc-tools'
rawtominc for MINC-2) and prints what nibabel reads back: the numbers the
test asserts. Run it from this folder:

    python3 -m venv /tmp/nibvenv && /tmp/nibvenv/bin/pip install nibabel numpy
    /tmp/nibvenv/bin/python make.py > expected.txt
    # MINC-2 also needs `rawtominc` (apt-get install minc-tools).

Every volume is 7×5×3 with distinct values (x fastest on disk), a spacing
of 1.5 × 2 × 2.5 and a non-zero origin.
"""
import gzip
import shutil
import subprocess

import nibabel as nib
import numpy as np

DIMS = (7, 5, 3)
i, j, k = np.meshgrid(*[np.arange(n) for n in DIMS], indexing="ij")
BASE = (i + 7 * j + 35 * k) * 3 - 50  # -50 … 262, distinct
SPACING = (1.5, 2.0, 2.5)


def affine(t):
    a = np.diag(SPACING + (1.0,))
    a[:3, 3] = t
    return a


def report(name, img):
    """What nibabel reads back: dims, type, zooms, voxel-0 position, stats."""
    img = nib.load(name)
    d = np.asarray(img.dataobj).astype(np.float64)  # scaled values
    if name.endswith(".mnc"):
        # nibabel keeps MINC's file order; voxcast reorders to x, y, z.
        import h5py
        with h5py.File(name) as f:
            order = f["minc-2.0/image/0/image"].attrs["dimorder"]
        order = (order.decode() if isinstance(order, bytes) else str(order)).split(",")
        print(f"  file shape {d.shape}, dimorder {order}")
        axes = {"xspace": 0, "yspace": 1, "zspace": 2}
        d = np.transpose(d, np.argsort([axes[n] for n in order]))
    print(f"{name}: dims {d.shape} stored {img.get_data_dtype()} "
          f"zooms {tuple(float(z) for z in img.header.get_zooms()[:3])}")
    print(f"  affine translation {tuple(float(x) for x in img.affine[:3, 3])}")
    print(f"  min {d.min()} max {d.max()} mean {d.mean():.6f} sum {d.sum()}")
    for v in [(0, 0, 0), (6, 0, 0), (0, 4, 0), (0, 0, 2), (3, 2, 1), (6, 4, 2)]:
        print(f"  v{v} = {d[v]}")


# NIfTI-2, little-endian int16 with scl_slope 0.5 / scl_inter 10, qform
# origin; and big-endian float32, gzipped, sform only.
img = nib.Nifti2Image(BASE.astype(np.int16), affine((-10.0, 20.0, 5.0)))
img.header.set_slope_inter(0.5, 10.0)
img.header.set_qform(img.affine, code=1)
img.header.set_sform(None, code=0)
nib.save(img, "nifti2_le.nii")
report("nifti2_le.nii", img)

hdr = nib.Nifti2Header(endianness=">")
img = nib.Nifti2Image((BASE / 4.0).astype(">f4"), affine((3.25, -7.5, 12.0)), header=hdr)
img.header.set_qform(None, code=0)
img.header.set_sform(img.affine, code=2)
nib.save(img, "nifti2_be.nii.gz")
report("nifti2_be.nii.gz", img)

# Analyze 7.5: plain little-endian uint8 (no origin: voxcast reads 0), and
# SPM's big-endian int16 with an origin (`originator`) and a scale factor.
UCHAR = (i + 7 * j + 35 * k) * 2  # 0 … 208, distinct
img = nib.AnalyzeImage(UCHAR.astype(np.uint8), affine((0.0, 0.0, 0.0)))
nib.save(img, "analyze_le.hdr")
report("analyze_le.hdr", img)

hdr = nib.Spm99AnalyzeHeader(endianness=">")
hdr.set_data_shape(DIMS)
hdr.set_data_dtype(np.int16)
hdr.set_zooms(SPACING)
hdr.set_slope_inter(2.0)
hdr["origin"][:3] = [4, 4, 3]  # 1-based voxel of the world origin
# nibabel's header writer; the image file is the raw big-endian voxels
# (Spm99AnalyzeImage would also write SPM's .mat file, which needs scipy).
with open("analyze_spm_be.hdr", "wb") as f:
    hdr.write_to(f)
with open("analyze_spm_be.img", "wb") as f:
    f.write(BASE.astype(">i2").tobytes(order="F"))
report("analyze_spm_be.hdr", img)
print("  originator", nib.load("analyze_spm_be.hdr").header["origin"][:3].tolist())

# MGH (always big-endian): float32 in a conformed (LIA) orientation, and
# MGZ uchar, axis aligned (RAS).
# Columns: x → left, y → inferior, z → anterior.
lia = np.array([[-1.5, 0, 0, 4.0], [0, 0, 2.5, 30.0], [0, -2.0, 0, -12.0], [0, 0, 0, 1]])
img = nib.MGHImage((BASE / 8.0).astype(np.float32), lia)
nib.save(img, "brain.mgh")
report("brain.mgh", img)
img = nib.MGHImage(UCHAR.astype(np.uint8), affine((-20.0, 8.0, 1.25)))
nib.save(img, "brain.mgz")
report("brain.mgz", img)

# MINC-2 (HDF5) by minc-tools' rawtominc: int16 normalised per slice
# (image-min/image-max from -scan_range), transverse (zspace,yspace,xspace)
# and sagittal (xspace,zspace,yspace) orders.
if shutil.which("rawtominc"):
    common = ["rawtominc", "-2", "-clobber", "-short", "-signed", "-scan_range",
              "-xstep", "1.5", "-ystep", "2", "-zstep", "2.5",
              "-xstart", "-10", "-ystart", "20", "-zstart", "5"]
    raw = BASE.astype("<i2").transpose(2, 1, 0).tobytes()  # z slowest, x fastest
    subprocess.run(common + ["minc2.mnc", "3", "5", "7"], input=raw, check=True)
    report("minc2.mnc", None)
    raw = BASE.astype("<i2").transpose(0, 2, 1).tobytes()  # x slowest, y fastest
    subprocess.run(common + ["-sagittal", "minc2_sagittal.mnc", "7", "3", "5"],
                   input=raw, check=True)
    report("minc2_sagittal.mnc", None)
else:
    print("rawtominc not found (apt-get install minc-tools): MINC-2 files not made")
