"""What rendering a NumPy array from Python costs over the same render from
the CLI (issue target: at most 5 % more).

    python crates/voxcast-py/bench/overhead.py [VOLUME] [--cli target/release/voxcast] [--runs 9]

Both render the same scene (saved as TOML and handed to the CLI with
`--scene`). The CLI's figure is its whole command minus the time it spends
loading the file and resolving the transfer function (it prints that), so
both start from the volume in memory: the CLI's then includes building the
renderer, rendering and writing the PNG. Python's is `vc.render(array)`
(wrapping the array — which computes its value range —, building the
renderer, rendering, returning the array), and `vc.render(vol)` for a Volume
made once. The transfer function is a preset (`--tf`, grayscale by default):
`auto` would compute a histogram that the CLI counts as loading. Medians of
`--runs` runs, alternated.
"""

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import voxcast as vc

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.abspath(os.path.join(HERE, "..", "..", ".."))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("volume", nargs="?", default=os.path.join(REPO, "..", "shared", "data", "mr_head", "HeadMRVolume.mhd"))
    p.add_argument("--cli", default=os.path.join(REPO, "target", "release", "voxcast"))
    p.add_argument("--runs", type=int, default=9)
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--method", default="uniform")
    p.add_argument("--tf", default="grayscale")
    a = p.parse_args()

    src = vc.open(a.volume)
    array = np.array(src.to_numpy())  # the user's own NumPy array (a copy)
    tmp = tempfile.mkdtemp()
    scene = vc.Scene(input=os.path.abspath(a.volume), size=(a.size, a.size), azimuth=30, elevation=20, method=a.method, tf=a.tf)
    scene_file = os.path.join(tmp, "scene.toml")
    scene.to_toml(scene_file)
    # The user's array carries the file's spacing and origin.
    kw = dict(spacing=src.spacing, origin=src.origin)

    once = vc.Volume(array, **kw)
    vc.render(once, scene, progress=False)  # warm-up
    py, py_once, cli, cli_load, render_s = [], [], [], [], []
    for _ in range(a.runs):
        t = time.perf_counter()
        img = vc.render(vc.Volume(array, **kw), scene, progress=False)
        py.append(time.perf_counter() - t)
        render_s.append(img.stats["seconds"])
        t = time.perf_counter()
        vc.render(once, scene, progress=False)
        py_once.append(time.perf_counter() - t)
        t = time.perf_counter()
        r = subprocess.run([a.cli, "render", "--scene", scene_file, "-o", os.path.join(tmp, "cli.png")],
                           check=True, capture_output=True, text=True)
        cli.append(time.perf_counter() - t)
        m = re.search(r"loaded .* in ([0-9.]+) s", r.stderr)
        cli_load.append(float(m.group(1)) if m else 0.0)
    py_m = statistics.median(py)
    once_m = statistics.median(py_once)
    cli_m = statistics.median(cli)
    cli_after_load = statistics.median(c - l for c, l in zip(cli, cli_load))
    print(f"volume {a.volume}: {src.dims[0]}×{src.dims[1]}×{src.dims[2]} {src._v.dtype}, "
          f"{a.size}², {a.method}, tf {a.tf}, {a.runs} runs, medians")
    print(f"  CLI whole command          {cli_m * 1e3:8.1f} ms")
    print(f"  CLI after loading the file {cli_after_load * 1e3:8.1f} ms")
    print(f"  Python vc.render(array)    {py_m * 1e3:8.1f} ms   (ray casting alone {statistics.median(render_s) * 1e3:.1f} ms)")
    print(f"  Python vc.render(vol)      {once_m * 1e3:8.1f} ms   (the Volume made once)")
    print(f"  Python array / CLI after loading {py_m / cli_after_load:8.3f}×")
    print(f"  Python vol / CLI after loading   {once_m / cli_after_load:8.3f}×")
    print(f"  Python array / CLI whole command {py_m / cli_m:8.3f}×")


if __name__ == "__main__":
    sys.exit(main())
