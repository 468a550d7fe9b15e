"""Volumes from NumPy arrays, xarray DataArrays and files."""

import numpy as np
import pytest

import voxcast as vc
from conftest import REPO, need, sphere


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int16, np.float32])
def test_c_ordered_zyx_array_is_read_in_place_and_round_trips(dtype):
    a = np.ascontiguousarray(sphere(12, dtype)[:, :10, :])  # z 12, y 10, x 12
    vol = vc.Volume(a, spacing=(0.5, 0.75, 2.0), origin=(1, 2, 3))
    assert vol.shares_memory
    assert vol.dims == (12, 10, 12)
    assert vol.spacing == (0.5, 0.75, 2.0)
    assert vol.origin == (1.0, 2.0, 3.0)
    assert vol.dtype == np.dtype(dtype)
    out = vol.to_numpy()
    assert out.shape == a.shape and out.dtype == a.dtype
    np.testing.assert_array_equal(out, a)
    # Neither way is there a copy: the view is the caller's memory.
    assert np.shares_memory(out, a)
    assert not out.flags.writeable
    assert np.shares_memory(np.asarray(vol), a)
    info = vol.info()
    assert info["dims"] == [12, 10, 12]
    assert info["dtype"] == vol._v.dtype
    assert info["min"] == pytest.approx(float(a.min())) and info["max"] == pytest.approx(float(a.max()))
    assert info["bytes"] == a.nbytes


def test_f_ordered_xyz_array_is_read_in_place():
    zyx = sphere(10)
    xyz = np.asfortranarray(zyx.transpose(2, 1, 0))  # nibabel's layout
    vol = vc.Volume(xyz, axes="xyz")
    assert vol.shares_memory
    assert vol.dims == (10, 10, 10)
    np.testing.assert_array_equal(vol.to_numpy(), xyz)
    np.testing.assert_array_equal(vol.to_numpy("zyx"), zyx)
    # The same voxels as the C-ordered zyx array: the same volume.
    np.testing.assert_array_equal(vc.Volume(zyx).to_numpy("xyz"), xyz)


def test_f_ordered_array_with_zyx_axes_is_copied_to_x_fastest():
    zyx = sphere(9)[:, :7, :]
    f = np.asfortranarray(zyx)
    vol = vc.Volume(f)
    assert not vol.shares_memory
    assert vol.dims == (9, 7, 9)
    np.testing.assert_array_equal(vol.to_numpy(), zyx)


def test_non_contiguous_and_foreign_arrays_are_copied_with_the_right_values():
    big = sphere(16)
    view = big[::2, 1:12, ::3]
    vol = vc.Volume(view)
    assert not vol.shares_memory
    np.testing.assert_array_equal(vol.to_numpy(), view)
    # float64 becomes float32; big-endian u16 becomes native; bool becomes u8.
    assert vc.Volume(big.astype(np.float64)).dtype == np.float32
    be = sphere(8, np.uint16).astype(">u2")
    np.testing.assert_array_equal(vc.Volume(be).to_numpy(), be.astype(np.uint16))
    assert vc.Volume(big > 0.5).dtype == np.uint8


def test_a_2d_array_and_bad_arguments_raise_voxcast_error():
    with pytest.raises(vc.VoxcastError, match=r"shape \(4, 5\).*3-D"):
        vc.Volume(np.zeros((4, 5), np.float32))
    with pytest.raises(vc.VoxcastError, match="axes"):
        vc.Volume(sphere(4), axes="zyy")
    with pytest.raises(vc.VoxcastError, match="spacing"):
        vc.Volume(sphere(4), spacing=(1, 0, 1))
    with pytest.raises(vc.VoxcastError, match="expected numbers"):
        vc.Volume(np.full((2, 2, 2), "a"))


def test_a_missing_file_raises_voxcast_error_naming_it(tmp_path):
    missing = tmp_path / "nope.nrrd"
    with pytest.raises(vc.VoxcastError, match="nope.nrrd"):
        vc.open(missing)
    bad = tmp_path / "bad.nrrd"
    bad.write_bytes(b"NRRD0004\ntype: float\ndimension: 3\nsizes: 100 100 100\nencoding: raw\n\n1234")
    with pytest.raises(vc.VoxcastError, match="bad.nrrd"):
        vc.open(bad)
    assert issubclass(vc.VoxcastError, Exception)


def test_files_open_with_every_reader_and_save_refuses_the_source(tmp_path):
    data = REPO.parent / "shared" / "data"
    mhd = data / "mr_head" / "HeadMRVolume.mhd"
    vol = vc.open(mhd)
    assert vol.source == str(mhd)
    nhdr = vc.open(data / "neghip" / "neghip.nhdr")
    assert nhdr.dims == (64, 64, 64) and nhdr.dtype == np.uint8
    assert vol.to_numpy().shape == vol.dims[::-1]
    out = tmp_path / "copy.nrrd"
    vol.save(out)
    again = vc.open(out)
    np.testing.assert_array_equal(again.to_numpy(), vol.to_numpy())
    assert again.spacing == pytest.approx(vol.spacing)
    # The file a volume came from is never overwritten.
    before = out.read_bytes()
    with pytest.raises(vc.VoxcastError):
        again.save(out)
    assert out.read_bytes() == before
    builtin = vc.open("builtin:demo")
    assert builtin.dims[0] > 1


def test_xarray_coordinates_give_spacing_origin_axes_name_and_units():
    xr = need("xarray")
    data = sphere(6)[:, :5, :4]  # z 6, y 5, x 4
    da = xr.DataArray(
        data,
        dims=("level", "lat", "lon"),
        coords={"level": 100.0 + 50.0 * np.arange(6), "lat": 10 + 0.25 * np.arange(5), "lon": -3 + 2.0 * np.arange(4)},
        name="QCLOUD",
        attrs={"units": "kg kg-1"},
    )
    vol = vc.Volume(da)
    assert vol.dims == (4, 5, 6)
    assert vol.spacing == pytest.approx((2.0, 0.25, 50.0))
    assert vol.origin == pytest.approx((-3.0, 10.0, 100.0))
    info = vol.info()
    assert info["name"] == "QCLOUD" and info["units"] == "kg kg-1"
    np.testing.assert_array_equal(vol.to_numpy(), data)
    # Dims in another order are found by name.
    t = da.transpose("lon", "level", "lat")
    np.testing.assert_array_equal(vc.Volume(t).to_numpy("zyx"), data)
    uneven = da.assign_coords(lat=[0, 1, 2, 4, 8])
    with pytest.raises(vc.VoxcastError, match="lat.*evenly spaced"):
        vc.Volume(uneven)


def test_volume_keeps_its_array_alive():
    a = sphere(8)
    expected = a.copy()
    vol = vc.Volume(a)
    del a
    import gc

    gc.collect()
    np.testing.assert_array_equal(vol.to_numpy(), expected)
