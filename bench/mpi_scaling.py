#!/usr/bin/env python3
"""Sort-last rendering over MPI: time per process, compositing, bytes moved.

Runs `mpirun -np N voxcast render INPUT` for each N (the voxcast binary
built with `--features mpi`), several times each, and prints a Markdown
table of medians: the slowest process's render, the wait for it, the
compositing, bytes sent per pixel, bytes read, and the PSNR of the
composited image against one plain process (`--ert 1`, out of core for a
store, as each part renders). Standard library only.

    cargo build --release --features mpi -p voxcast-cli
    python3 bench/mpi_scaling.py ../shared/data/teapot_ct/slices --size 512x512
    python3 bench/mpi_scaling.py f512.zarr --size 1024x1024 --tf fire --level 0

Processes are not bound to cores (`--bind-to none`): each takes its share
of the machine's cores as threads (RAYON_NUM_THREADS overrides).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    return p


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("input")
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--np", default="1,2,4", help="process counts (default 1,2,4)")
    ap.add_argument("--rounds", type=int, default=3, help="renders per count (median)")
    ap.add_argument("--voxcast", default="target/release/voxcast")
    ap.add_argument("--json", help="write every figure here")
    # Any other flag is passed to `voxcast render`.
    a, extra = ap.parse_known_args()
    a.extra = [x for x in extra if x != "--"]
    vox = os.path.abspath(a.voxcast)
    tmp = tempfile.mkdtemp(prefix="voxcast-mpi-")
    base = [a.input, "--size", a.size, "--quiet", *a.extra]
    one = os.path.join(tmp, "one.png")
    ref = [vox, "render", *base, "--ert", "1", "-o", one]
    if a.input.rstrip("/").endswith(".zarr"):
        ref.append("--out-of-core")
    run(ref)
    rows, figures = [], {}
    for n in [int(x) for x in a.np.split(",")]:
        runs = []
        for r in range(a.rounds):
            out = os.path.join(tmp, f"n{n}.png")
            js = os.path.join(tmp, f"n{n}-{r}.json")
            run(["mpirun", "--allow-run-as-root", "--oversubscribe", "--bind-to", "none",
                 "-np", str(n), vox, "render", *base, "-o", out, "--stats-json", js])
            runs.append(json.load(open(js))["mpi"])
        cmp = run([vox, "compare", one, out, "--json"])
        db = json.loads(cmp.stdout).get("psnr_db")
        med = lambda f: statistics.median(f(m) for m in runs)
        per = runs[len(runs) // 2]["per_process"]
        row = {
            "processes": n,
            "render_s": med(lambda m: m["render_seconds_max"]),
            "mean_render_s": med(lambda m: statistics.mean(p["render_seconds"] for p in m["per_process"])),
            "wait_s": med(lambda m: max(p["wait_seconds"] for p in m["per_process"])),
            "composite_s": med(lambda m: m["composite_seconds_max"]),
            "bytes_per_pixel": runs[0]["bytes_per_pixel"],
            "read_mib": sum(p["bytes_read"] for p in per) / 2**20,
            "visible_chunks": [int(p["visible_chunks"]) for p in per],
            "psnr_db": db,
        }
        rows.append(row)
        figures[n] = runs
    print(f"| processes | render, slowest (mean) | wait | compositing | bytes sent / pixel | read | chunks that may show, per process | PSNR vs 1 process |")
    print("|---:|---:|---:|---:|---:|---:|---|---:|")
    for r in rows:
        db = "identical" if r["psnr_db"] is None else f"{r['psnr_db']:.1f} dB"
        print(f"| {r['processes']} | {r['render_s']:.3f} s ({r['mean_render_s']:.3f}) | {r['wait_s']:.3f} s "
              f"| {r['composite_s'] * 1e3:.1f} ms | {r['bytes_per_pixel']:.1f} | {r['read_mib']:.1f} MiB "
              f"| {r['visible_chunks']} | {db} |")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rows": rows, "runs": figures}, f, indent=1)


if __name__ == "__main__":
    main()
