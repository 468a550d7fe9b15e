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
