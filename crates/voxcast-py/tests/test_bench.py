"""`vc.bench`: the bench table as a list of dicts."""

import voxcast as vc
from conftest import sphere


def test_bench_returns_one_row_per_method_with_the_cli_table():
    vol = vc.Volume(sphere(32))
    rows = vc.bench(vol, methods=["adaptive", "uniform+noskip"], repeat=1, warmup=0, cache=False,
                    size=(48, 48), progress=False)
    names = [r["name"] for r in rows]
    assert names == ["uniform", "adaptive", "uniform+noskip"]  # uniform, the baseline, added first
    for r in rows:
        assert r["samples"] > 0 and r["ms_median"] > 0
        # psnr_db is None (JSON null) when identical to the reference.
        assert r["psnr_db"] is None or r["psnr_db"] > 20
    assert rows.report["scene"]["width"] == 48
    assert any("baseline" in n for n in rows.report["notes"])
    assert "adaptive" in str(rows) and "PSNR" in str(rows)


def test_ctrl_c_stops_a_bench():
    import os
    import signal
    import threading
    import time

    import pytest

    vol = vc.Volume(sphere(48))
    slow = dict(size=(256, 256), step=0.05, **{"render.skip_empty": False})
    t0 = time.perf_counter()
    vc.render(vol, progress=False, **slow)
    one = time.perf_counter() - t0
    # Ten timed renders of three methods and a reference: about 30 renders.
    timer = threading.Timer(2 * one, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        vc.bench(vol, methods="uniform,adaptive,threshold", repeat=10, warmup=0, cache=False,
                 progress=False, **slow)
    stopped = time.perf_counter() - t0
    timer.join()
    assert stopped < 8 * one, (stopped, one)
