"""Renders: against the CLI byte for byte, the GIL, Ctrl-C, progress,
Jupyter, images, orbits."""

import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import voxcast as vc
from conftest import REPO, need, sphere

PNG = b"\x89PNG\r\n\x1a\n"


def test_numpy_sphere_renders_the_bytes_the_cli_renders_from_the_same_scene(tmp_path, cli):
    vol = vc.Volume(sphere(24), spacing=(1.0, 1.0, 1.5))
    vol.save(tmp_path / "sphere.nrrd")
    scene = vc.Scene(
        input=tmp_path / "sphere.nrrd",
        tf="viridis",
        azimuth=35,
        elevation=25,
        size=(96, 80),
        method="adaptive+grouped",
    )
    scene.to_toml(tmp_path / "scene.toml")
    img = vc.render(vol, scene, progress=False)
    assert img.shape == (80, 96, 4) and img.dtype == np.float32
    assert img.stats["rays"] == 96 * 80 and img.stats["samples"] > 0
    assert 0.05 < float(img[..., 3].mean()) < 0.95, "the sphere fills part of the frame"
    img.save(tmp_path / "py.png")
    subprocess.run(
        [cli, "render", "--scene", str(tmp_path / "scene.toml"), "-o", str(tmp_path / "cli.png"), "-q"],
        check=True,
    )
    assert (tmp_path / "py.png").read_bytes() == (tmp_path / "cli.png").read_bytes()
    # The scene's own input, read by the library, gives the same bytes.
    again = vc.render(scene=vc.Scene.from_toml(tmp_path / "scene.toml"), progress=False)
    again.save(tmp_path / "again.png")
    assert (tmp_path / "again.png").read_bytes() == (tmp_path / "cli.png").read_bytes()
    # The linear floats agree too (EXR files differ in their chunk order, so
    # the CLI compares the pixels).
    img.save(tmp_path / "py.exr")
    subprocess.run(
        [cli, "render", "--scene", str(tmp_path / "scene.toml"), "-o", str(tmp_path / "cli.exr"), "-q"],
        check=True,
    )
    same = subprocess.run(
        [cli, "compare", str(tmp_path / "py.exr"), str(tmp_path / "cli.exr")],
        check=True, capture_output=True, text=True,
    )
    assert "identical" in same.stdout, same.stdout


def test_the_demo_with_no_arguments_matches_voxcast_render(tmp_path, cli):
    img = vc.render(size=(64, 48), progress=False)
    img.save(tmp_path / "py.png")
    subprocess.run([cli, "render", "--size", "64x48", "-o", str(tmp_path / "cli.png"), "-q"], check=True)
    assert (tmp_path / "py.png").read_bytes() == (tmp_path / "cli.png").read_bytes()


def test_settings_change_the_picture_and_bad_ones_name_themselves():
    vol = vc.Volume(sphere(20))
    a = vc.render(vol, size=32, azimuth=0, progress=False)
    b = vc.render(vol, size=32, azimuth=90, progress=False)
    assert not np.array_equal(a, b), "the sphere's bump moves with the camera"
    c = vc.render(vol, size=32, azimuth=0, tf="fire", progress=False)
    assert not np.array_equal(a, c)
    d = vc.render(vol, size=32, azimuth=0, **{"render.jitter": False}, progress=False)
    assert d.stats["samples"] > 0
    with pytest.raises(vc.VoxcastError, match="azimth.*did you mean 'azimuth'"):
        vc.render(vol, azimth=3)
    with pytest.raises(vc.VoxcastError, match="step"):
        vc.render(vol, step=-1.0)
    with pytest.raises(vc.VoxcastError, match="method"):
        vc.render(vol, method="fastest")
    with pytest.raises(vc.VoxcastError, match="device"):
        vc.render(vol, size=8, device="tpu")


def test_transfer_functions_from_points_and_colormaps():
    vol = vc.Volume(sphere(16))
    red = vc.TransferFunction(color=[(0, 1, 0, 0), (1, 1, 0, 0)], opacity=[(0, 0), (1, 0.5)])
    img = vc.render(vol, tf=red, size=24, background="black", progress=False)
    rgb = img[..., :3].reshape(-1, 3)
    lit = rgb[rgb.sum(axis=1) > 0.05]
    assert len(lit) > 20 and np.all(lit[:, 0] > 5 * lit[:, 1]), "red transfer function, red pixels"
    need("matplotlib")
    tf = vc.TransferFunction.from_colormap("magma", stops=8)
    assert len(tf["color"]) == 8 and tf["opacity"][0] == [0.0, 0.0]
    by_name = vc.render(vol, tf="magma", size=24, progress=False)
    assert not np.array_equal(by_name, img)
    with pytest.raises(vc.VoxcastError, match="magmaa.*did you mean 'magma'"):
        vc.TransferFunction.from_colormap("magmaa")


def test_repr_png_is_the_png_that_save_writes(tmp_path):
    img = vc.render(vc.Volume(sphere(12)), size=(20, 16), progress=False)
    png = img._repr_png_()
    assert png.startswith(PNG)
    img.save(tmp_path / "x.png")
    assert (tmp_path / "x.png").read_bytes() == png
    assert img.to_srgb8().shape == (16, 20, 3)
    assert img[0]._repr_png_() is None  # a row is not an image
    with pytest.raises(vc.VoxcastError, match=r"must end in \.png or \.exr"):
        img.save(tmp_path / "x.jpg")


def test_an_image_is_never_written_into_the_volume_source():
    folder = REPO.parent / "shared" / "data" / "dicom_ct_lung"
    vol = vc.open(folder)
    img = vc.render(vol, size=8, progress=False)
    before = sorted(os.listdir(folder))
    # A file inside a slice folder would join the stack next time.
    with pytest.raises(vc.VoxcastError, match="refusing to write"):
        img.save(folder / "render.png")
    with pytest.raises(vc.VoxcastError, match="refusing to write"):
        vc.orbit(vol, frames=1, size=8, path=folder / "o.gif", progress=False)
    assert sorted(os.listdir(folder)) == before


def _slow_scene():
    # Fine steps on a 512² image: long enough to watch (≥ 0.3 s here).
    return dict(size=(512, 512), step=0.02, ert=1.0, **{"render.skip_empty": False})


def test_the_gil_is_released_while_rendering():
    vol = vc.Volume(sphere(64))
    done = threading.Event()
    result = {}

    def work():
        t = time.perf_counter()
        result["img"] = vc.render(vol, progress=False, **_slow_scene())
        result["seconds"] = time.perf_counter() - t
        done.set()

    th = threading.Thread(target=work)
    ticks = 0
    th.start()
    while not done.is_set():
        ticks += 1
        time.sleep(0.002)
    th.join()
    # With the GIL held for the whole render this thread would not tick.
    assert result["seconds"] > 0.1
    assert ticks >= 20, (ticks, result["seconds"])


def test_ctrl_c_cancels_a_render():
    vol = vc.Volume(sphere(64))
    t0 = time.perf_counter()
    vc.render(vol, progress=False, **_slow_scene())
    full = time.perf_counter() - t0
    timer = threading.Timer(0.1 * full, lambda: os.kill(os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        vc.render(vol, progress=False, **_slow_scene())
    stopped = time.perf_counter() - t0
    timer.join()
    assert stopped < 0.7 * full, (stopped, full)


def test_progress_reports_tiles_and_a_raising_callback_cancels():
    vol = vc.Volume(sphere(64))
    seen = []
    vc.render(vol, progress=lambda d, t: seen.append((d, t)), **_slow_scene())
    assert seen, "a render of some tenths of a second reports progress"
    assert all(0 <= d <= t for d, t in seen) and len({t for _, t in seen}) == 1
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)

    class Stop(Exception):
        pass

    def stop(d, t):
        raise Stop()

    with pytest.raises(Stop):
        vc.render(vol, progress=stop, **_slow_scene())


def test_orbit_returns_frames_and_writes_a_gif(tmp_path):
    vol = vc.Volume(sphere(16))
    frames = vc.orbit(vol, frames=4, size=(24, 20), path=tmp_path / "o.gif", progress=False)
    assert len(frames) == 4 and all(f.shape == (20, 24, 4) for f in frames)
    assert not np.array_equal(frames[0], frames[1])
    data = (tmp_path / "o.gif").read_bytes()
    assert data.startswith(b"GIF89a")
    with pytest.raises(vc.VoxcastError, match=".gif or .mp4"):
        vc.orbit(vol, frames=2, path=tmp_path / "o.avi")


def test_ipython_displays_an_image_as_png():
    formatters = need("IPython.core.formatters")
    img = vc.render(vc.Volume(sphere(12)), size=(16, 12), progress=False)
    png = formatters.PNGFormatter()(img)
    assert png is not None and bytes(png).startswith(PNG)
