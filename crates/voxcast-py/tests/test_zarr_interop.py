"""OME-Zarr interop: stores that `voxcast convert` writes open in zarr-python
and ome-zarr-py with the right metadata and pyramid, and stores that
zarr-python writes (Zarr v2 with blosc, v3 with zstd, a leading channel axis)
are read by `voxcast info` / `voxcast convert` voxel for voxel."""

import json
import math
import subprocess

import numpy as np
import pytest

from conftest import need


def run(cli, *args):
    """Runs the CLI; a failure shows its stderr."""
    p = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
    assert p.returncode == 0, f"voxcast {' '.join(map(str, args))} failed ({p.returncode}):\n{p.stderr}"
    return p.stdout


def info(cli, store, *args):
    return json.loads(run(cli, "info", store, "--json", *args))


def mean_2x2x2(a: np.ndarray) -> np.ndarray:
    """The 2×2×2 mean (float64) of a z,y,x array; at odd edges only the voxels
    that exist are averaged."""
    out_shape = tuple(math.ceil(n / 2) for n in a.shape)
    total = np.zeros(out_shape, np.float64)
    count = np.zeros(out_shape, np.float64)
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                part = a[dz::2, dy::2, dx::2].astype(np.float64)
                sz, sy, sx = part.shape
                total[:sz, :sy, :sx] += part
                count[:sz, :sy, :sx] += 1
    return total / count


def round_half_up(m: np.ndarray, dtype) -> np.ndarray:
    """Integer means rounded to nearest (a mean of n/8 ending in .5 goes up;
    the means are never negative here)."""
    return np.floor(m + 0.5).astype(dtype)


def multiscales_attrs(group, zarr_format: int) -> dict:
    """The one multiscales entry: v3 (OME-Zarr 0.5) under "ome", v2 (0.4) at
    the top of the attributes."""
    attrs = dict(group.attrs)
    if zarr_format == 3:
        assert "ome" in attrs, f"no 'ome' attributes: {sorted(attrs)}"
        assert attrs["ome"]["version"] == "0.5"
        ms = attrs["ome"]["multiscales"]
    else:
        assert "multiscales" in attrs, f"no 'multiscales' attributes: {sorted(attrs)}"
        ms = attrs["multiscales"]
        assert ms[0]["version"] == "0.4"
    assert len(ms) == 1
    return ms[0]


# --- voxcast writes, zarr-python and ome-zarr-py read -----------------------


@pytest.mark.parametrize("zarr_format", [3, 2])
def test_voxcast_pyramid_opens_in_zarr_python_and_ome_zarr(tmp_path, cli, zarr_format):
    zarr = need("zarr")
    need("ome_zarr")
    from ome_zarr.io import parse_url
    from ome_zarr.reader import Multiscales, Reader

    store = tmp_path / "demo.zarr"
    run(cli, "convert", "builtin:demo", "-o", store, "--chunk", "32", "--zarr-version", zarr_format, "-q")

    group = zarr.open_group(str(store), mode="r")
    assert group.metadata.zarr_format == zarr_format
    ms = multiscales_attrs(group, zarr_format)
    assert [a["name"] for a in ms["axes"]] == ["z", "y", "x"]
    paths = [d["path"] for d in ms["datasets"]]
    levels = len(paths)
    assert levels >= 2
    assert paths == [str(i) for i in range(levels)]

    shape = (128, 128, 128)
    for i, path in enumerate(paths):
        arr = group[path]
        assert arr.shape == shape, f"level {i}"
        assert arr.dtype == np.uint8
        assert arr.fill_value == 0
        shape = tuple(math.ceil(n / 2) for n in shape)
        scale = next(t for t in ms["datasets"][i]["coordinateTransformations"] if t["type"] == "scale")
        assert scale["scale"] == [2.0**i] * 3

    # Level 1 is level 0's 2×2×2 mean, rounded to nearest (128³: no odd edges).
    level0 = group["0"][:]
    assert level0.shape == (128, 128, 128) and level0.max() > 0
    expected = round_half_up(mean_2x2x2(level0), np.uint8)
    level1 = group["1"][:]
    assert level1.dtype == np.uint8
    np.testing.assert_array_equal(level1, expected)

    # voxcast reads back what it wrote, with the numbers numpy gives.
    got = info(cli, store)
    assert got["dims"] == [128, 128, 128]
    assert got["scalar_type"] == "u8"
    assert got["min"] == float(level0.min()) and got["max"] == float(level0.max())
    assert got["mean"] == pytest.approx(float(level0.mean()), rel=1e-5)

    # ome-zarr-py: one image node with every level.
    location = parse_url(str(store), mode="r")
    assert location is not None, "ome_zarr.io.parse_url did not recognise the store"
    nodes = list(Reader(location)())
    images = [n for n in nodes if any(isinstance(s, Multiscales) for s in n.specs)]
    assert len(images) == 1, f"{len(images)} image nodes of {len(nodes)}"
    data = images[0].data
    assert len(data) == levels
    assert [tuple(d.shape) for d in data] == [group[p].shape for p in paths]
    np.testing.assert_array_equal(np.asarray(data[1]), level1)


# --- zarr-python writes, voxcast reads --------------------------------------


def structured_u16(shape) -> np.ndarray:
    """Seeded u16 voxels (z,y,x) with structure along every axis and a zero
    block, so a swapped axis, an edge chunk or a skipped chunk shows."""
    z, y, x = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    rng = np.random.default_rng(16)
    a = (1 + 1000 * z + 37 * y + x + rng.integers(0, 500, size=shape)).astype(np.uint16)
    a[:16, :16, :16] = 0  # one whole 16³ chunk of the copy holds only zeros
    a[5, 30, 40] = 65535
    return a


def write_ome_group(zarr, path, data, zarr_format, axes, scale, chunks):
    """A one-level OME-Zarr image written by hand with zarr-python: 0.4
    metadata for v2 (blosc, the v2 default), 0.5 for v3 (default zstd)."""
    multiscales = {
        "axes": axes,
        "datasets": [{"path": "0", "coordinateTransformations": [{"type": "scale", "scale": scale}]}],
        "name": "from-zarr-python",
    }
    group = zarr.open_group(str(path), mode="w", zarr_format=zarr_format)
    if zarr_format == 2:
        numcodecs = need("numcodecs")
        arr = group.create_array(
            "0", shape=data.shape, dtype=data.dtype, chunks=chunks, compressors=numcodecs.Blosc()
        )
        group.attrs["multiscales"] = [{"version": "0.4", **multiscales}]
    else:
        arr = group.create_array("0", shape=data.shape, dtype=data.dtype, chunks=chunks)
        group.attrs["ome"] = {"version": "0.5", "multiscales": [multiscales]}
    arr[...] = data
    return arr


ZYX = [{"name": n, "type": "space", "unit": "micrometer"} for n in "zyx"]


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_zarr_python_store_is_read_and_converted_voxel_for_voxel(tmp_path, cli, zarr_format):
    zarr = need("zarr")
    a = structured_u16((23, 37, 41))
    store = tmp_path / "py.zarr"
    arr = write_ome_group(zarr, store, a, zarr_format, ZYX, [2.0, 0.5, 0.25], chunks=(8, 16, 16))
    codecs = json.dumps(arr.metadata.to_dict())
    assert ("blosc" if zarr_format == 2 else "zstd") in codecs, codecs

    got = info(cli, store)
    assert got["dims"] == [41, 37, 23]
    assert got["scalar_type"] == "u16"
    assert got["spacing"] == pytest.approx([0.25, 0.5, 2.0])
    assert got["min"] == float(a.min()) == 0.0
    assert got["max"] == float(a.max()) == 65535.0
    assert got["mean"] == pytest.approx(float(a.mean()), rel=1e-5)

    copy = tmp_path / "copy.zarr"
    run(cli, "convert", store, "-o", copy, "--chunk", "16", "-q")
    copied = zarr.open_group(str(copy), mode="r")
    level0 = copied["0"][:]
    assert level0.dtype == np.uint16
    assert level0.shape == a.shape
    assert np.array_equal(level0, a)
    # The zero chunk was not written (2×3×3 chunks of 16³, one of only
    # zeros), and reads back as the fill value.
    assert copied["0"].fill_value == 0
    assert copied["0"].nchunks == 18
    assert copied["0"].nchunks_initialized == 17

    # Level 1 over odd edges: only the voxels that exist are averaged.
    level1 = copied["1"][:]
    assert level1.shape == (12, 19, 21)
    np.testing.assert_array_equal(level1, round_half_up(mean_2x2x2(a), np.uint16))

    # The spacing survives the copy: level 0's scale is the source's.
    ms = multiscales_attrs(copied, 3)
    scale = next(t for t in ms["datasets"][0]["coordinateTransformations"] if t["type"] == "scale")
    assert scale["scale"] == pytest.approx([2.0, 0.5, 0.25])


def test_leading_channel_axis_picks_the_channel_with_var(tmp_path, cli):
    zarr = need("zarr")
    shape = (12, 10, 14)  # z, y, x
    rng = np.random.default_rng(3)
    channels = np.stack(
        [
            rng.integers(10, 101, size=shape).astype(np.uint16),
            rng.integers(500, 901, size=shape).astype(np.uint16),
        ]
    )
    channels[0, 0, 0, 0], channels[0, 1, 2, 3] = 5, 120
    channels[1, 11, 9, 13], channels[1, 4, 4, 4] = 400, 1234
    axes = [{"name": "c", "type": "channel"}, *ZYX]
    store = tmp_path / "channels.zarr"
    write_ome_group(zarr, store, channels, 2, axes, [1.0, 1.5, 1.0, 0.5], chunks=(1, 6, 5, 7))

    second = info(cli, store, "--var", "1")
    assert second["dims"] == [14, 10, 12]
    assert second["spacing"] == pytest.approx([0.5, 1.0, 1.5])
    assert (second["min"], second["max"]) == (400.0, 1234.0)
    assert second["mean"] == pytest.approx(float(channels[1].mean()), rel=1e-5)

    first = info(cli, store, "--var", "0")
    assert (first["min"], first["max"]) == (5.0, 120.0)
