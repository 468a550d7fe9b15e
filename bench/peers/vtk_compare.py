#!/usr/bin/env python3
"""voxcast `uniform` against VTK's CPU ray caster, same work, same machine.

Renders three workloads with vtkFixedPointVolumeRayCastMapper (the CPU ray
caster of VTK, ParaView and 3D Slicer) and with `voxcast bench --methods
uniform`, with the same volume, transfer function, camera, image size (512x512)
and step (0.5 voxel), unshaded, and prints a Markdown table of seconds per
frame plus the PSNR between the two images (so the reader can see the work is
the same, not just the time). See README.md in this folder.

    pip install -r bench/peers/requirements.txt
    cargo build --release -p voxcast-cli
    python3 bench/peers/vtk_compare.py --json peers.json --images peers-img

Timing, both sides: render time only, not file reading; the first frame is
not timed (VTK builds its tables there; voxcast builds its block grid before
its warm-up frame); the median of --frames frames is reported. VTK's frames
nudge the camera by +-0.01 degree so nothing can be cached between frames;
voxcast keeps no per-view state between renders, so `voxcast bench` repeats
the same view.

Colour: voxcast reads transfer-function colours as sRGB and composites in
linear light (then encodes the PNG as sRGB). VTK composites the numbers it is
given, so it is given the same colours converted to linear light (sampled at
every u8 value), and its framebuffer (linear) is encoded as sRGB in the
script. PSNR is reported both in linear light (the composited values, where
8-bit quantisation of each renderer's output is smallest) and on the sRGB
images as written.
"""

import argparse
import hashlib
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# VTK must choose its offscreen window class before it is imported.
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[2]

WIDTH = HEIGHT = 512
STEP = 0.5  # voxels (= world units: spacing is 1 on every workload)
AZIMUTH, ELEVATION = 30.0, 20.0
FOV = 30.0  # voxcast's default vertical field of view, degrees
NUDGE = 0.01  # degrees of azimuth between VTK frames

# One transfer function for every workload, over u8 values 0..255 (window
# 0..255, so the normalised value is v/255). Colours are sRGB (voxcast's
# convention); opacity is per unit length (one voxel).
TF = {
    "color": [
        [0.0, 0.23, 0.30, 0.75],
        [0.35, 0.55, 0.70, 0.95],
        [0.55, 0.90, 0.85, 0.80],
        [0.75, 0.95, 0.60, 0.40],
        [1.0, 0.70, 0.05, 0.10],
    ],
    "opacity": [[0.0, 0.0], [0.15, 0.0], [0.45, 0.04], [0.75, 0.15], [1.0, 0.5]],
    "window": [0.0, 255.0],
}

WORKLOADS = {
    "teapot": "teapot CT 256×256×178 u8",
    "ml": "Marschner–Lobb 256³ u8 (dense)",
    "blobs": "24 Gaussian blobs 256³ u8 (sparse)",
}


# ---------------------------------------------------------------- volumes


def write_nrrd(path_stem: Path, vol_zyx: np.ndarray, comment: str) -> Path:
    """u8 array (z, y, x) -> STEM.raw + STEM.nhdr (spacing 1); returns the .nhdr."""
    raw = path_stem.with_suffix(".raw")
    nhdr = path_stem.with_suffix(".nhdr")
    assert vol_zyx.dtype == np.uint8
    np.ascontiguousarray(vol_zyx).tofile(raw)
    nz, ny, nx = vol_zyx.shape
    nhdr.write_text(
        "NRRD0004\n"
        f"# {comment}\n"
        "type: uint8\n"
        "dimension: 3\n"
        f"sizes: {nx} {ny} {nz}\n"
        "spacings: 1 1 1\n"
        "encoding: raw\n"
        f"data file: {raw.name}\n"
    )
    return nhdr


def marschner_lobb(n=256, fm=6.0, alpha=0.25) -> np.ndarray:
    """Marschner & Lobb (1994) test signal on [-1, 1]^3, voxel centres at the
    ends, value (0..1) * 255 rounded. Returns (z, y, x) u8."""
    t = np.linspace(-1.0, 1.0, n, dtype=np.float64)
    x = t[None, None, :]
    y = t[None, :, None]
    z = t[:, None, None]
    r = np.sqrt(x * x + y * y)
    rho_r = np.cos(2.0 * math.pi * fm * np.cos(math.pi * r / 2.0))
    v = (1.0 - np.sin(math.pi * z / 2.0) + alpha * (1.0 + rho_r)) / (2.0 * (1.0 + alpha))
    return np.clip(np.rint(v * 255.0), 0, 255).astype(np.uint8)


def gaussian_blobs(n=256, count=24, seed=15) -> np.ndarray:
    """`count` isotropic Gaussian blobs, fixed seed: centres in the middle
    70 % of the box, sigma 4..12 voxels, peak 0.5..1; summed, clipped to 1,
    * 255 rounded. Most voxels are 0 (sparse). Returns (z, y, x) u8."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0.15 * (n - 1), 0.85 * (n - 1), size=(count, 3))
    sigmas = rng.uniform(4.0, 12.0, size=count)
    peaks = rng.uniform(0.5, 1.0, size=count)
    acc = np.zeros((n, n, n), dtype=np.float32)
    idx = np.arange(n, dtype=np.float32)
    for (cx, cy, cz), s, a in zip(centres, sigmas, peaks):
        r = 4.0 * s  # beyond 4 sigma the blob is < 1/255 of its peak
        lo = [max(0, int(math.floor(c - r))) for c in (cx, cy, cz)]
        hi = [min(n, int(math.ceil(c + r)) + 1) for c in (cx, cy, cz)]
        gx = np.exp(-((idx[lo[0]:hi[0]] - cx) ** 2) / (2 * s * s))
        gy = np.exp(-((idx[lo[1]:hi[1]] - cy) ** 2) / (2 * s * s))
        gz = np.exp(-((idx[lo[2]:hi[2]] - cz) ** 2) / (2 * s * s))
        acc[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]] += a * gz[:, None, None] * gy[None, :, None] * gx[None, None, :]
    return np.clip(np.rint(np.minimum(acc, 1.0) * 255.0), 0, 255).astype(np.uint8)


def check_sha256(data: Path, files, quiet=False):
    """Checks files (relative to `data`) against data/SHA256SUMS; warns only."""
    sums = {}
    try:
        for line in (data / "SHA256SUMS").read_text().splitlines():
            h, _, name = line.partition("  ")
            sums[os.path.normpath(name)] = h
    except OSError:
        if not quiet:
            print("note: no SHA256SUMS in the data folder; not checked", file=sys.stderr)
        return
    bad = []
    for f in files:
        rel = os.path.normpath(os.path.relpath(f, data))
        want = sums.get(rel)
        if want is None or hashlib.sha256(Path(f).read_bytes()).hexdigest() != want:
            bad.append(rel)
    if bad:
        print(f"warning: {len(bad)} teapot file(s) differ from SHA256SUMS, e.g. {bad[0]}", file=sys.stderr)


def png_gray8_rows(path: Path) -> np.ndarray:
    """Decodes an 8-bit grayscale, non-interlaced PNG in plain Python (file
    row 0 first). Slow (about a second a slice): used to check one slice."""
    import struct
    import zlib

    f = path.read_bytes()
    pos, idat = 8, b""
    while pos < len(f):
        n, kind = struct.unpack(">I4s", f[pos:pos + 8])
        body = f[pos + 8:pos + 8 + n]
        pos += 12 + n
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, ctype, interlace) != (8, 0, 0):
                raise ValueError(f"{path}: not an 8-bit grayscale non-interlaced PNG")
        elif kind == b"IDAT":
            idat += body
    raw = zlib.decompress(idat)
    out = np.zeros((h, w), dtype=np.uint8)
    prev = [0] * w
    for y in range(h):
        ft = raw[y * (w + 1)]
        line = raw[y * (w + 1) + 1:(y + 1) * (w + 1)]
        cur = [0] * w
        for x in range(w):
            a = cur[x - 1] if x else 0
            b = prev[x]
            c = prev[x - 1] if x else 0
            if ft == 0:
                p = 0
            elif ft == 1:
                p = a
            elif ft == 2:
                p = b
            elif ft == 3:
                p = (a + b) // 2
            else:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (line[x] + p) & 255
        out[y] = cur
        prev = cur
    return out


def read_teapot(data: Path) -> tuple:
    """The teapot slices as (z, y, x) u8 in voxcast's convention (slice
    file k = z k, PNG row j = y j: no flip), and the folder voxcast reads."""
    import vtk
    from vtk.util import numpy_support

    folder = data / "teapot_ct" / "slices"
    files = sorted(folder.glob("teapot_*.png"))
    if len(files) != 178:
        sys.exit(f"expected 178 teapot slices in {folder}, found {len(files)} "
                 "(pass --data or set VOXCAST_DATA to the shared data folder)")
    check_sha256(data, files)
    names = vtk.vtkStringArray()
    for f in files:
        names.InsertNextValue(str(f))
    reader = vtk.vtkPNGReader()
    reader.SetFileNames(names)
    reader.Update()
    img = reader.GetOutput()
    nx, ny, nz = img.GetDimensions()
    arr = numpy_support.vtk_to_numpy(img.GetPointData().GetScalars())
    if arr.ndim == 2:  # grayscale+alpha or RGB: keep the first component
        arr = arr[:, 0]
    vol = arr.reshape(nz, ny, nx).astype(np.uint8)
    # vtkPNGReader puts the file's last row at y = 0 (and ignores
    # SetFileLowerLeft in VTK 9.7); voxcast puts row 0 at y = 0. Check
    # against one slice decoded here rather than trust either.
    k = 100
    rows = png_gray8_rows(files[k])
    if np.array_equal(vol[k], rows[::-1]):
        vol = vol[:, ::-1, :]
    elif not np.array_equal(vol[k], rows):
        sys.exit(f"vtkPNGReader's slice {k} matches {files[k]} neither as is nor flipped")
    return np.ascontiguousarray(vol), folder


# ---------------------------------------------------------------- transfer function


def srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1.0 / 2.4) - 0.055)


def tf_color_at(v):
    """voxcast's TransferFunction::color_at: piecewise linear in sRGB."""
    p = np.array(TF["color"])
    return np.stack([np.interp(v, p[:, 0], p[:, k]) for k in (1, 2, 3)], axis=-1)


def write_tf_toml(path: Path):
    fmt = lambda rows: "[" + ", ".join("[" + ", ".join(f"{x:g}" for x in r) + "]" for r in rows) + "]"
    path.write_text(
        "# written by bench/peers/vtk_compare.py; values 0..1 over the window\n"
        f"color = {fmt(TF['color'])}\n"
        f"opacity = {fmt(TF['opacity'])}\n"
        f"window = [{TF['window'][0]:g}, {TF['window'][1]:g}]\n"
    )


# ---------------------------------------------------------------- camera


def voxcast_camera(dims_xyz):
    """voxcast's Camera::fit for the box through the voxel centres
    [0, dims-1] (spacing 1): perspective, vertical fov 30 degrees, the bounding
    sphere fitted to the image, orbit by azimuth/elevation."""
    lo = np.zeros(3)
    hi = np.array(dims_xyz, dtype=np.float64) - 1.0
    centre = (lo + hi) / 2.0
    radius = max(np.linalg.norm(hi - lo) / 2.0, 1e-6)
    az, el = math.radians(AZIMUTH), math.radians(ELEVATION)
    to_eye = np.array([math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), math.sin(el)])
    aspect = WIDTH / HEIGHT
    half_min = math.atan(math.tan(math.radians(FOV) / 2.0) * min(aspect, 1.0))
    dist = radius / math.sin(half_min)
    return centre, centre + to_eye * dist


# ---------------------------------------------------------------- VTK


def render_vtk(vol_zyx: np.ndarray, frames: int):
    import vtk
    from vtk.util import numpy_support

    nz, ny, nx = vol_zyx.shape
    image = vtk.vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.SetSpacing(1.0, 1.0, 1.0)  # one voxel = one world unit
    image.SetOrigin(0.0, 0.0, 0.0)
    scalars = numpy_support.numpy_to_vtk(np.ascontiguousarray(vol_zyx).ravel(), deep=True,
                                         array_type=vtk.VTK_UNSIGNED_CHAR)
    image.GetPointData().SetScalars(scalars)

    w0, w1 = TF["window"]
    opacity = vtk.vtkPiecewiseFunction()
    for v, a in TF["opacity"]:
        opacity.AddPoint(w0 + v * (w1 - w0), a)
    # voxcast interpolates the sRGB control points and composites in linear
    # light; give VTK that colour, linear, at every u8 value.
    color = vtk.vtkColorTransferFunction()
    values = np.arange(256, dtype=np.float64)
    lin = srgb_to_linear(tf_color_at((values - w0) / (w1 - w0)))
    for s, (r, g, b) in zip(values, lin):
        color.AddRGBPoint(float(s), float(r), float(g), float(b))

    prop = vtk.vtkVolumeProperty()
    prop.SetColor(color)
    prop.SetScalarOpacity(opacity)
    prop.SetScalarOpacityUnitDistance(1.0)  # opacity per voxel, as voxcast's
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOff()

    mapper = vtk.vtkFixedPointVolumeRayCastMapper()
    mapper.SetInputData(image)
    mapper.SetBlendModeToComposite()
    mapper.SetSampleDistance(STEP)  # world units = voxels here
    mapper.SetImageSampleDistance(1.0)
    mapper.SetAutoAdjustSampleDistances(0)
    if hasattr(mapper, "SetLockSampleDistanceToInputSpacing"):
        mapper.SetLockSampleDistanceToInputSpacing(0)
    # No other geometry in the scene: do not read back the depth buffer.
    mapper.SetIntermixIntersectingGeometry(0)

    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)

    ren = vtk.vtkRenderer()
    ren.SetBackground(0.0, 0.0, 0.0)
    ren.AddVolume(volume)
    win = vtk.vtkRenderWindow()
    win.SetOffScreenRendering(1)
    win.SetMultiSamples(0)
    win.SetSize(WIDTH, HEIGHT)
    win.AddRenderer(ren)

    centre, eye = voxcast_camera((nx, ny, nz))
    cam = ren.GetActiveCamera()
    cam.SetFocalPoint(*centre)
    cam.SetPosition(*eye)
    cam.SetViewUp(0.0, 0.0, 1.0)
    cam.SetViewAngle(FOV)
    cam.OrthogonalizeViewUp()
    ren.ResetCameraClippingRange()

    # First frame: builds the mapper's tables; not timed (reported apart).
    t0 = time.perf_counter()
    win.Render()
    first = time.perf_counter() - t0
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(win)
    grab.SetInputBufferTypeToRGB()
    grab.ReadFrontBufferOff()
    grab.Update()
    out = grab.GetOutput()
    w, h, _ = out.GetDimensions()
    fb = numpy_support.vtk_to_numpy(out.GetPointData().GetScalars()).reshape(h, w, -1)[::-1, :, :3].copy()

    times, mapper_times = [], []
    for i in range(frames):
        cam.Azimuth(NUDGE if i % 2 == 0 else -NUDGE)
        t0 = time.perf_counter()
        win.Render()
        times.append(time.perf_counter() - t0)
        mapper_times.append(mapper.GetTimeToDraw())
    threads = mapper.GetNumberOfThreads()
    win.Finalize()
    return {
        "image_linear8": fb,
        "first_frame_s": first,
        "frame_s": times,
        "mapper_time_to_draw_s": mapper_times,
        "threads": threads,
    }


# ---------------------------------------------------------------- voxcast


def voxcast_scene_flags(tf_path: Path):
    return [
        "--tf", str(tf_path),
        "--window", f"{TF['window'][0]:g},{TF['window'][1]:g}",
        "--size", f"{WIDTH}x{HEIGHT}",
        "--azimuth", f"{AZIMUTH:g}",
        "--elevation", f"{ELEVATION:g}",
        "--fov", f"{FOV:g}",
        "--step", f"{STEP:g}",
        "--shading", "off",
        "--background", "black",
    ]


def run(cmd, env=None):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr}")
    return p


def render_voxcast(exe: Path, inp: Path, tf_path: Path, frames: int, work: Path, name: str, env):
    flags = voxcast_scene_flags(tf_path)
    # Timing: `voxcast bench` builds the renderer once (volume read and
    # block grid outside the timer), renders --warmup 1 untimed frame, then
    # --repeat timed ones, and reports each. It also renders (once, then
    # cached in $VOXCAST_CACHE) its own high-quality reference.
    bench_json = work / f"voxcast-bench-{name}.json"
    run([str(exe), "bench", str(inp), *flags, "--methods", "uniform", "--repeat", str(frames),
         "--warmup", "1", "--json", str(bench_json), "--quiet"], env=env)
    report = json.loads(bench_json.read_text())
    m = next(m for m in report["methods"] if m["name"] == "uniform")
    # The image: one `voxcast render` of the same scene.
    png = work / f"voxcast-{name}.png"
    stats = work / f"voxcast-render-{name}.json"
    run([str(exe), "render", str(inp), *flags, "-o", str(png), "--stats-json", str(stats), "--quiet"], env=env)
    return {
        "frame_s": [ms / 1000.0 for ms in m["ms_per_repeat"]],
        "setup_ms": report["run"]["setup_ms"],
        "threads": report["machine"].get("threads"),
        "samples": m["samples"],
        "psnr_vs_own_reference_db": m["psnr_db"],
        "png": png,
        "render_stats": json.loads(stats.read_text()),
    }


# ---------------------------------------------------------------- images


def read_png_rgb(path: Path) -> np.ndarray:
    import vtk
    from vtk.util import numpy_support

    r = vtk.vtkPNGReader()
    r.SetFileName(str(path))
    r.Update()
    img = r.GetOutput()
    w, h, _ = img.GetDimensions()
    a = numpy_support.vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, -1)
    return a[::-1, :, :3].copy()  # VTK's row 0 is the bottom


def write_png_rgb(path: Path, rgb: np.ndarray):
    import vtk
    from vtk.util import numpy_support

    h, w, _ = rgb.shape
    img = vtk.vtkImageData()
    img.SetDimensions(w, h, 1)
    arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(rgb[::-1]).reshape(-1, 3), deep=True,
                                     array_type=vtk.VTK_UNSIGNED_CHAR)
    img.GetPointData().SetScalars(arr)
    wr = vtk.vtkPNGWriter()
    wr.SetFileName(str(path))
    wr.SetInputData(img)
    wr.Write()


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)


# ---------------------------------------------------------------- main


def cpu_model():
    try:
        for line in subprocess.run(["lscpu"], stdout=subprocess.PIPE, text=True).stdout.splitlines():
            if line.startswith("Model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path,
                    default=Path(os.environ.get("VOXCAST_DATA", REPO.parent / "shared" / "data")),
                    help="the shared data folder (default: $VOXCAST_DATA, else ../shared/data from the repo root)")
    ap.add_argument("--voxcast", type=Path, default=REPO / "target" / "release" / "voxcast",
                    help="the voxcast release binary (default: target/release/voxcast)")
    ap.add_argument("--frames", type=int, default=10, help="timed frames per renderer and workload (median reported)")
    ap.add_argument("--rounds", type=int, default=1,
                    help="alternate VTK and voxcast this many times per workload (each round: --frames frames "
                         "after an untimed one; the median is over all rounds), so that a busy spell of a shared "
                         "machine falls on both")
    ap.add_argument("--workloads", default="teapot,ml,blobs", help="comma-separated subset of teapot,ml,blobs")
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "voxcast-peers",
                    help="where generated volumes, the TF file and voxcast's outputs go (kept; voxcast's "
                         "reference renders are cached there unless VOXCAST_CACHE is set)")
    ap.add_argument("--json", type=Path, help="write every measurement as JSON")
    ap.add_argument("--images", type=Path, help="write both renderers' images (PNG, sRGB) into this folder")
    args = ap.parse_args()

    import vtk

    if not args.voxcast.is_file():
        sys.exit(f"no voxcast binary at {args.voxcast}: `cargo build --release -p voxcast-cli` or pass --voxcast")
    names = [w.strip() for w in args.workloads.split(",") if w.strip()]
    for n in names:
        if n not in WORKLOADS:
            sys.exit(f"unknown workload {n!r}: expected teapot, ml or blobs")
    args.work.mkdir(parents=True, exist_ok=True)
    if args.images:
        args.images.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    env.setdefault("VOXCAST_CACHE", str(args.work / "cache"))
    tf_path = args.work / "tf.toml"
    write_tf_toml(tf_path)

    cores = os.cpu_count()
    version = run([str(args.voxcast), "--version"]).stdout.strip()
    print(f"# {cores} cores ({cpu_model()}); VTK {vtk.vtkVersion.GetVTKVersion()}, {version}; "
          f"{WIDTH}x{HEIGHT}, step {STEP} voxel, unshaded, azimuth {AZIMUTH:g} elevation {ELEVATION:g}; "
          f"median of {args.frames} frames after the first, {max(1, args.rounds)} round(s)", file=sys.stderr)

    rows = []
    for name in names:
        t0 = time.perf_counter()
        if name == "teapot":
            vol, inp = read_teapot(args.data)
        elif name == "ml":
            # Generated every run (a fraction of a second), never a stale copy.
            vol = marschner_lobb()
            inp = write_nrrd(args.work / "marschner_lobb_256", vol,
                             "Marschner-Lobb fM=6 alpha=0.25 on [-1,1]^3, *255")
        else:
            vol = gaussian_blobs()
            inp = write_nrrd(args.work / "blobs24_256", vol,
                             "24 Gaussian blobs, seed 15, sigma 4..12, peak 0.5..1, *255")
        print(f"{name}: volume {vol.shape[::-1]} ready in {time.perf_counter() - t0:.1f} s; "
              f"{np.count_nonzero(vol) / vol.size:.0%} non-zero voxels", file=sys.stderr)

        v = x = None
        for r in range(max(1, args.rounds)):
            # Alternate which renderer goes first.
            for side in (("vtk", "voxcast") if r % 2 == 0 else ("voxcast", "vtk")):
                if side == "vtk":
                    got = render_vtk(vol, args.frames)
                    if v is None:
                        v = got
                    else:
                        v["frame_s"] += got["frame_s"]
                        v["mapper_time_to_draw_s"] += got["mapper_time_to_draw_s"]
                else:
                    got = render_voxcast(args.voxcast, inp, tf_path, args.frames, args.work, name, env)
                    if x is None:
                        x = got
                    else:
                        x["frame_s"] += got["frame_s"]

        vtk_lin8 = v["image_linear8"]
        vtk_srgb8 = np.clip(np.rint(linear_to_srgb(vtk_lin8 / 255.0) * 255.0), 0, 255).astype(np.uint8)
        vox_srgb8 = read_png_rgb(x["png"])
        psnr_linear = psnr(vtk_lin8 / 255.0, srgb_to_linear(vox_srgb8 / 255.0))
        psnr_srgb = psnr(vtk_srgb8 / 255.0, vox_srgb8 / 255.0)
        if args.images:
            write_png_rgb(args.images / f"{name}-vtk.png", vtk_srgb8)
            write_png_rgb(args.images / f"{name}-vtk-framebuffer-linear.png", vtk_lin8)
            (args.images / f"{name}-voxcast.png").write_bytes(x["png"].read_bytes())

        vtk_s = float(np.median(v["frame_s"]))
        vox_s = float(np.median(x["frame_s"]))
        row = {
            "workload": name,
            "label": WORKLOADS[name],
            "dims_xyz": list(vol.shape[::-1]),
            "vtk_s_per_frame": vtk_s,
            "voxcast_s_per_frame": vox_s,
            "speedup": vtk_s / vox_s,
            "psnr_db_linear": psnr_linear,
            "psnr_db_srgb": psnr_srgb,
            "vtk": {k: v[k] for k in ("first_frame_s", "frame_s", "mapper_time_to_draw_s", "threads")},
            "voxcast": {k: x[k] for k in ("frame_s", "setup_ms", "threads", "samples",
                                          "psnr_vs_own_reference_db")},
            "voxcast_input": str(inp),
        }
        rows.append(row)
        print(f"{name}: VTK {vtk_s:.3f} s ({v['threads']} threads), voxcast {vox_s:.3f} s "
              f"({x['threads']} threads), PSNR {psnr_linear:.1f} dB linear / {psnr_srgb:.1f} dB sRGB",
              file=sys.stderr)

    print(f"\n{cores} cores, {cpu_model()}; VTK {vtk.vtkVersion.GetVTKVersion()} "
          f"(vtkFixedPointVolumeRayCastMapper, {rows[0]['vtk']['threads']} threads) against {version} "
          f"`uniform` ({rows[0]['voxcast']['threads']} threads); {WIDTH}×{HEIGHT}, step {STEP} voxel, "
          f"unshaded; median of {args.frames} frames after the first"
          f"{f' × {args.rounds} rounds' if args.rounds > 1 else ''}.\n")
    print("| workload | VTK s/frame | voxcast s/frame | voxcast speed-up | PSNR VTK vs voxcast (linear / sRGB) |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['label']} | {r['vtk_s_per_frame']:.3f} | {r['voxcast_s_per_frame']:.3f} | "
              f"{r['speedup']:.2f}× | {r['psnr_db_linear']:.1f} / {r['psnr_db_srgb']:.1f} dB |")

    if args.json:
        report = {
            "date": time.strftime("%Y-%m-%d"),
            "machine": {"cores": cores, "cpu": cpu_model(), "platform": platform.platform()},
            "vtk_version": vtk.vtkVersion.GetVTKVersion(),
            "voxcast_version": version,
            "voxcast_binary": str(args.voxcast),
            "settings": {"width": WIDTH, "height": HEIGHT, "step_voxels": STEP, "azimuth": AZIMUTH,
                         "elevation": ELEVATION, "fov_deg": FOV, "shading": False, "frames": args.frames, "rounds": max(1, args.rounds),
                         "vtk_nudge_deg": NUDGE, "transfer_function": TF},
            "workloads": rows,
        }
        args.json.write_text(json.dumps(report, indent=2, default=str) + "\n")


if __name__ == "__main__":
    main()
