"""voxcast: volume rendering by ray casting, from Python.

    >>> import voxcast as vc
    >>> vol = vc.open("scan.nii.gz")                 # every format the CLI reads
    >>> vol = vc.Volume(array, spacing=(0.5, 0.5, 1.0))  # a NumPy array, no copy
    >>> img = vc.render(vol, tf="ct-bone", azimuth=30, elevation=20, size=(512, 512))
    >>> img.save("bone.png"); img.stats["samples"]

`render` returns an (H, W, 4) float32 array of linear RGBA (an `Image`, which
shows itself in Jupyter); `Scene` is the scene file of `voxcast render
--scene`, so a Python render and a CLI render of the same scene give the same
bytes. Errors are `VoxcastError`, naming the file and field at fault.
"""

from __future__ import annotations

import difflib
import json
import os
import shutil
import subprocess
import sys
import time
from typing import Any, Callable, Iterable, Optional, Sequence, Union

import numpy as np

from . import _voxcast as _native
from ._voxcast import VoxcastError, __version__

__all__ = [
    "Volume",
    "Scene",
    "Image",
    "TransferFunction",
    "BenchTable",
    "VoxcastError",
    "open",
    "render",
    "orbit",
    "bench",
    "presets",
    "methods",
    "__version__",
]

# ---------------------------------------------------------------------------
# Volumes


def _native_dtype(a: np.ndarray) -> np.ndarray:
    """The array in a type voxcast stores (u8, u16, i16, f32), unchanged when
    it already is one (native byte order); others are converted (a copy)."""
    kind, size = a.dtype.kind, a.dtype.itemsize
    if not a.dtype.isnative:
        a = a.astype(a.dtype.newbyteorder("="))
    if (kind, size) in (("u", 1), ("u", 2), ("i", 2), ("f", 4)):
        return a
    if kind == "b":
        return a.astype(np.uint8)
    if kind == "i" and size == 1:
        return a.astype(np.int16)
    if kind in "uif":
        return a.astype(np.float32)
    raise VoxcastError(
        f"array of {a.dtype}: expected numbers (uint8, uint16, int16 or float32 are read "
        "in place; other numeric types are converted to float32)"
    )


_AXIS_NAMES = {
    "x": ("x", "lon", "longitude", "west_east", "i", "col", "column", "width"),
    "y": ("y", "lat", "latitude", "south_north", "j", "row", "height"),
    "z": ("z", "level", "lev", "bottom_top", "depth", "k", "slice", "plane", "altitude", "pressure"),
}


def _axes_of_dataarray(da: Any, default: str) -> str:
    """The axes ('zyx', 'xyz', …) of an xarray DataArray from its dim names;
    `default` when they do not name x, y and z."""
    found = []
    for d in da.dims:
        name = str(d).lower()
        axis = next((a for a, names in _AXIS_NAMES.items() if name in names), None)
        found.append(axis)
    if sorted(a for a in found if a) == ["x", "y", "z"]:
        return "".join(found)
    return default


def _uniform_coordinate(values: np.ndarray, dim: str) -> tuple[float, float]:
    """(origin, spacing) of a 1-D coordinate, which must be evenly spaced."""
    v = np.asarray(values, dtype=np.float64)
    if v.size == 1:
        return float(v[0]), 1.0
    d = np.diff(v)
    step = float(d.mean())
    if step == 0 or not np.all(np.abs(d - step) <= 1e-3 * abs(step)):
        raise VoxcastError(
            f"coordinate {dim!r}: values are not evenly spaced (from {d.min():g} to {d.max():g}); "
            "voxcast renders regular grids — resample it (e.g. DataArray.interp) first"
        )
    if step < 0:
        raise VoxcastError(
            f"coordinate {dim!r}: values decrease; reverse that axis (da.isel({dim}=slice(None, None, -1)))"
        )
    return float(v[0]), step


class Volume:
    """A 3-D scalar field: voxels (u8, u16, i16 or f32), spacing and origin.

    ``Volume(array, spacing=(sx, sy, sz), origin=(ox, oy, oz), axes="zyx")``
    wraps a 3-D NumPy array. `axes` says which array axis is which: "zyx"
    (NumPy, scikit-image, napari, tifffile, SimpleITK's GetArrayFromImage)
    or "xyz" (nibabel, VTK, PyVista). Spacing and origin are always given in
    x, y, z order, as in the CLI and scene files. When x varies fastest in
    memory (a C-ordered "zyx" array, an F-ordered "xyz" one) and the type is
    u8, u16, i16 or f32, the voxels are read in place: no copy is made, and
    the array must not be changed while the volume is in use. Anything else
    is copied once into that layout.

    An ``xarray.DataArray`` gives its axes from its dim names (x/y/z,
    lon/lat/level, west_east/south_north/bottom_top …) and its spacing and
    origin from its (evenly spaced) coordinates; its name and `units`
    attribute travel with it.
    """

    def __init__(
        self,
        data: Any,
        spacing: Optional[Sequence[float]] = None,
        origin: Optional[Sequence[float]] = None,
        axes: str = "zyx",
        name: Optional[str] = None,
        units: Optional[str] = None,
    ):
        if isinstance(data, Volume):
            self._v, self._axes, self._in_place = data._v, data._axes, data._in_place
            return
        if hasattr(data, "dims") and hasattr(data, "coords") and hasattr(data, "values"):
            data, spacing, origin, axes, name, units = self._from_dataarray(
                data, spacing, origin, axes, name, units
            )
        axes = str(axes).lower()
        if sorted(axes) != ["x", "y", "z"]:
            raise VoxcastError(f"axes {axes!r}: expected an order of x, y and z such as 'zyx' or 'xyz'")
        a = np.asarray(data)
        if a.ndim != 3:
            raise VoxcastError(
                f"array of shape {a.shape}: expected a 3-D array (a 2-D image is a volume of "
                "one slice: use a[np.newaxis])"
            )
        given = a
        a = _native_dtype(a)
        # A view with z, y, x axes; x fastest in memory when the layout allows.
        zyx = a.transpose([axes.index(c) for c in "zyx"])
        if not (zyx.flags.c_contiguous and zyx.flags.aligned):
            zyx = np.ascontiguousarray(zyx)
        self._in_place = np.may_share_memory(zyx, given)
        nz, ny, nx = zyx.shape
        spacing = (1.0, 1.0, 1.0) if spacing is None else tuple(float(s) for s in spacing)
        origin = (0.0, 0.0, 0.0) if origin is None else tuple(float(o) for o in origin)
        if len(spacing) != 3 or len(origin) != 3:
            raise VoxcastError(f"spacing {spacing} and origin {origin}: expected three numbers each (x, y, z)")
        self._v = _native.from_array(zyx.reshape(-1), (nx, ny, nz), spacing, origin, name, units)
        self._axes = axes

    @staticmethod
    def _from_dataarray(da, spacing, origin, axes, name, units):
        axes = _axes_of_dataarray(da, axes)
        if spacing is None or origin is None:
            sp, org = {}, {}
            for dim, ax in zip(da.dims, axes):
                if dim in da.coords:
                    org[ax], sp[ax] = _uniform_coordinate(da.coords[dim].values, str(dim))
                else:
                    org[ax], sp[ax] = 0.0, 1.0
            spacing = spacing if spacing is not None else tuple(sp[c] for c in "xyz")
            origin = origin if origin is not None else tuple(org[c] for c in "xyz")
        name = name if name is not None else (None if da.name is None else str(da.name))
        units = units if units is not None else da.attrs.get("units")
        return np.asarray(da.data), spacing, origin, axes, name, units

    @classmethod
    def _wrap(cls, native: Any) -> "Volume":
        v = cls.__new__(cls)
        v._v = native
        v._axes = "zyx"
        v._in_place = False
        return v

    @property
    def dims(self) -> tuple[int, int, int]:
        """Grid size (x, y, z)."""
        return self._v.dims

    @property
    def shape(self) -> tuple[int, ...]:
        """The shape `to_numpy()` gives (in the volume's axes order)."""
        d = dict(zip("xyz", self.dims))
        return tuple(d[c] for c in self._axes)

    @property
    def spacing(self) -> tuple[float, float, float]:
        """Distance between voxel centres along x, y, z."""
        return self._v.spacing

    @property
    def origin(self) -> tuple[float, float, float]:
        """World position of the first voxel (x, y, z)."""
        return self._v.origin

    @property
    def dtype(self) -> np.dtype:
        return np.dtype({"u8": np.uint8, "u16": np.uint16, "i16": np.int16, "f32": np.float32}[self._v.dtype])

    @property
    def shares_memory(self) -> bool:
        """True when the voxels are read in place from the array the volume
        was made from (no copy was made)."""
        return self._in_place

    @property
    def source(self) -> Optional[str]:
        """The file or folder it was read from (None for an array)."""
        return self._v.source

    def info(self) -> dict:
        """Dims, spacing, origin, dtype, value range, units, name, variables, time, bytes."""
        d = json.loads(self._v.info_json())
        d["source"] = self.source
        d["shares_memory"] = self.shares_memory
        return d

    def to_numpy(self, axes: Optional[str] = None) -> np.ndarray:
        """The voxels as a read-only 3-D array viewing the volume's memory
        (no copy), in `axes` order (by default the order the volume was made
        with; "zyx" for a file)."""
        axes = (axes or self._axes).lower()
        if sorted(axes) != ["x", "y", "z"]:
            raise VoxcastError(f"axes {axes!r}: expected an order of x, y and z")
        nx, ny, nz = self.dims
        a = self._v.flat_view().reshape(nz, ny, nx)
        a = a.transpose(["zyx".index(c) for c in axes])
        a.flags.writeable = False
        return a

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        """`np.asarray(vol)`: `to_numpy()` (a copy only when asked for)."""
        a = self.to_numpy()
        if dtype is not None and np.dtype(dtype) != a.dtype:
            return a.astype(dtype)
        return np.array(a) if copy else a

    def save(self, path: Union[str, os.PathLike], gzip: bool = False) -> None:
        """Writes the volume as NRRD (atomically; never over the file it came from)."""
        self._v.save_nrrd(os.fspath(path), gzip)

    def __repr__(self) -> str:
        nx, ny, nz = self.dims
        where = f" from {self.source}" if self.source else (" (shares memory)" if self.shares_memory else "")
        sx, sy, sz = self.spacing
        return f"<voxcast.Volume {nx}×{ny}×{nz} {self._v.dtype}, spacing {sx:g}×{sy:g}×{sz:g}{where}>"


def open(path: Union[str, os.PathLike], **options: Any) -> Volume:
    """Reads a volume with voxcast's readers: NRRD, MetaImage, VTK, NIfTI,
    MGH, MINC, DICOM (files or a folder), image stacks, raw, OpenVDB, FDS,
    WRF; or ``builtin:NAME``.

    Options (as the CLI's flags): ``raw_dims=(x, y, z)``, ``raw_type`` ("u8",
    "u16", "i16", "f32"), ``raw_big_endian``, ``raw_header_bytes``,
    ``spacing=(x, y, z)``, ``variable`` (of a multi-variable file), ``time``
    (of a series).
    """
    return Volume._wrap(_native.open(os.fspath(path), **options))


# ---------------------------------------------------------------------------
# Transfer functions


class TransferFunction(dict):
    """A colour and opacity map over the normalised value (0 = low end of the
    window, 1 = high end), as a scene file's ``[transfer.map]``.

    ``TransferFunction(color=[(v, r, g, b), …], opacity=[(v, alpha), …],
    window=(lo, hi))``: colours in sRGB 0…1, opacity per voxel length.
    ``TransferFunction.from_colormap("magma", opacity=[(0, 0), (1, 0.3)])``
    samples a matplotlib colormap.
    """

    def __init__(
        self,
        color: Iterable[Sequence[float]],
        opacity: Iterable[Sequence[float]],
        window: Optional[Sequence[float]] = None,
    ):
        color = [[float(x) for x in c] for c in np.asarray(color, dtype=np.float64).reshape(-1, 4)]
        opacity = [[float(x) for x in o] for o in np.asarray(opacity, dtype=np.float64).reshape(-1, 2)]
        super().__init__(color=color, opacity=opacity)
        if window is not None:
            lo, hi = window
            self["window"] = [float(lo), float(hi)]

    @classmethod
    def from_colormap(
        cls,
        name: str,
        opacity: Iterable[Sequence[float]] = ((0.0, 0.0), (1.0, 0.3)),
        stops: int = 16,
        window: Optional[Sequence[float]] = None,
    ) -> "TransferFunction":
        """A map from a matplotlib colormap (needs matplotlib)."""
        try:
            import matplotlib
        except ImportError as e:
            raise VoxcastError(f"colormap {name!r}: matplotlib is not installed (pip install matplotlib)") from e
        try:
            cmap = matplotlib.colormaps[name]
        except KeyError:
            near = difflib.get_close_matches(name, list(matplotlib.colormaps), n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise VoxcastError(f"colormap {name!r}: not a matplotlib colormap{hint}") from None
        xs = np.linspace(0.0, 1.0, stops)
        color = [(x, *cmap(x)[:3]) for x in xs]
        return cls(color, opacity, window)


def presets() -> dict[str, str]:
    """The transfer-function presets, name → description."""
    return dict(_native.presets())


def methods() -> list[str]:
    """The sampling methods (append +grouped, +noskip as on the CLI)."""
    return list(_native.methods())


# ---------------------------------------------------------------------------
# Scenes

# Short keyword → the scene field it sets.
_FIELDS = {
    "azimuth": "camera.azimuth",
    "elevation": "camera.elevation",
    "zoom": "camera.zoom",
    "fov": "camera.fov",
    "projection": "camera.projection",
    "look_at": "camera.look_at",
    "width": "render.width",
    "height": "render.height",
    "step": "render.step",
    "ert": "render.ert",
    "order": "render.order",
    "optical": "render.optical",
    "shading": "render.shading",
    "background": "render.background",
    "seed": "render.seed",
    "grouped": "render.grouped",
    "skip_empty": "render.skip_empty",
    "jitter": "render.jitter",
    "block_size": "render.block_size",
    "spp": "render.spp",
    "simd": "render.simd",
    "window": "transfer.window",
    "input": "input.path",
}
_SPECIAL = ("size", "method", "tf")
_COLORS = {"black": [0.0, 0.0, 0.0], "white": [1.0, 1.0, 1.0]}


def _plain(value: Any) -> Any:
    """A value as JSON takes it (tuples, NumPy scalars and arrays)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


class Scene:
    """Everything a render depends on: the scene file of ``voxcast render
    --scene``. Fields are read and set by dotted key, with the file's names:
    ``scene["camera.azimuth"] = 30``, ``scene["render.adaptive.tolerance"]``.
    Keywords as `render` takes them (``Scene(tf="ct-bone", azimuth=30,
    size=(512, 512), method="adaptive+grouped")``) set the common ones.
    Every change is checked by the library's rules; a bad one raises
    `VoxcastError` and leaves the scene as it was.
    """

    def __init__(self, **settings: Any):
        self._s = _native._Scene()
        self.update(**settings)

    @classmethod
    def from_toml(cls, source: Union[str, os.PathLike]) -> "Scene":
        """A scene from a file (relative paths from its folder) or TOML text."""
        s = cls.__new__(cls)
        text = os.fspath(source)
        if os.path.isfile(text):
            s._s = _native._Scene.load(text)
        elif "\n" in text or "=" in text:
            s._s = _native._Scene.parse(text)
        else:
            raise VoxcastError(f"{text}: no such scene file")
        return s

    def to_toml(self, path: Optional[Union[str, os.PathLike]] = None) -> str:
        """The scene as TOML; with `path`, also written there (atomically,
        file paths relative to its folder)."""
        if path is None:
            return self._s.to_toml()
        self._s.save(os.fspath(path))
        return self._s.to_toml(os.fspath(path))

    def to_dict(self) -> dict:
        """Every field, defaults included."""
        return json.loads(self._s.to_json())

    def copy(self) -> "Scene":
        s = Scene.__new__(Scene)
        s._s = _native._Scene()
        s._s.set_json(self._s.to_json())
        return s

    def __getitem__(self, key: str) -> Any:
        node: Any = self.to_dict()
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                raise KeyError(key)
            node = node[part]
        return node

    def __setitem__(self, key: str, value: Any) -> None:
        self.set(**{key: value})

    def set(self, **fields: Any) -> "Scene":
        """Sets fields by dotted key (``scene.set(**{"render.step": 0.25})``),
        all at once: one bad value and none is set."""
        d = self.to_dict()
        for key, value in fields.items():
            parts = key.split(".")
            node = d
            for part in parts[:-1]:
                nxt = node.get(part)
                if nxt is None:
                    nxt = node[part] = {}
                elif not isinstance(nxt, dict):
                    raise VoxcastError(f"{key}: {part} is a value, not a table")
                node = nxt
            if value is None:
                node.pop(parts[-1], None)
            else:
                node[parts[-1]] = _plain(value)
        try:
            self._s.set_json(json.dumps(d))
        except VoxcastError as e:
            raise VoxcastError(f"{', '.join(fields)}: {e}") from None
        return self

    def update(self, **settings: Any) -> "Scene":
        """Sets fields by `render`'s keywords (see `render`)."""
        fields: dict[str, Any] = {}
        for key, value in settings.items():
            if key == "size":
                w, h = (value, value) if np.isscalar(value) else value
                fields["render.width"], fields["render.height"] = int(w), int(h)
            elif key == "method":
                self._s.set_method(str(value))
            elif key == "tf":
                if isinstance(value, dict):
                    fields["transfer.map"] = dict(value)
                    fields["transfer.tf"] = "auto"
                elif isinstance(value, str) and value not in presets() and value != "auto" \
                        and not os.path.exists(value) and _is_colormap(value):
                    fields["transfer.map"] = dict(TransferFunction.from_colormap(value))
                    fields["transfer.tf"] = "auto"
                else:
                    fields["transfer.tf"] = os.fspath(value)
                    fields["transfer.map"] = None
            elif key == "background" and isinstance(value, str):
                if value not in _COLORS:
                    raise VoxcastError(f"background {value!r}: expected 'black', 'white' or (r, g, b) in 0…1")
                fields["render.background"] = _COLORS[value]
            elif key in _FIELDS:
                fields[_FIELDS[key]] = value
            elif "." in key:
                fields[key] = value
            else:
                known = sorted(list(_FIELDS) + list(_SPECIAL))
                near = difflib.get_close_matches(key, known, n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                raise VoxcastError(
                    f"unknown setting {key!r}{hint}; known: {', '.join(known)}, "
                    "or a scene field by dotted key such as 'render.adaptive.tolerance'"
                )
        if fields:
            self.set(**fields)
        return self

    @property
    def method(self) -> str:
        return self._s.method_name()

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scene) and self._s == other._s

    def __repr__(self) -> str:
        return f"voxcast.Scene.from_toml('''\n{self.to_toml()}''')"


def _is_colormap(name: str) -> bool:
    try:
        import matplotlib
    except ImportError:
        return False
    return name in matplotlib.colormaps


# ---------------------------------------------------------------------------
# Images


class Image(np.ndarray):
    """A rendered image: an (H, W, 4) float32 array of linear RGBA (RGB
    composited over the background, A the volume's coverage), row 0 at the
    top. `stats` holds the render's statistics (rays, samples, seconds, …).
    In Jupyter it shows itself; `save` writes PNG (8-bit sRGB, the CLI's
    encoder) or EXR (linear float)."""

    stats: dict
    source: Optional[str]

    def __new__(cls, pixels: Any, stats: Optional[dict] = None, source: Optional[str] = None):
        obj = np.asarray(pixels, dtype=np.float32).view(cls)
        obj.stats = dict(stats or {})
        obj.source = source
        return obj

    def __array_finalize__(self, obj: Any) -> None:
        self.stats = getattr(obj, "stats", {})
        self.source = getattr(obj, "source", None)

    def _pixels(self) -> np.ndarray:
        a = np.ascontiguousarray(self, dtype=np.float32).view(np.ndarray)
        if a.ndim != 3 or a.shape[2] not in (3, 4):
            raise VoxcastError(f"image of shape {a.shape}: expected (height, width, 4)")
        return a

    def save(self, path: Union[str, os.PathLike]) -> None:
        """Writes .png (8-bit sRGB) or .exr (linear float RGBA), atomically;
        never over the volume's own file."""
        _native.write_image(self._pixels(), os.fspath(path), self.source)

    def to_srgb8(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB, the PNG's pixels."""
        a = self._pixels()
        return np.frombuffer(_native.srgb8(a), dtype=np.uint8).reshape(a.shape[0], a.shape[1], 3)

    def _repr_png_(self) -> Optional[bytes]:
        if self.ndim != 3 or self.shape[2] not in (3, 4) or self.size == 0:
            return None
        return bytes(_native.png_bytes(self._pixels()))


# ---------------------------------------------------------------------------
# Rendering


def _progress(progress: Any, what: str) -> tuple[Optional[Callable[[int, int], None]], Callable[[], None]]:
    """The callback for the native side and a function closing the bar.
    "auto": a tqdm bar (when tqdm is installed) shown once the work has
    lasted a second; a callable gets (done, total); False: nothing."""
    if callable(progress):
        return progress, lambda: None
    if progress is False or progress is None:
        return None, lambda: None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None, lambda: None
    start = time.monotonic()
    bar: list = []

    def cb(done: int, total: int) -> None:
        if not bar:
            if time.monotonic() - start < 1.0:
                return
            bar.append(tqdm(total=total, desc=what, unit="tile", leave=False))
        b = bar[0]
        b.total = total
        b.n = done
        b.refresh()

    def close() -> None:
        if bar:
            bar[0].close()

    return cb, close


def _scene_and_volume(volume: Any, scene: Optional[Scene], settings: dict) -> tuple[Scene, Optional[Volume]]:
    """The scene to render and the in-memory volume (None: the scene's input)."""
    if scene is None:
        s = Scene()
        if volume is None and "input" not in settings:
            # The demo in its own three-quarter view, as `voxcast render`.
            s.update(azimuth=30.0, elevation=20.0, zoom=1.6)
    else:
        s = scene.copy()
    vol: Optional[Volume] = None
    if isinstance(volume, (str, os.PathLike)):
        s.update(input=os.fspath(volume))
    elif volume is not None:
        vol = volume if isinstance(volume, Volume) else Volume(volume)
    s.update(**settings)
    return s, vol


def render(
    volume: Any = None,
    scene: Optional[Scene] = None,
    *,
    device: str = "cpu",
    progress: Any = "auto",
    **settings: Any,
) -> Image:
    """Renders a volume; returns an `Image` ((H, W, 4) float32 linear RGBA
    with `.stats`).

    `volume`: a `Volume`, a NumPy array or xarray DataArray (made a `Volume`
    as ``Volume(a)`` does), a file path, or None for the scene's input (the
    built-in demo by default). `scene`: a `Scene` to start from. `device`:
    "cpu", "gpu" (wgpu on any Vulkan adapter) or "auto". `progress`: "auto"
    (a tqdm bar on renders over a second), False, or a callable(done, total).

    Settings (each also a `Scene` keyword): ``tf`` (a preset name — see
    `presets()` —, "auto", a TF file, a `TransferFunction` or a matplotlib
    colormap name), ``window=(lo, hi)``, ``azimuth``, ``elevation``,
    ``zoom``, ``fov``, ``projection`` ("perspective"/"orthographic"),
    ``size=(width, height)``, ``method`` ("uniform", "adaptive+grouped", …,
    see `methods()`), ``step``, ``ert``, ``shading``, ``background``,
    ``jitter``, ``spp``, ``seed``; or any scene field by dotted key
    (``**{"render.adaptive.tolerance": 0.1}``).

    The GIL is released while rendering; Ctrl-C stops the render and raises
    KeyboardInterrupt.
    """
    s, vol = _scene_and_volume(volume, scene, settings)
    cb, close = _progress(progress, "rendering")
    try:
        pixels, stats, _device, note = _native.render(s._s, None if vol is None else vol._v, device, cb)
    finally:
        close()
    if note and device != "cpu":
        print(note, file=sys.stderr)
    source = vol.source if vol is not None else s["input.path"]
    return Image(pixels, json.loads(stats), source)


def orbit(
    volume: Any = None,
    scene: Optional[Scene] = None,
    *,
    frames: int = 36,
    path: Optional[Union[str, os.PathLike]] = None,
    fps: float = 12.0,
    device: str = "cpu",
    progress: Any = "auto",
    **settings: Any,
) -> list[Image]:
    """Renders `frames` views orbiting the volume (azimuth from the scene's
    over a full turn) and returns them; with `path`, also writes a looping
    .gif, or an .mp4 through ffmpeg, as `voxcast animate` does."""
    if frames < 1:
        raise VoxcastError(f"frames {frames}: expected at least 1")
    ext = "" if path is None else os.path.splitext(os.fspath(path))[1].lower()
    if path is not None and ext not in (".gif", ".mp4"):
        raise VoxcastError(f"{os.fspath(path)}: expected a .gif or .mp4 path")
    if ext == ".mp4" and shutil.which("ffmpeg") is None:
        raise VoxcastError("ffmpeg is not on PATH: MP4 needs it (write a .gif instead); nothing was written")
    s, vol = _scene_and_volume(volume, scene, settings)
    a0 = float(s["camera.azimuth"])
    bar_cb, close = _progress(progress, "orbit")
    out: list[Image] = []
    try:
        for i in range(frames):
            s.update(azimuth=(a0 + 360.0 * i / frames) % 360.0)
            out.append(render(vol, s, device=device, progress=False))
            if bar_cb is not None:
                bar_cb(i + 1, frames)
    finally:
        close()
    if path is not None:
        src = vol.source if vol is not None else s["input.path"]
        if ext == ".gif":
            _native.write_gif([f._pixels() for f in out], os.fspath(path), fps, src)
        else:
            _write_mp4(out, os.fspath(path), fps)
    return out


def _write_mp4(frames: list, path: str, fps: float) -> None:
    """Pipes the frames to ffmpeg (libx264, yuv420p) as `voxcast animate`."""
    h, w = frames[0].shape[:2]
    tmp = os.path.join(os.path.dirname(os.path.abspath(path)), f".{os.path.basename(path)}.part")
    cmd = ["ffmpeg", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24",
           "-s", f"{w}x{h}", "-r", f"{fps}", "-i", "-", "-an", "-c:v", "libx264",
           "-pix_fmt", "yuv420p", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-f", "mp4", tmp]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE)
    try:
        assert proc.stdin is not None
        for f in frames:
            proc.stdin.write(f.to_srgb8().tobytes())
        proc.stdin.close()
        if proc.wait() != 0:
            raise VoxcastError(f"ffmpeg failed (exit {proc.returncode}); nothing was written")
        os.replace(tmp, path)
    finally:
        if proc.poll() is None:
            proc.kill()
        if os.path.exists(tmp):
            os.remove(tmp)


# ---------------------------------------------------------------------------
# Benchmarks


class BenchTable(list):
    """The bench's rows (one dict per method: name, seconds, samples, PSNR,
    SSIM, speed-up…); `.report` is the whole report (scene, machine,
    reference, notes) as `voxcast bench --json` writes it; printing it gives
    the CLI's table."""

    report: dict
    table: str

    def __str__(self) -> str:
        return self.table

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:
        p.text(self.table)


def bench(
    volume: Any = None,
    scene: Optional[Scene] = None,
    *,
    methods: Optional[Union[str, Sequence[str]]] = None,
    repeat: int = 5,
    warmup: int = 1,
    quality: Optional[float] = None,
    cache: bool = True,
    progress: Any = "auto",
    **settings: Any,
) -> BenchTable:
    """Times sampling methods on the CPU against a converged reference, as
    `voxcast bench` does: time, samples, PSNR and SSIM, speed-up over
    `uniform`. `quality=DB` first picks each method's setting for that PSNR
    so they are compared at equal quality. Returns a `BenchTable`."""
    s, vol = _scene_and_volume(volume, scene, settings)
    if methods is not None and not isinstance(methods, str):
        methods = ",".join(methods)
    cb, close = _progress(progress, "bench")
    try:
        report, table = _native.bench(
            s._s, None if vol is None else vol._v, methods, repeat, warmup, quality, cache, cb
        )
    finally:
        close()
    out = BenchTable(json.loads(report)["methods"])
    out.report = json.loads(report)
    out.table = table
    return out
