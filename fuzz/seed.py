#!/usr/bin/env python3
"""Builds the seed corpus of every fuzz target in fuzz/corpus/<target>/.

Seeds come from the real test data (../shared/data, or $VOXCAST_DATA): small
files whole, headers of big ones with the sizes shrunk so that a few bytes
of the real voxels make a complete, valid file, and the first frames of the
FDS files; plus small synthetic files for the formats whose real files are
all big (VDB, DICOM, NIfTI, PNG/TIFF, Mitsuba .vol), and the repository's
own examples (scenes, transfer functions, geometry, OBJ meshes).

Inputs that hold several files use the layout of
crates/voxcast/src/fuzz_support.rs: the main file, then for each further
file FILE_MARKER + name + "\\n" + bytes.

Usage: fuzz/seed.py [--out DIR]   (run from anywhere; nothing is downloaded)
"""

import argparse
import gzip
import os
import struct
import sys
import zlib
from pathlib import Path

FILE_MARKER = b"\n%%voxcast-fuzz-file "
ROOT = Path(__file__).resolve().parent.parent


def data_dir():
    d = os.environ.get("VOXCAST_DATA")
    p = Path(d) if d else ROOT / ".." / "shared" / "data"
    if not p.is_dir():
        sys.exit(f"seed.py: no test data at {p} (set VOXCAST_DATA)")
    return p.resolve()


def join(main, *parts):
    out = bytearray(main)
    for name, data in parts:
        out += FILE_MARKER + name.encode() + b"\n" + data
    return bytes(out)


class Corpus:
    def __init__(self, out):
        self.out = out
        self.counts = {}

    def add(self, target, name, data):
        d = self.out / target
        d.mkdir(parents=True, exist_ok=True)
        (d / name).write_bytes(data)
        self.counts[target] = self.counts.get(target, 0) + 1


# --------------------------------------------------------------------------
# NRRD, MetaImage, VTK, raw


def nrrd(c, data):
    raw = (data / "neghip" / "neghip_64x64x64_uint8.raw").read_bytes()
    ct = (data / "ct_head_headsq" / "headsq_64x64x93_uint16le.raw").read_bytes()
    vox = raw[64 * 64 * 32 : 64 * 64 * 32 + 64]  # a row of real voxels
    c.add("nrrd", "neghip_header_only", (data / "neghip" / "neghip.nhdr").read_bytes())
    c.add(
        "nrrd",
        "neghip_detached_4x4x4",
        join(
            b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nspacings: 1 1 1\n"
            b"encoding: raw\ndata file: d.raw\n",
            ("d.raw", vox),
        ),
    )
    c.add(
        "nrrd",
        "ct_attached_u16",
        b"NRRD0004\n# CT\ntype: uint16\ndimension: 3\nsizes: 4 2 2\nspacings: 3.2 3.2 1.5\n"
        b"endian: little\nencoding: raw\n\n" + ct[40000:40032],
    )
    c.add(
        "nrrd",
        "gzip_space_directions",
        b"NRRD0005\ntype: short\ndimension: 3\nspace: left-posterior-superior\nsizes: 3 2 2\n"
        b"space directions: (1,0,0) (0,2,0) (0,0,3)\nspace origin: (10,20,30)\nendian: big\n"
        b"encoding: gzip\n\n" + gzip.compress(ct[40000:40024]),
    )
    c.add(
        "nrrd",
        "ascii_4d",
        b"NRRD0004\ntype: float\ndimension: 4\nsizes: 1 2 2 1\nkinds: scalar domain domain domain\n"
        b"encoding: ascii\n\n1.5 2 -3 4e2\n",
    )
    c.add(
        "nrrd",
        "list_files",
        join(
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nline skip: 1\n"
            b"byte skip: 1\ndata file: LIST\ns1.raw\ns2.raw\n",
            ("s1.raw", b"x\n" + vox[:4]),
            ("s2.raw", b"y\n" + vox[4:8]),
        ),
    )
    c.add(
        "nrrd",
        "format_files",
        join(
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: hex\n"
            b"data file: s%d.txt 1 2 1 2\n",
            ("s1.txt", vox[:4].hex().encode()),
            ("s2.txt", vox[4:8].hex().encode()),
        ),
    )


def metaimage(c, data):
    hdr = (data / "mr_head" / "HeadMRVolume.mhd").read_bytes()
    raw = (data / "mr_head" / "HeadMRVolume.raw").read_bytes()
    vox = raw[48 * 62 * 21 : 48 * 62 * 21 + 48]
    small = hdr.replace(b"DimSize = 48 62 42", b"DimSize = 4 4 3")
    c.add("metaimage", "mr_head_header_only", hdr)
    c.add("metaimage", "mr_head_4x4x3", join(small, ("HeadMRVolume.raw", vox)))
    c.add(
        "metaimage",
        "local_short",
        b"ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
        b"DimSize = 2 3 2\nElementSpacing = 1 2 3\nOffset = 5 6 7\nElementType = MET_SHORT\n"
        b"ElementDataFile = LOCAL\n" + raw[1000:1024],
    )
    c.add(
        "metaimage",
        "local_zlib",
        b"NDims = 3\nDimSize = 4 4 3\nElementType = MET_UCHAR\nCompressedData = True\n"
        b"CompressedDataSize = %d\nElementDataFile = LOCAL\n" % len(zlib.compress(vox))
        + zlib.compress(vox),
    )
    c.add(
        "metaimage",
        "list_doubles_msb",
        join(
            b"NDims = 3\nDimSize = 2 2 2\nElementType = MET_DOUBLE\nElementByteOrderMSB = True\n"
            b"HeaderSize = 2\nElementDataFile = LIST 2D\na.raw\nb.raw\n",
            ("a.raw", b"hh" + struct.pack(">4d", 1, 2, 3, 4)),
            ("b.raw", b"hh" + struct.pack(">4d", 5, 6, 7, 8)),
        ),
    )
    c.add(
        "metaimage",
        "pattern_files",
        join(
            b"NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = s%02d.raw 1 2 1\n",
            ("s01.raw", vox[:4]),
            ("s02.raw", vox[4:8]),
        ),
    )


def vtk(c, data):
    iron = (data / "iron_protein" / "ironProt.vtk").read_bytes()
    head = iron[: iron.index(b"LOOKUP_TABLE default\n") + len(b"LOOKUP_TABLE default\n")]
    body = iron[len(head) :]
    small = head.replace(b"DIMENSIONS 68 68 68", b"DIMENSIONS 4 4 2").replace(
        b"POINT_DATA 314432", b"POINT_DATA 32"
    )
    c.add("vtk", "iron_4x4x2", small + body[68 * 68 * 34 : 68 * 68 * 34 + 32] + b"\n")
    car = (data / "carotid_mra" / "carotid.vtk").read_bytes()
    i = car.index(b"LOOKUP_TABLE default\n") + len(b"LOOKUP_TABLE default\n")
    chead = car[:i]
    for a, b in [
        (b"DIMENSIONS 76 49 45", b"DIMENSIONS 2 2 2"),
        (b"POINT_DATA 167580", b"POINT_DATA 8"),
    ]:
        chead = chead.replace(a, b)
    c.add("vtk", "carotid_2x2x2_be_float", chead + car[i + 4 * 80000 : i + 4 * 80008] + car[-200:])
    c.add("vtk", "carotid_head", car[:2048])
    c.add(
        "vtk",
        "ascii_spacing_origin",
        b"# vtk DataFile Version 2.0\nascii test\nASCII\n\nDATASET STRUCTURED_POINTS\n"
        b"DIMENSIONS 2 2 1\nSPACING 1 2 3\nORIGIN 1 1 1\nPOINT_DATA 4\n"
        b"SCALARS s short 1\nLOOKUP_TABLE default\n1 2\n3 -4\nFIELD f 1\na 1 1 float\n0\n",
    )


def raw(c, data):
    ct = (data / "ct_head_headsq" / "headsq_64x64x93_uint16le.raw").read_bytes()

    def layout(dims, ty, be, skip):
        return struct.pack("<3QBBQ", *dims, ty, be, skip)

    c.add("raw", "u16_4x4x2", layout((4, 4, 2), 1, 0, 0) + ct[40000:40064])
    c.add("raw", "u8_skip", layout((3, 3, 3), 0, 0, 5) + b"HEADR" + bytes(range(27)))
    c.add("raw", "f32_be", layout((2, 2, 1), 3, 1, 0) + struct.pack(">4f", 0, 1, 2.5, -1))
    c.add("raw", "i16", layout((2, 1, 1), 2, 0, 0) + struct.pack("<2h", -5, 7))


# --------------------------------------------------------------------------
# NIfTI


def nifti_header(dims, datatype, bitpix, magic, vox_offset, pixdim=(1, 1, 1), big=False):
    e = ">" if big else "<"
    h = bytearray(348)
    struct.pack_into(e + "i", h, 0, 348)
    dim = [len(dims)] + list(dims) + [1] * (7 - len(dims))
    struct.pack_into(e + "8h", h, 40, *dim)
    struct.pack_into(e + "hh", h, 70, datatype, bitpix)
    struct.pack_into(e + "8f", h, 76, 1.0, *pixdim, 1, 1, 1, 1)
    struct.pack_into(e + "f", h, 108, vox_offset)
    struct.pack_into(e + "ff", h, 112, 1.0, 0.0)  # scl_slope, scl_inter
    struct.pack_into(e + "hh", h, 252, 1, 0)  # qform_code, sform_code
    struct.pack_into(e + "fff", h, 268, 10.0, 20.0, 30.0)  # qoffset
    h[328:344] = b"fuzz-seed".ljust(16, b"\0")  # intent_name
    h[344:348] = magic
    return bytes(h)


def nifti(c, data):
    ct = (data / "ct_head_headsq" / "headsq_64x64x93_uint16le.raw").read_bytes()
    v16 = ct[40000:40048]
    one = nifti_header((4, 3, 2), 512, 16, b"n+1\0", 352, (3.2, 3.2, 1.5)) + b"\0" * 4 + v16
    c.add("nifti", "u16_4x3x2", one)
    c.add("nifti", "u16_gz", gzip.compress(one))
    c.add(
        "nifti",
        "be_f32",
        nifti_header((2, 2, 2), 16, 32, b"n+1\0", 352, big=True)
        + b"\0" * 4
        + struct.pack(">8f", *range(8)),
    )
    h = bytearray(nifti_header((2, 2, 1, 1), 4, 16, b"n+1\0", 352))
    struct.pack_into("<ff", h, 112, 2.0, -1024.0)
    c.add("nifti", "i16_scaled_4d", bytes(h) + b"\0" * 4 + struct.pack("<4h", 1, -2, 3, 4))
    c.add(
        "nifti",
        "hdr_img_pair",
        join(nifti_header((2, 2, 2), 2, 8, b"ni1\0", 0), ("v.img", bytes(range(8)))),
    )
    c.add(
        "nifti",
        "i64_with_extension",
        nifti_header((2, 1, 1), 1024, 64, b"n+1\0", 368)
        + bytes([1, 0, 0, 0])
        + struct.pack("<ii", 16, 4)
        + b"abcdefgh"
        + struct.pack("<2q", 5, -7),
    )


# --------------------------------------------------------------------------
# PNG / TIFF slices


def png(w, h, depth, color, rows):
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))

    ihdr = struct.pack(">IIBBBBB", w, h, depth, color, 0, 0, 0)
    raw = b"".join(b"\0" + r for r in rows)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def tiff(w, h, bps, fmt, spp, pages):
    """Little-endian uncompressed TIFF, one strip per page."""
    out = bytearray(b"II*\0" + struct.pack("<I", 0))
    prev_next = 4
    for data in pages:
        data_off = len(out)
        out += data
        if len(out) % 2:
            out += b"\0"
        bps_off = 0
        if spp > 1:
            bps_off = len(out)
            out += struct.pack("<%dH" % spp, *([bps] * spp))
        entries = [
            (256, 3, 1, w),
            (257, 3, 1, h),
            (258, 3, spp, bps if spp == 1 else bps_off),
            (259, 3, 1, 1),
            (262, 3, 1, 1 if spp == 1 else 2),
            (273, 4, 1, data_off),
            (277, 3, 1, spp),
            (278, 3, 1, h),
            (279, 4, 1, len(data)),
            (339, 3, 1, fmt),
        ]
        ifd = len(out)
        struct.pack_into("<I", out, prev_next, ifd)
        out += struct.pack("<H", len(entries))
        for tag, typ, cnt, val in entries:
            if typ == 3 and cnt == 1:
                out += struct.pack("<HHIHH", tag, typ, cnt, val, 0)
            else:
                out += struct.pack("<HHII", tag, typ, cnt, val)
        prev_next = len(out)
        out += struct.pack("<I", 0)
    return bytes(out)


def image_stack(c, data):
    slices = sorted((data / "teapot_ct" / "slices").glob("*.png"))
    by_size = sorted(slices, key=lambda p: p.stat().st_size)
    a, b = by_size[0], by_size[1]
    c.add("image_stack", "teapot_one_slice", a.read_bytes())
    c.add("image_stack", "teapot_two_slices", join(a.read_bytes(), (b.name, b.read_bytes())))
    g8 = [bytes([16 * y + x for x in range(4)]) for y in range(3)]
    c.add("image_stack", "png_gray8_pair", join(png(4, 3, 8, 0, g8), ("s0001.png", png(4, 3, 8, 0, g8[::-1]))))
    c.add("image_stack", "png_gray16", png(2, 2, 16, 0, [b"\x01\x00\x02\x00", b"\xff\xff\x00\x10"]))
    c.add("image_stack", "png_rgb", png(2, 2, 8, 2, [bytes(range(6)), bytes(range(6, 12))]))
    c.add("image_stack", "png_gray1", png(8, 2, 1, 0, [b"\xa5", b"\x5a"]))
    c.add("image_stack", "tiff_u8_two_pages", tiff(4, 2, 8, 1, 1, [bytes(range(8)), bytes(range(8, 16))]))
    c.add("image_stack", "tiff_u16", tiff(2, 2, 16, 1, 1, [struct.pack("<4H", 1, 500, 65535, 7)]))
    c.add("image_stack", "tiff_i16", tiff(2, 1, 16, 2, 1, [struct.pack("<2h", -3, 9)]))
    c.add("image_stack", "tiff_f32", tiff(2, 1, 32, 3, 1, [struct.pack("<2f", 0.5, -2)]))
    c.add("image_stack", "tiff_rgb8", tiff(2, 1, 8, 1, 3, [bytes(range(6))]))


# --------------------------------------------------------------------------
# DICOM (explicit VR little endian, a few tags and a tiny image)


def dcm_el(group, elem, vr, value):
    if isinstance(value, str):
        value = value.encode()
        if len(value) % 2:
            value += b" " if vr not in (b"UI",) else b"\0"
    if vr in (b"OB", b"OW", b"SQ", b"UN", b"UT"):
        return struct.pack("<HH", group, elem) + vr + b"\0\0" + struct.pack("<I", len(value)) + value
    return struct.pack("<HH", group, elem) + vr + struct.pack("<H", len(value)) + value


def dicom_slice(i, rows=4, cols=3, bits=16, signed=0, slope="1", inter="-1024"):
    sop = "1.2.826.0.1.3680043.2.1125.1.%d" % (100 + i)
    meta_body = (
        dcm_el(0x0002, 0x0001, b"OB", b"\0\1")
        + dcm_el(0x0002, 0x0002, b"UI", "1.2.840.10008.5.1.4.1.1.2")
        + dcm_el(0x0002, 0x0003, b"UI", sop)
        + dcm_el(0x0002, 0x0010, b"UI", "1.2.840.10008.1.2.1")
    )
    meta = dcm_el(0x0002, 0x0000, b"UL", struct.pack("<I", len(meta_body))) + meta_body
    n = rows * cols
    if bits == 16:
        px = struct.pack("<%dH" % n, *[(i * 37 + k * 11) % 4096 for k in range(n)])
    else:
        px = bytes((i * 37 + k * 11) % 256 for k in range(n))
    if len(px) % 2:
        px += b"\0"
    ds = (
        dcm_el(0x0008, 0x0016, b"UI", "1.2.840.10008.5.1.4.1.1.2")
        + dcm_el(0x0008, 0x0018, b"UI", sop)
        + dcm_el(0x0008, 0x0060, b"CS", "CT")
        + dcm_el(0x0018, 0x0050, b"DS", "2.5")
        + dcm_el(0x0020, 0x000E, b"UI", "1.2.826.0.1.3680043.2.1125.7")
        + dcm_el(0x0020, 0x0013, b"IS", str(i + 1))
        + dcm_el(0x0020, 0x0032, b"DS", "-10\\-20\\%g" % (2.5 * i))
        + dcm_el(0x0020, 0x0037, b"DS", "1\\0\\0\\0\\1\\0")
        + dcm_el(0x0028, 0x0002, b"US", struct.pack("<H", 1))
        + dcm_el(0x0028, 0x0004, b"CS", "MONOCHROME2")
        + dcm_el(0x0028, 0x0010, b"US", struct.pack("<H", rows))
        + dcm_el(0x0028, 0x0011, b"US", struct.pack("<H", cols))
        + dcm_el(0x0028, 0x0030, b"DS", "0.7\\0.7")
        + dcm_el(0x0028, 0x0100, b"US", struct.pack("<H", bits))
        + dcm_el(0x0028, 0x0101, b"US", struct.pack("<H", 12 if bits == 16 else 8))
        + dcm_el(0x0028, 0x0102, b"US", struct.pack("<H", 11 if bits == 16 else 7))
        + dcm_el(0x0028, 0x0103, b"US", struct.pack("<H", signed))
        + dcm_el(0x0028, 0x1052, b"DS", inter)
        + dcm_el(0x0028, 0x1053, b"DS", slope)
        + dcm_el(0x7FE0, 0x0010, b"OW", px)
    )
    return b"\0" * 128 + b"DICM" + meta + ds


def dicom(c, data):
    s = [dicom_slice(i) for i in range(3)]
    c.add("dicom", "synthetic_one_slice", s[0])
    c.add("dicom", "synthetic_three_slices", join(s[1], ("b.dcm", s[0]), ("c.dcm", s[2])))
    c.add(
        "dicom",
        "synthetic_u8_two",
        join(dicom_slice(0, 2, 2, 8, 0, "1", "0"), ("b.dcm", dicom_slice(1, 2, 2, 8, 0, "1", "0"))),
    )
    for folder in ["dicom_mri_brain", "dicom_ct_lung"]:
        f = sorted((data / folder).glob("*.dcm"))[0]
        c.add("dicom", folder + "_head4k", f.read_bytes()[:4096])


# --------------------------------------------------------------------------
# FDS


def rec(b):
    return struct.pack("<i", len(b)) + b + struct.pack("<i", len(b))


def rle(values):
    out = bytearray()
    i = 0
    while i < len(values):
        j = i
        while j < len(values) and values[j] == values[i] and j - i < 254:
            j += 1
        if j - i >= 4:
            out += bytes([0xFF, values[i], j - i])
        else:
            out += bytes(values[i:j])
        i = j
    return bytes(out)


def s3d(bounds, frames):
    out = bytearray(rec(struct.pack("<8i", 1, 0, *bounds)))
    for t, vals in frames:
        enc = rle(vals)
        out += rec(struct.pack("<f", t)) + rec(struct.pack("<ii", len(vals), len(enc))) + rec(enc)
    return bytes(out)


def sf(labels, bounds, frames):
    out = bytearray()
    for l in labels:
        out += rec(l.encode().ljust(30))
    out += rec(struct.pack("<6i", *bounds))
    for t, vals in frames:
        out += rec(struct.pack("<f", t)) + rec(struct.pack("<%df" % len(vals), *vals))
    return bytes(out)


def q(dims, nvars, seed):
    n = dims[0] * dims[1] * dims[2]
    vals = [((k * 7 + seed) % 13) * 0.25 for k in range(n * nvars)]
    return rec(struct.pack("<3i", *dims)) + rec(struct.pack("<4f", 0, 0, 0, 0)) + rec(struct.pack("<%df" % len(vals), *vals))


def xyz(dims):
    n = dims[0] * dims[1] * dims[2]
    coords = [float(k % 3) for k in range(3 * n)]
    iblank = [0 if k == 0 else 1 for k in range(n)]
    return rec(struct.pack("<3i", *dims)) + rec(struct.pack("<%df" % (3 * n), *coords) + struct.pack("<%di" % n, *iblank))


def first_s3d_frames(p, k):
    b = p.read_bytes()
    off = 40
    for _ in range(k):
        nout = struct.unpack_from("<i", b, off + 20)[0]
        off += 36 + nout
    return b[:off]


SMV_TINY = """CHID
 tiny
GRID   MESH_0000001
     2     2     2     0     0     0     0     0     0
PDIM
   0.00000  0.20000  0.00000  0.20000  0.00000  0.20000  0.0 0.0 0.0
TRNX
     0
     0  0.00000
     1  0.10000
     2  0.20000
TRNY
     0
     0  0.00000
     1  0.10000
     2  0.20000
TRNZ
     0
     0  0.00000
     1  0.10000
     2  0.20000
OBST
       1
  0.0 0.1 0.0 0.1 0.0 0.1 1 -1 -1 -1 -1 -1 -1 ! Block
  0 1 0 1 0 1 -3 0 0.5 0.5 0.5 1.0 ! T 0 0 0 0 0 0
XYZ
 t.xyz
SMOKF3D     1   8700.000
 t_1.s3d
 SOOT DENSITY
 rho_C
 kg/m3
SMOKF3D     1   0.000
 t_2.s3d
 TEMPERATURE
 temp
 C
SLCF     1 # STRUCTURED &     0     2     0     2     0     2 !      3      0      0
 t_3.sf
 SOOT DENSITY
 rho_C
 kg/m3
PL3D       10.0     1
 t_10p00.q
 TEMPERATURE
 temp
 C
 SOOT DENSITY
 rho_C
 kg/m3
 A
 a
 u
 B
 b
 u
 HRRPUV
 hrrpuv
 kW/m3
PL3D       20.0     1
 t_20p01.q
 TEMPERATURE
 temp
 C
 SOOT DENSITY
 rho_C
 kg/m3
 A
 a
 u
 B
 b
 u
 HRRPUV
 hrrpuv
 kW/m3
"""


def fds(c, data):
    room = data / "fds_room"
    dims = (3, 3, 3)
    vals = lambda s: [(s + k * 5) % 200 for k in range(27)]
    s3d_soot = s3d([0, 2, 0, 2, 0, 2], [(0.0, vals(0)), (0.5, vals(3)), (1.0, [7] * 27)])
    s3d_temp = s3d([0, 2, 0, 2, 0, 2], [(0.0, vals(1)), (1.0, vals(9))])
    sf3 = sf(["SOOT DENSITY", "rho_C", "kg/m3"], [0, 2, 0, 2, 0, 2], [(0.0, [0.1 * k for k in range(27)]), (5.0, [0.2 * k for k in range(27)])])
    c.add("fds_s3d", "tiny_3_frames", s3d_soot)
    c.add("fds_s3d", "room_first_frames", first_s3d_frames(room / "room_smoke_1_2.s3d", 3))
    c.add("fds_sf", "tiny_3d", sf3)
    c.add("fds_sf", "tiny_2d", sf(["TEMPERATURE", "temp", "C"], [0, 2, 1, 1, 0, 2], [(1.0, [20.0] * 9)]))
    sfb = (room / "room_smoke_1_3.sf").read_bytes()
    c.add("fds_sf", "room_head4k", sfb[:4096])
    c.add("fds_q", "tiny_q", q(dims, 5, 1))
    c.add("fds_q", "tiny_xyz", xyz(dims))
    c.add("fds_q", "room_q_head", (room / "room_smoke_1_10p00.q").read_bytes()[:4096])
    c.add(
        "fds",
        "tiny_case",
        join(
            SMV_TINY.encode(),
            ("t.xyz", xyz(dims)),
            ("t_1.s3d", s3d_soot),
            ("t_2.s3d", s3d_temp),
            ("t_3.sf", sf3),
            ("t_10p00.q", q(dims, 5, 1)),
            ("t_20p01.q", q(dims, 5, 2)),
        ),
    )
    c.add("fds", "room_smv_only", (room / "room_smoke.smv").read_bytes())


# --------------------------------------------------------------------------
# VDB (one float grid, one leaf; uncompressed, zip, Blosc-LZ4, half floats)


def vdb_string(s):
    return struct.pack("<I", len(s)) + s


def lz4_literals(b):
    """An LZ4 block of literals only (valid for any input)."""
    n = len(b)
    if n < 15:
        return bytes([n << 4]) + b
    out = bytearray([0xF0])
    r = n - 15
    while r >= 255:
        out.append(255)
        r -= 255
    out.append(r)
    return bytes(out) + b


def blosc(b, typesize, memcpy=False):
    if memcpy:
        return struct.pack("<BBBBIII", 2, 1, 0x02, typesize, len(b), len(b), 16 + len(b)) + b
    # One block, not split, no shuffle, LZ4 (codec 1).
    stream = lz4_literals(b)
    block = struct.pack("<i", len(stream)) + stream
    flags = 0x10 | (1 << 5)
    total = 16 + 4 + len(block)
    return struct.pack("<BBBBIII", 2, 1, flags, typesize, len(b), len(b), total) + struct.pack("<I", 20) + block


def vdb(compression, half, mode):
    grid_type = b"Tree_float_5_4_3" + (b"_HalfFloat" if half else b"")
    esize = 2 if half else 4

    def data(raw_bytes):
        if compression & 0x4:
            chunk = blosc(raw_bytes, esize, memcpy=(mode == "memcpy"))
            return struct.pack("<q", len(chunk)) + chunk
        if compression & 0x1:
            z = zlib.compress(raw_bytes)
            return struct.pack("<q", len(z)) + z
        return raw_bytes

    def compressed(values_bytes, count_on):
        # metadata byte 0 (no inactive values), then the active values
        if half and count_on == 0:
            return b"\0"
        return b"\0" + data(values_bytes)

    grid = bytearray()
    grid += struct.pack("<I", compression)
    grid += struct.pack("<I", 0)  # grid metadata
    grid += vdb_string(b"UniformScaleTranslateMap")
    grid += struct.pack("<3d", 1, 2, 3) + struct.pack("<3d", 0.5, 0.5, 0.5)
    grid += struct.pack("<12d", *([1.0] * 12))
    grid += struct.pack("<I", 1)  # buffer count
    grid += struct.pack("<f", 0.0)  # background
    grid += struct.pack("<II", 0, 1)  # root tiles, children
    grid += struct.pack("<3i", 0, 0, 0)
    # internal node 5: child mask bit 0, no values
    m5 = bytearray(512)
    m5[0] = 1
    grid += m5 + bytes(512)
    active_mask = compression & 0x2
    grid += compressed(b"", 0) if active_mask else compressed(bytes(4 * 32768), 32768)
    m4 = bytearray(64)
    m4[0] = 1
    grid += m4 + bytes(64)
    grid += compressed(b"", 0) if active_mask else compressed(bytes(4 * 4096), 4096)
    leaf_mask = bytes([0xFF] * 8 + [0] * 56)  # 64 active voxels
    grid += leaf_mask  # topology
    grid += leaf_mask  # buffer
    n = 64 if active_mask else 512
    if half:
        vals = b"".join(struct.pack("<e", 0.01 * k) for k in range(n))
    else:
        vals = struct.pack("<%df" % n, *[0.01 * k for k in range(n)])
    grid += compressed(vals, n)

    head = bytearray()
    head += struct.pack("<q", 0x56444220) + struct.pack("<III", 224, 10, 0) + b"\1"
    head += b"0" * 36
    head += struct.pack("<I", 1)  # file metadata: one entry
    head += vdb_string(b"creator") + vdb_string(b"string") + vdb_string(b"voxcast seed.py")
    head += struct.pack("<I", 1)  # grid count
    desc = vdb_string(b"density") + vdb_string(grid_type) + vdb_string(b"")
    grid_pos = len(head) + len(desc) + 24
    end_pos = grid_pos + len(grid)
    desc += struct.pack("<qqq", grid_pos, 0, end_pos)
    return bytes(head + desc + grid)


def vdb_seeds(c, data):
    c.add("vdb", "raw_mask_float", vdb(0x2, False, ""))
    c.add("vdb", "zip_mask_float", vdb(0x3, False, ""))
    c.add("vdb", "blosc_lz4_mask_float", vdb(0x6, False, ""))
    c.add("vdb", "blosc_lz4_half", vdb(0x6, True, ""))
    c.add("vdb", "blosc_memcpy_float", vdb(0x6, False, "memcpy"))
    for f in ["smoke_vdb/smoke.vdb", "cloud_vdb/cloud.vdb"]:
        c.add("vdb", Path(f).stem + "_head16k", (data / f).read_bytes()[:16384])


# --------------------------------------------------------------------------
# Mitsuba .vol


def mitsuba(c, data):
    def vol(dims, ch, vals, enc=1):
        return b"VOL\x03" + struct.pack("<i3ii6f", enc, *dims, ch, 0, 0, 0, 1, 2, 3) + struct.pack("<%df" % len(vals), *vals)

    c.add("mitsuba_vol", "density_2x2x2", vol((2, 2, 2), 1, [0.1 * k for k in range(8)]))
    c.add("mitsuba_vol", "rgb_2x1x1", vol((2, 1, 1), 3, [0.1 * k for k in range(6)]))
    c.add("mitsuba_vol", "flat_1x3x2", vol((1, 3, 2), 1, [1, 2, 3, 4, 5, 6]))


# --------------------------------------------------------------------------
# Scenes, transfer functions, geometry, OBJ


def text_seeds(c, data):
    ex = ROOT / "examples"
    geo = ex / "geometry"
    chair = (geo / "chair.obj").read_bytes()
    ball = (geo / "ball.obj").read_bytes()
    for f in sorted(ex.glob("*.toml")):
        c.add("scene", f.stem, f.read_bytes())
    c.add(
        "scene",
        "with_files",
        join(
            b'[input]\npath = "builtin:demo"\n[transfer]\ntf = "tf.toml"\nwindow = [0.0, 200.0]\n'
            b'[camera]\nprojection = "orthographic"\nazimuth = 10.0\nelevation = -80.0\nzoom = 2.0\n'
            b'[render]\nwidth = 8\nheight = 6\nmethod = "uniform"\nstep = 0.25\nshading = false\n'
            b'[geometry]\nfile = "g.toml"\nshadows = true\n',
            ("tf.toml", b'color = [[0.0, 0, 0, 0], [1.0, 1, 1, 1]]\nopacity = [[0.0, 0.0], [1.0, 0.5]]\n'),
            ("g.toml", b'[[box]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 2.0, 1.0]\ncolor = [0.5, 0.5, 0.5]\n[[mesh]]\npath = "c.obj"\n'),
            ("c.obj", chair),
        ),
    )
    c.add(
        "scene",
        "inline_map_lights",
        b'[transfer.map]\ncolor = [[0.0, 1, 0, 0], [0.5, 0, 1, 0], [1.0, 0, 0, 1]]\nopacity = [[0.0, 0.0], [1.0, 1.0]]\n'
        b'[render]\nmethod = "path"\nspp = 2\n[[render.lights]]\nkind = "sun"\ndirection = [0.0, 0.0, 1.0]\n'
        b'[geometry]\n[[geometry.plane]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\ncolor = [0.2, 0.2, 0.2]\n',
    )
    for f in sorted(ex.glob("*.toml")):
        t = f.read_bytes()
        if b"opacity" in t and b"[input]" not in t:
            c.add("tf", f.stem, t)
    c.add("tf", "windowed", b'color = [[0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]]\nopacity = [[0.0, 0.0], [0.4, 0.0], [1.0, 0.5]]\nwindow = [-1000.0, 2000.0]\n')
    c.add("tf", "single_points", b"color = [[0.5, 0.2, 0.4, 0.6]]\nopacity = [[0.5, 1.0]]\n")
    c.add("tf", "steps", b"color = [[0.0, 0, 0, 0], [0.5, 0, 0, 0], [0.5, 1, 1, 1], [1.0, 1, 1, 1]]\nopacity = [[0.2, 0.0], [0.2, 1.0]]\n")
    c.add("geometry", "plume_room", join((geo / "plume-room.toml").read_bytes(), ("chair.obj", chair), ("ball.obj", ball)))
    c.add("geometry", "shapes_only", b'[[box]]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n[[plane]]\npoint = [0.0, 0.0, -1.0]\nnormal = [0.0, 0.0, 1.0]\n')
    c.add("obj", "chair", chair)
    c.add("obj", "ball", ball)
    c.add(
        "obj",
        "normals_negative_indices",
        b"o q\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf -4//-1 -3//-1 -2//-1 -1//-1\n"
        b"g tri\nv 0 0 1\nv 1 0 1\nv 0 1 2\nf 5/1 6/1 7/1\nl 1 2\np 3\n",
    )


# --------------------------------------------------------------------------
# OME-Zarr / Zarr stores (the folder's files as parts, paths inside the store)


def zarr_v3_store(shape=(4, 4, 4), chunk=(2, 2, 2), levels=2, codec="gzip", dtype="uint8"):
    """An OME-Zarr 0.5 store (Zarr v3) of `levels` levels, each half the
    last, with a ramp of values: (root zarr.json, [(path, bytes)])."""
    import json

    axes = [{"name": a, "type": "space", "unit": "micrometer"} for a in "zyx"]
    datasets = [
        {"path": str(l), "coordinateTransformations": [{"type": "scale", "scale": [2.0**l] * 3}]}
        for l in range(levels)
    ]
    root = {"zarr_format": 3, "node_type": "group",
            "attributes": {"ome": {"version": "0.5", "multiscales": [{"axes": axes, "datasets": datasets}]}}}
    codecs = [{"name": "bytes", "configuration": {"endian": "little"}}]
    if codec == "gzip":
        codecs.append({"name": "gzip", "configuration": {"level": 1}})
    parts = []
    dims = list(shape)
    for l in range(levels):
        meta = {"zarr_format": 3, "node_type": "array", "shape": dims, "data_type": dtype,
                "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": list(chunk)}},
                "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
                "fill_value": 0, "codecs": codecs}
        parts.append((f"{l}/zarr.json", json.dumps(meta).encode()))
        n = [-(-d // c) for d, c in zip(dims, chunk)]
        for k in range(n[0]):
            for j in range(n[1]):
                for i in range(n[2]):
                    vals = [(17 * (k + j + i) + v) % 256 for v in range(chunk[0] * chunk[1] * chunk[2])]
                    fmt = {"uint8": "B", "uint16": "H", "float32": "f"}[dtype]
                    raw = struct.pack(f"<{len(vals)}{fmt}", *vals)
                    if codec == "gzip":
                        raw = gzip.compress(raw, 1)
                    parts.append((f"{l}/c/{k}/{j}/{i}", raw))
        dims = [max(1, d // 2) for d in dims]
    return json.dumps(root).encode(), parts


def zarr_v2_store():
    """An OME-Zarr 0.4 store (Zarr v2), one level, no compressor."""
    import json

    attrs = {"multiscales": [{"version": "0.4",
                              "axes": [{"name": a, "type": "space"} for a in "zyx"],
                              "datasets": [{"path": "0", "coordinateTransformations": [{"type": "scale", "scale": [1, 1, 1]}]}]}]}
    arr = {"zarr_format": 2, "shape": [3, 4, 5], "chunks": [2, 2, 5], "dtype": "<u2",
           "compressor": None, "fill_value": 0, "order": "C", "filters": None}
    parts = [(".zattrs", json.dumps(attrs).encode()), ("0/.zarray", json.dumps(arr).encode())]
    for k in range(2):
        for j in range(2):
            parts.append((f"0/{k}.{j}.0", struct.pack("<20H", *range(20 * (k + j), 20 * (k + j) + 20))))
    return json.dumps({"zarr_format": 2}).encode(), parts


def zarr_seeds(c, data):
    for name, kw in [("v3_gzip_two_levels", {}), ("v3_raw_one_level", {"codec": None, "levels": 1}),
                     ("v3_f32_one_chunk", {"codec": None, "dtype": "float32", "chunk": (4, 4, 4), "levels": 1})]:
        root, parts = zarr_v3_store(**kw)
        c.add("zarr", name, join(root, *parts))
    root, parts = zarr_v2_store()
    c.add("zarr", "v2_u16", join(root, *parts))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "fuzz" / "corpus"))
    args = ap.parse_args()
    data = data_dir()
    c = Corpus(Path(args.out))
    for f in [nrrd, metaimage, vtk, raw, nifti, image_stack, dicom, fds, vdb_seeds, mitsuba, text_seeds, zarr_seeds]:
        f(c, data)
    seeds = ROOT / "fuzz" / "seeds"
    if seeds.is_dir():  # hand-made seeds kept in the repository
        for d in sorted(seeds.iterdir()):
            for f in sorted(d.iterdir()):
                c.add(d.name, f.name, f.read_bytes())
    for t, n in sorted(c.counts.items()):
        print(f"{t:12} {n:3} seeds")


if __name__ == "__main__":
    main()
