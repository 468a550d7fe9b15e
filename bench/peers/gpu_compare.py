#!/usr/bin/env python3
"""voxcast's GPU back end against a bare CUDA ray cast (../shared/tools/gpu_ceiling.py) on one NVIDIA GPU.

For each workload (the teapot CT, Marschner-Lobb 256^3 dense, 24 Gaussian blobs 256^3 sparse: the volumes
of vtk_compare.py) and image size it runs:

* the ceiling: a CUDA kernel with hardware trilinear 3D-texture fetches, a 256-entry TF, front-to-back,
  no skipping, no early termination (CuPy), its samples/s;
* `voxcast bench --device gpu --methods uniform` dense (--skip-empty off --ert 1 --jitter off), with
  --gpu-filter exact and hardware: GPU milliseconds by timestamp queries, hence samples/s against the
  ceiling's;
* the same with voxcast's defaults (empty-space skipping, early termination 0.99): frames per second on
  the GPU (timestamps) and wall clock (adds writing the parameters, reading the image back, averaging);
  shaded too.

Prints a Markdown table and writes every report as JSON. Needs numpy and pillow; the ceiling needs CuPy.

    python3 bench/peers/gpu_compare.py --voxcast target/release/voxcast --json gpu.json
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np  # noqa: E402
import vtk_compare as vc  # noqa: E402  (volumes, transfer function, camera; vtk itself is not imported)

REPO = Path(__file__).resolve().parents[2]


def teapot_raw(data: Path, work: Path) -> Path:
    """The teapot slices as one raw u8 file (z, y, x), for the ceiling."""
    from PIL import Image

    files = sorted((data / "teapot_ct" / "slices").glob("teapot_*.png"))
    if len(files) != 178:
        sys.exit(f"expected 178 teapot slices in {data / 'teapot_ct' / 'slices'}, found {len(files)}")
    vol = np.stack([np.asarray(Image.open(f).convert("L"), dtype=np.uint8) for f in files])
    out = work / "teapot_256x256x178.raw"
    vol.tofile(out)
    return out


def run(cmd, env=None):
    try:
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    except OSError as e:
        return 127, "", str(e)
    return p.returncode, p.stdout, p.stderr


def ceiling(script: Path, raw: Path, dims, size, step):
    code, out, err = run([sys.executable, str(script), str(raw), *map(str, dims), str(size), str(size), str(step)])
    if code != 0:
        return {"error": (err or out).strip().splitlines()[-1:] or ["failed"]}
    return json.loads(out.strip().splitlines()[-1])


def bench(exe: Path, inp: Path, tf: Path, size: int, extra, work: Path, name: str, frames: int, env):
    js = work / f"{name}.json"
    flags = vc.voxcast_scene_flags(tf)
    flags[flags.index("--size") + 1] = f"{size}x{size}"
    extra = list(extra)
    for opt in ("--shading",):  # a variant's setting replaces the scene's
        if opt in extra:
            i = extra.index(opt)
            flags[flags.index(opt) + 1] = extra[i + 1]
            del extra[i:i + 2]
    cmd = [str(exe), "bench", str(inp), *flags, "--device", "gpu", "--methods", "uniform",
           "--repeat", str(frames), "--warmup", "2", "--json", str(js), "--quiet", *extra]
    code, out, err = run(cmd, env)
    if code != 0:
        return {"error": err.strip()[-400:], "cmd": " ".join(cmd)}
    rep = json.loads(js.read_text())
    m = next(m for m in rep["methods"] if m["name"] == "uniform")
    gpu_ms = m.get("device_ms_median")
    return {
        "cmd": " ".join(cmd),
        "samples": m["samples"],
        "wall_ms": m["ms_median"],
        "gpu_ms": gpu_ms,
        "gsamples_per_s": m["samples"] / gpu_ms * 1e-6 if gpu_ms else None,
        "fps_gpu": 1000.0 / gpu_ms if gpu_ms else None,
        "fps_wall": 1000.0 / m["ms_median"],
        "psnr_db": m["psnr_db"],
        "device": rep["run"]["device"],
        "notes": rep["notes"],
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--voxcast", type=Path, default=REPO / "target" / "release" / "voxcast")
    ap.add_argument("--data", type=Path, default=Path(os.environ.get("VOXCAST_DATA", REPO.parent / "shared" / "data")))
    ap.add_argument("--ceiling", type=Path, default=REPO.parent / "shared" / "tools" / "gpu_ceiling.py")
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "voxcast-gpu-peers")
    ap.add_argument("--sizes", default="1024,512", help="square image sizes")
    ap.add_argument("--workloads", default="teapot,ml,blobs")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--no-ceiling", action="store_true", help="skip the CUDA ceiling (no CuPy or no NVIDIA GPU)")
    ap.add_argument("--variants", help="comma-separated subset of: dense exact, dense hardware, default exact, "
                    "default hardware, shaded exact, shaded hardware (e.g. 'dense exact,dense hardware')")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    a.work.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    env.setdefault("VOXCAST_CACHE", str(a.work / "cache"))
    tf = a.work / "tf.toml"
    vc.write_tf_toml(tf)
    inputs = {}
    for w in a.workloads.split(","):
        if w == "teapot":
            inputs[w] = (a.data / "teapot_ct" / "slices", teapot_raw(a.data, a.work), (256, 256, 178))
        elif w == "ml":
            nhdr = vc.write_nrrd(a.work / "marschner_lobb_256", vc.marschner_lobb(), "Marschner-Lobb")
            inputs[w] = (nhdr, nhdr.with_suffix(".raw"), (256, 256, 256))
        elif w == "blobs":
            nhdr = vc.write_nrrd(a.work / "blobs24_256", vc.gaussian_blobs(), "24 Gaussian blobs")
            inputs[w] = (nhdr, nhdr.with_suffix(".raw"), (256, 256, 256))
        else:
            sys.exit(f"unknown workload {w}")
    dense = ["--skip-empty", "off", "--ert", "1", "--jitter", "off"]
    variants = {
        "dense exact": dense + ["--gpu-filter", "exact"],
        "dense hardware": dense + ["--gpu-filter", "hardware"],
        "default exact": ["--gpu-filter", "exact"],
        "default hardware": ["--gpu-filter", "hardware"],
        "shaded exact": ["--gpu-filter", "exact", "--shading", "on"],
        "shaded hardware": ["--gpu-filter", "hardware", "--shading", "on"],
    }
    if a.variants:
        keep = [v.strip() for v in a.variants.split(",")]
        unknown = [v for v in keep if v not in variants]
        if unknown:
            sys.exit(f"unknown variant(s) {unknown}; known: {list(variants)}")
        variants = {k: v for k, v in variants.items() if k in keep}
    results = {"machine": {"platform": platform.platform(),
                           "workgroup": os.environ.get("VOXCAST_GPU_WORKGROUP", "8x8")}, "runs": []}
    code, out, _ = run(["nvidia-smi", "--query-gpu=name,driver_version,clocks.max.sm", "--format=csv,noheader"])
    results["machine"]["nvidia_smi"] = out.strip() if code == 0 else None
    for size in map(int, a.sizes.split(",")):
        for w, (inp, raw, dims) in inputs.items():
            row = {"workload": w, "size": size}
            if not a.no_ceiling:
                row["ceiling"] = ceiling(a.ceiling, raw, dims, size, vc.STEP)
            for name, extra in variants.items():
                row[name] = bench(a.voxcast, inp, tf, size, extra, a.work, f"{w}-{size}-{name.replace(' ', '-')}",
                                  a.frames, env)
                print(f"{w} {size}² {name}: {json.dumps({k: v for k, v in row[name].items() if k != 'notes'})}",
                      file=sys.stderr, flush=True)
            results["runs"].append(row)
    if a.json:
        a.json.write_text(json.dumps(results, indent=1))
    dev = next((r[k]["device"] for r in results["runs"] for k in variants if "device" in r[k]), "?")
    print(f"\nGPU: {results['machine']['nvidia_smi'] or dev}; voxcast on {dev}\n")
    print("| workload | size | ceiling G samples/s | dense exact G/s (% of ceiling) | dense hardware G/s (%) "
          "| default exact fps GPU / wall | default hardware fps GPU / wall | shaded exact / hardware fps GPU "
          "| PSNR exact / hardware dB |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")

    def g(r, k):
        return r.get(k) if isinstance(r, dict) else None

    def pct(x, c):
        return f"{x:.2f} ({100 * x / c:.0f} %)" if x and c else (f"{x:.2f}" if x else "–")

    def fps(r):
        return f"{r['fps_gpu']:.0f} / {r['fps_wall']:.0f}" if g(r, "fps_gpu") else "–"

    for r in results["runs"]:
        c = g(r.get("ceiling"), "gsamples_per_s")
        se, sh = r.get("shaded exact"), r.get("shaded hardware")
        de, dh = r.get("default exact"), r.get("default hardware")
        print(f"| {vc.WORKLOADS[r['workload']]} | {r['size']}² | {c if c else 'n/a'} "
              f"| {pct(g(r.get('dense exact'), 'gsamples_per_s'), c)} "
              f"| {pct(g(r.get('dense hardware'), 'gsamples_per_s'), c)} "
              f"| {fps(de)} | {fps(dh)} "
              f"| {g(se, 'fps_gpu') or 0:.0f} / {g(sh, 'fps_gpu') or 0:.0f} "
              f"| {g(de, 'psnr_db') or 0:.1f} / {g(dh, 'psnr_db') or 0:.1f} |")


if __name__ == "__main__":
    main()
