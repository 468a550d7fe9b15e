"""Shared fixtures of the Python tests: the CLI binary to compare with, a
small sphere volume, and optional modules that CI must have."""

import importlib
import os
import pathlib
import shutil

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def need(module: str):
    """Imports an optional module; skips without it, except in CI (CI=true),
    where a missing module is a failure, so no test is silently skipped."""
    try:
        return importlib.import_module(module)
    except ImportError:
        if os.environ.get("CI"):
            pytest.fail(f"{module} is not installed; CI installs it (.ci/run)")
        pytest.skip(f"{module} is not installed")


@pytest.fixture(scope="session")
def cli() -> str:
    """The `voxcast` CLI: $VOXCAST_CLI, else the newest build in target/,
    else one on PATH."""
    env = os.environ.get("VOXCAST_CLI")
    if env:
        assert os.path.isfile(env), f"VOXCAST_CLI={env}: no such file"
        return env
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    built = [p for p in (target / "debug" / "voxcast", target / "release" / "voxcast") if p.is_file()]
    if built:
        return str(max(built, key=lambda p: p.stat().st_mtime))
    found = shutil.which("voxcast")
    if found:
        return found
    pytest.fail("no voxcast CLI: build it (cargo build) or set VOXCAST_CLI")


def sphere(n: int = 24, dtype=np.float32) -> np.ndarray:
    """A soft sphere with a bump, indexed [z, y, x] (not symmetric in x, y, z,
    so a swapped axis shows)."""
    z, y, x = np.meshgrid(*(np.arange(n, dtype=np.float32),) * 3, indexing="ij")
    c = (n - 1) / 2
    r = np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2)
    v = np.clip(1.0 - r / (0.45 * n), 0.0, 1.0) + 0.5 * (x > 0.7 * n) * (y < 0.4 * n)
    if np.dtype(dtype).kind == "f":
        return v.astype(dtype)
    return (v / v.max() * 200).astype(dtype)
