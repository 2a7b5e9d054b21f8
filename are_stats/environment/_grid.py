"""The 2D occupancy grid M_2D (paper Sect. 3.1) with ROS ``map_server`` IO and inflation.

Cell values follow ``nav_msgs/OccupancyGrid``: ``0`` free, ``100`` occupied, ``-1`` unknown,
``1..99`` intermediate occupancy (``scale`` mode). ``data[i, j]`` is the cell in row ``i``
(along the map's local y axis) and column ``j`` (along its local x axis); row 0 is the row
at the origin, i.e. the *bottom* of the map image. The origin ``(x, y, yaw)`` is the pose of
the lower-left corner of cell ``(0, 0)`` in the environment frame F_E.

Reading follows ROS 2 Nav2's ``map_server`` (``loadMapFromFile`` in ``map_io.cpp``) bit
for bit: GraphicsMagick 16-bit quanta, doubles, strict thresholds, ``rint(100 * ratio)`` in
``scale`` mode, ``-1`` above 100 in ``raw`` mode (see :meth:`OccupancyGrid.from_ros_yaml`).
Writing follows ``map_saver`` (free 254, occupied 0, unknown 205 for ``trinary``).
"""

from __future__ import annotations

import math
import os
import struct
import threading
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
import yaml
from PIL import Image, UnidentifiedImageError

from are_stats import inputs
from are_stats._atomic import atomic_path, check_writable
from are_stats._checks import check_finite, check_in, describe
from are_stats.environment._shipped import resolve_shipped
from are_stats.inputs import Described, InputError, Source

# Pillow's Image is imported at the top (about 15 ms of import CPU).

__all__ = [
    "OccupancyGrid",
    "read_map",
    "FREE",
    "OCCUPIED",
    "UNKNOWN",
    "MIN_RESOLUTION",
    "MAX_RESOLUTION",
    "MAX_ORIGIN",
]

FREE = 0
OCCUPIED = 100
UNKNOWN = -1
_MODES = ("trinary", "scale", "raw")
#: Smallest and largest map resolution accepted (metres per cell).
MIN_RESOLUTION = 1e-6
MAX_RESOLUTION = 1e4
#: Largest ``|x|``, ``|y|`` of a map origin accepted (metres).
MAX_ORIGIN = 1e7
_MAP_KEYS = (
    "image",
    "resolution",
    "origin",
    "negate",
    "occupied_thresh",
    "free_thresh",
    "mode",
    "width",
    "height",
)


#: GraphicsMagick (Q16, as Nav2 links it) stores an 8-bit sample ``v`` as ``257 v``
#: out of ``65535``.
_QUANTUM_PER_LEVEL = 257.0
_MAX_RGB = 65535.0


def _read_table(mode: str, negate: bool, occ_th: float, free_th: float) -> np.ndarray:
    """Cell value of each opaque grey level 0..255, as Nav2's map_server reads it."""
    grey = np.arange(256, dtype=float)
    shade = _shade(3.0 * _QUANTUM_PER_LEVEL * grey, 3)
    return _shade_to_values(shade, np.ones(256, bool), mode, negate, occ_th, free_th)


def _shade(quantum_sum: np.ndarray, n_channels: int) -> np.ndarray:
    """``scaleQuantumToDouble(sum / channels.size())``: the brightness in ``[0, 1]``."""
    return (quantum_sum / float(n_channels)) / _MAX_RGB


def _round_half_away(x: np.ndarray) -> np.ndarray:
    """``std::round`` of non-negative doubles (halves away from zero, no ``x + 0.5`` error)."""
    t = np.trunc(x)
    return t + ((x - t) >= 0.5)


def _shade_to_values(
    shade: np.ndarray,
    opaque: np.ndarray,
    mode: str,
    negate: bool,
    occ_th: float,
    free_th: float,
) -> np.ndarray:
    """Cell values from pixel brightness, line for line as Nav2's ``loadMapFromFile``.

    ``opaque`` is whether the pixel's alpha is 255 (always true for images without alpha);
    only ``scale`` mode looks at it.
    """
    if mode == "raw":
        pct = _round_half_away(shade * 255)
        ok = (pct >= FREE) & (pct <= OCCUPIED)
        return np.where(ok, pct, UNKNOWN).astype(np.int8)
    occ = shade if negate else 1.0 - shade
    out = np.full(shade.shape, UNKNOWN, dtype=np.int8)
    if mode == "scale":
        between = (occ >= free_th) & (occ <= occ_th)
        mid = np.rint((occ[between] - free_th) / (occ_th - free_th) * 100.0)
        out[between] = mid.astype(np.int8)
    out[occ < free_th] = FREE
    out[occ_th < occ] = OCCUPIED
    if mode == "scale":
        out[~opaque] = UNKNOWN
    return out


class OccupancyGrid:
    """Occupancy grid M_2D: a ``(height, width)`` int8 array with resolution and origin.

    Parameters
    ----------
    data : (height, width) int
        Cell values: ``0`` free, ``100`` occupied, ``-1`` unknown, ``1..99`` intermediate
        (the only values Nav2's map_server produces, in every mode). Row 0 is the bottom row
        (at the origin), as in ``nav_msgs/OccupancyGrid``.
    resolution : float
        Cell side in metres.
    origin : (3,) float
        Pose ``(x, y, yaw)`` of the lower-left corner of cell ``(0, 0)`` in F_E.
    negate, occupied_thresh, free_thresh, mode
        The ``map_server`` metadata, kept for writing the map back.
    source : str, optional
        The file the map was read from (:meth:`from_ros_yaml` sets it), named by the
        errors of those that use the grid (a map that is not the fit's); a copy keeps it,
        a grid built in memory has none.

    Notes
    -----
    The toolkit reads the values the same way whichever ``mode`` produced them:
    :attr:`free` is exactly ``0`` and :attr:`occupied` exactly ``100`` (so a ``scale``
    pixel whose occupancy equals ``occupied_thresh``, which Nav2 reads as ``rint(100) =
    100``, is an occupied cell, and one at ``free_thresh`` a free cell); :attr:`unknown` is
    everything else, ``-1`` and the intermediate ``1..99``. Only free cells count towards
    :attr:`free_area`, and only occupied cells become walls (:func:`extrude_grid`).

    Examples
    --------
    >>> g = OccupancyGrid(np.zeros((4, 5)), 0.5)
    >>> g.free_area
    5.0
    >>> g.world_to_cell([1.2, 0.3]).tolist()
    [0, 2]
    """

    def __init__(
        self,
        data: npt.ArrayLike,
        resolution: float,
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        *,
        negate: bool = False,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.196,
        mode: str = "trinary",
        source: str | os.PathLike | None = None,
    ) -> None:
        a = check_finite("data", data, ndim=2)
        if a.shape[0] == 0 or a.shape[1] == 0:
            raise ValueError(f"data: expected a non-empty 2-d array, got shape {a.shape}")
        if ((a < -1) | (a > 100) | (a != np.round(a))).any():
            raise ValueError(
                f"data: expected integers in -1..100 (mode {mode!r}), got {describe(a)}"
            )
        self.data = np.round(a).astype(np.int64).astype(np.int8)
        o = np.asarray(origin).tolist() if isinstance(origin, np.ndarray) else origin
        self.resolution, self.origin = _check_geometry(
            resolution.item() if isinstance(resolution, np.ndarray) else resolution,
            o,
            "OccupancyGrid",
        )
        self.mode = check_in("mode", mode, _MODES)
        self.negate = bool(negate)
        _check_thresholds(occupied_thresh, free_thresh, "OccupancyGrid")
        self.occupied_thresh = float(occupied_thresh)
        self.free_thresh = float(free_thresh)
        self.source = None if source is None else str(source)

    # ------------------------------------------------------------------ basic views
    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)`` in cells."""
        return self.data.shape  # type: ignore[return-value]

    @property
    def height(self) -> int:
        """Number of rows."""
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        """Number of columns."""
        return int(self.data.shape[1])

    @property
    def free(self) -> np.ndarray:
        """``(height, width)`` bool: free cells (value 0)."""
        return self.data == FREE

    @property
    def occupied(self) -> np.ndarray:
        """``(height, width)`` bool: occupied cells (value 100)."""
        return self.data == OCCUPIED

    @property
    def unknown(self) -> np.ndarray:
        """``(height, width)`` bool: neither free nor occupied (-1 or intermediate 1..99)."""
        return (self.data != FREE) & (self.data != OCCUPIED)

    @property
    def n_free(self) -> int:
        """Number of free cells."""
        return int(np.count_nonzero(self.data == FREE))

    @property
    def free_area(self) -> float:
        """nu(M_2D) in m^2: free cells times resolution^2; unknown is not free (DECISIONS 4)."""
        return self.n_free * self.resolution**2

    def copy(self) -> OccupancyGrid:
        """A deep copy (same metadata)."""
        out = OccupancyGrid.__new__(OccupancyGrid)
        out.__dict__.update(self.__dict__)
        out.data = self.data.copy()
        return out

    def __repr__(self) -> str:
        return (
            f"OccupancyGrid({self.height}x{self.width}, resolution={self.resolution}, "
            f"origin={self.origin}, free_area={self.free_area:.2f} m^2)"
        )

    # ------------------------------------------------------------------ transforms
    def world_to_local(self, xy: npt.ArrayLike) -> np.ndarray:
        """Continuous grid coordinates ``(u, v)`` in cell units of world points.

        Parameters
        ----------
        xy : (..., 2) float
            Points in F_E.

        Returns
        -------
        (..., 2) float
            ``u`` along columns, ``v`` along rows; cell ``(i, j)`` covers
            ``[j, j + 1] x [i, i + 1]``.
        """
        p = check_finite("xy", xy)
        if p.ndim == 0 or p.shape[-1] != 2:
            raise ValueError(f"xy: expected points of shape (..., 2), got shape {p.shape}")
        x0, y0, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = p[..., 0] - x0, p[..., 1] - y0
        return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1) / self.resolution

    def local_to_world(self, uv: npt.ArrayLike) -> np.ndarray:
        """Inverse of :meth:`world_to_local`: ``(..., 2)`` cell units to F_E points."""
        q = check_finite("uv", uv) * self.resolution
        x0, y0, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        return np.stack(
            [x0 + c * q[..., 0] - s * q[..., 1], y0 + s * q[..., 0] + c * q[..., 1]], axis=-1
        )

    def world_to_cell(self, xy: npt.ArrayLike) -> np.ndarray:
        """Cells ``(i, j)`` ``(..., 2) int64`` of world points ``xy (..., 2)`` in F_E (origin
        yaw respected): ``data[i, j]`` holds the point; not bounds-checked (see
        :meth:`in_bounds`)."""
        uv = np.floor(self.world_to_local(xy)).astype(np.int64)
        return uv[..., ::-1].copy()

    def cell_to_world(self, ij: npt.ArrayLike) -> np.ndarray:
        """World coordinates ``(..., 2)`` of the centres of cells ``ij = (row, col)``."""
        a = check_finite("ij", ij)
        if a.ndim == 0 or a.shape[-1] != 2:
            raise ValueError(f"ij: expected cells of shape (..., 2), got shape {a.shape}")
        return self.local_to_world(a[..., ::-1] + 0.5)

    def in_bounds(self, ij: npt.ArrayLike) -> np.ndarray:
        """``(...)`` bool: whether cells ``(row, col)`` lie inside the grid."""
        a = np.asarray(ij)
        return (
            (a[..., 0] >= 0)
            & (a[..., 0] < self.height)
            & (a[..., 1] >= 0)
            & (a[..., 1] < self.width)
        )

    @property
    def corners_world(self) -> np.ndarray:
        """``(4, 2)`` world coordinates of the map's corners (counter-clockwise)."""
        w, h = self.width, self.height
        return self.local_to_world(np.array([[0, 0], [w, 0], [w, h], [0, h]], float))

    # ------------------------------------------------------------------ inflation
    def distance_to_occupied(self) -> np.ndarray:
        """``(height, width)`` Euclidean distance (m) from each cell centre to the nearest
        occupied cell centre (0 on occupied cells, +inf when nothing is occupied)."""
        # lazy: SciPy's ndimage adds 0.34 s CPU to `import are_stats.environment`
        from scipy import ndimage

        occ = self.occupied
        if not occ.any():
            return np.full(self.shape, np.inf)
        return ndimage.distance_transform_edt(~occ) * self.resolution

    def inflate(self, radius: float) -> np.ndarray:
        """``(height, width)`` bool: cells within ``radius`` metres of an occupied cell."""
        r = float(check_finite("radius", radius))
        if r < 0:
            raise ValueError(f"radius: expected a number >= 0, got {r!r}")
        return self.distance_to_occupied() <= r

    def inflation_costmap(
        self,
        inscribed_radius: float,
        inflation_radius: float,
        cost_scaling_factor: float = 10.0,
        track_unknown: bool = False,
    ) -> np.ndarray:
        """costmap_2d's inflation layer: ``(height, width)`` uint8 costs.

        ``254`` on occupied cells, ``253`` within ``inscribed_radius``,
        ``252 * exp(-cost_scaling_factor * (d - inscribed_radius))`` up to
        ``inflation_radius``, else ``0``; unknown cells are ``255`` when ``track_unknown``.
        """
        ri = float(check_finite("inscribed_radius", inscribed_radius))
        ro = float(check_finite("inflation_radius", inflation_radius))
        k = float(check_finite("cost_scaling_factor", cost_scaling_factor))
        if ri < 0 or ro < ri:
            raise ValueError(
                "inflation_radius: expected 0 <= inscribed_radius <= inflation_radius, "
                f"got {ri!r} and {ro!r}"
            )
        d = self.distance_to_occupied()
        cost = np.zeros(self.shape, dtype=np.uint8)
        band = (d > ri) & (d <= ro)
        cost[band] = (252.0 * np.exp(-k * (d[band] - ri))).astype(np.uint8)
        cost[(d <= ri)] = 253
        cost[self.occupied] = 254
        if track_unknown:
            cost[self.data == UNKNOWN] = 255
        return cost

    # ------------------------------------------------------------------ ROS IO
    @classmethod
    def from_ros_yaml(cls, path: str | os.PathLike) -> OccupancyGrid:
        """Read a ROS ``map_server`` map (YAML + PGM/PNG image).

        Parameters
        ----------
        path : str or PathLike
            The map YAML: ``image``, ``resolution`` and ``origin`` required; ``negate``
            (0/1), ``occupied_thresh``, ``free_thresh``, ``mode`` and the (checked)
            ``width``/``height`` optional; any other key is an error. Numbers must be
            numbers (no booleans or strings); ``resolution`` lies in
            ``[MIN_RESOLUTION, MAX_RESOLUTION]`` metres, the origin's ``x, y`` within
            ``MAX_ORIGIN`` metres of zero and its yaw within ``[-2 pi, 2 pi]``.

        Returns
        -------
        OccupancyGrid

        Raises
        ------
        FileNotFoundError
            If the YAML does not exist.
        are_stats.inputs.InputError
            (a ``ValueError``) if a field is missing, unknown or malformed, the image is
            missing or cannot be decoded, or it is larger than the memory limit allows
            (:class:`are_stats.inputs.LimitError`, checked from its header before any
            pixel is read).

        Notes
        -----
        Pixels become cells as in Nav2's ``loadMapFromFile`` (``nav2_map_server/src/
        map_io.cpp``), in doubles: ``shade`` is the mean of the red, green and blue quanta
        (plus ``alpha`` in ``trinary`` mode when the image has an alpha channel) over
        ``65535``, with an 8-bit sample ``v`` as the quantum ``257 v``; ``occ = 1 - shade``,
        or ``shade`` with ``negate``.

        - ``trinary``: ``occupied_thresh < occ`` gives ``100``, ``occ < free_thresh``
          ``0``, anything else ``-1``.
        - ``scale``: a pixel whose alpha is not 255 gives ``-1``; else as ``trinary``, but
          in between ``rint((occ - free_thresh) / (occupied_thresh - free_thresh) * 100)``
          (halves to even), so a speed mask with ``free_thresh: 0``, ``occupied_thresh: 1``
          reads grey ``204`` as ``20`` and black as ``100``.
        - ``raw``: ``round(255 shade)`` (halves away from zero) if it lies in ``0..100``,
          else ``-1``; ``negate`` and alpha are ignored.

        A tRNS chunk counts as an alpha channel, palettes are looked up, and ``1``-bit,
        CMYK and YCbCr images are read as their RGB.
        """
        p = Path(path)
        meta = inputs.check_keys(
            inputs.load_yaml(p, "ROS map YAML"), p, "", _MAP_KEYS, ("image", "resolution", "origin")
        )
        image = inputs.get_str(meta["image"], p, "image")
        if not image.strip():
            raise InputError(p, "image", "an image file name", image)
        res, origin = _check_geometry(meta["resolution"], meta["origin"], p)
        negate = meta.get("negate", 0)
        if not (isinstance(negate, bool) or (type(negate) is int and negate in (0, 1))):
            raise InputError(p, "negate", "0 or 1", negate)
        occ_th = inputs.get_float(
            meta.get("occupied_thresh", 0.65), p, "occupied_thresh", lo=0, hi=1
        )
        free_th = inputs.get_float(meta.get("free_thresh", 0.196), p, "free_thresh", lo=0, hi=1)
        _check_thresholds(occ_th, free_th, str(p))
        mode = inputs.get_str(meta.get("mode", "trinary"), p, "mode", choices=_MODES)
        sizes = {k: inputs.get_int(meta[k], p, k, lo=1) for k in ("width", "height") if k in meta}
        img_path = Path(image)
        if not img_path.is_absolute():
            img_path = p.parent / img_path
        data = _read_image(img_path, mode, bool(negate), occ_th, free_th, p)
        for key, n in (("width", data.shape[1]), ("height", data.shape[0])):
            if key in sizes and sizes[key] != n:
                raise InputError(
                    p, key, f"the image's {key} ({n} pixels of {img_path.name})", sizes[key]
                )
        grid = cls.__new__(cls)
        grid.data = data
        grid.resolution = res
        grid.origin = origin
        grid.negate = bool(negate)
        grid.occupied_thresh = occ_th
        grid.free_thresh = free_th
        grid.mode = mode
        grid.source = str(p)
        return grid

    def to_ros_yaml(
        self,
        path: str | os.PathLike,
        image: str | None = None,
        force: bool = False,
    ) -> Path:
        """Write the map as ROS ``map_saver`` does: a YAML and an image beside it.

        Parameters
        ----------
        path : str or PathLike
            The YAML to write.
        image : str, optional
            Image file name (relative to the YAML folder); default ``<stem>.pgm``
            (``<stem>.png`` in ``scale`` mode, whose unknown cells need an alpha channel).
        force : bool
            Overwrite existing files.

        Returns
        -------
        Path
            The YAML path. The image is written with ``negate: 0``; the pixel of each value
            is chosen so that reading it back with the grid's thresholds and mode returns the
            same value (map_saver's 254 / 0 / 205 for ``trinary``).
        """
        yp = Path(path)
        if image is None:
            image = yp.stem + (".png" if self.mode == "scale" else ".pgm")
        ip = yp.parent / image
        check_writable(yp, force)
        check_writable(ip, force)
        pixels, alpha = self._pixels_for_values()
        img = pixels[::-1]  # image row 0 is the top of the map
        fmt = "PNG" if ip.suffix.lower() == ".png" else "PPM"
        if ip.suffix.lower() not in (".png", ".pgm"):
            raise ValueError(f"image: expected a .pgm or .png file name, got {image!r}")
        if alpha is not None:
            if fmt != "PNG":
                raise ValueError(
                    "image: scale-mode maps with unknown cells need a .png (alpha channel), "
                    f"got {image!r}"
                )
            pil = Image.fromarray(np.stack([img, alpha[::-1]], axis=-1), mode="LA")
        else:
            pil = Image.fromarray(img, mode="L")
        with atomic_path(ip, force=force) as tmp:
            pil.save(tmp, format=fmt)
        meta = {
            "image": image,
            "mode": self.mode,
            "resolution": self.resolution,
            "origin": [float(v) for v in self.origin],
            "negate": 0,
            "occupied_thresh": self.occupied_thresh,
            "free_thresh": self.free_thresh,
        }
        with atomic_path(yp, force=force) as tmp:
            tmp.write_text(yaml.safe_dump(meta, sort_keys=False, default_flow_style=None))
        return yp

    def _pixels_for_values(self) -> tuple[np.ndarray, np.ndarray | None]:
        table = _read_table(self.mode, False, self.occupied_thresh, self.free_thresh)
        values = np.unique(self.data)
        preferred = {FREE: 254, OCCUPIED: 0, UNKNOWN: 205}
        lut = np.zeros(256, dtype=np.uint8)
        need_alpha = False
        for v in values.tolist():
            pref = preferred.get(v)
            if self.mode == "raw":
                lut[v % 256] = v % 256
                continue
            if pref is not None and table[pref] == v:
                lut[v % 256] = pref
                continue
            hits = np.flatnonzero(table == v)
            if hits.size:
                lut[v % 256] = hits[len(hits) // 2]
            elif v == UNKNOWN and self.mode == "scale":
                need_alpha = True
                lut[v % 256] = 205
            else:
                # nearest representable intermediate value (8-bit images cannot hold all 99)
                cand = np.flatnonzero((table > 0) & (table < 100))
                if cand.size == 0:
                    raise ValueError(
                        f"data: no 8-bit pixel reads back as {v} in mode {self.mode!r} with "
                        f"occupied_thresh={self.occupied_thresh!r}, "
                        f"free_thresh={self.free_thresh!r}"
                    )
                k = cand[np.argmin(np.abs(table[cand].astype(int) - v))]
                lut[v % 256] = k
        pixels = lut[self.data.view(np.uint8)]
        alpha = None
        if need_alpha:
            alpha = np.where(self.data == UNKNOWN, 0, 255).astype(np.uint8)
        return pixels, alpha


def read_map(
    name_or_path: str | os.PathLike, *, source: str = "--map"
) -> tuple[Path, OccupancyGrid]:
    """A map where a command or config takes one: a ROS map YAML, or the name of a shipped
    map (``courtyard``; :func:`~are_stats.environment.resolve_shipped`), read by
    :meth:`OccupancyGrid.from_ros_yaml`.

    Parameters
    ----------
    name_or_path : str or PathLike
        A map YAML (an existing file wins) or a shipped map's name.
    source : str
        The option or key it came from, named when it is neither (``"--map"``).

    Returns
    -------
    path : Path
        The map YAML read.
    grid : OccupancyGrid

    Raises
    ------
    are_stats.inputs.InputError
        Naming ``source`` and the shipped maps when ``name_or_path`` is neither a file nor
        a shipped map's name; the errors of :meth:`OccupancyGrid.from_ros_yaml`.

    Examples
    --------
    >>> path, grid = read_map("courtyard")
    >>> path.name, grid.resolution
    ('courtyard.yaml', 0.1)
    """
    path = resolve_shipped(name_or_path, "map", source=source)
    return path, OccupancyGrid.from_ros_yaml(path)


def _check_geometry(resolution: object, origin: object, source: Source) -> tuple[float, tuple]:
    """Resolution and origin of a map, checked strictly (see :meth:`from_ros_yaml`)."""
    res = inputs.get_float(resolution, source, "resolution", lo=MIN_RESOLUTION, hi=MAX_RESOLUTION)
    o = inputs.get_list(origin, source, "origin", min_len=3, max_len=3)
    x, y = (
        inputs.get_float(v, source, f"origin[{k}]", lo=-MAX_ORIGIN, hi=MAX_ORIGIN)
        for k, v in enumerate(o[:2])
    )
    yaw = inputs.get_float(o[2], source, "origin[2] (yaw)", lo=-2 * math.pi, hi=2 * math.pi)
    return res, (x, y, yaw)


def _check_thresholds(occ_th: float, free_th: float, where: str) -> None:
    if not (0.0 <= free_th < occ_th <= 1.0):
        raise ValueError(
            f"{where}: expected 0 <= free_thresh < occupied_thresh <= 1, got "
            f"free_thresh={free_th!r}, occupied_thresh={occ_th!r}"
        )


_IMAGE_LOCK = threading.Lock()
# Pillow modes decoded as map_server does; 16-bit and float images are refused (Pillow
# would clip them to 8 bits and turn every grey above 255 white, i.e. free).
_IMAGE_MODES = ("1", "L", "LA", "La", "P", "PA", "RGB", "RGBA", "RGBa", "RGBX", "CMYK", "YCbCr")
# What other Pillow modes are decoded as: the red, green and blue (and alpha) GraphicsMagick's
# pixelColor would give (a palette is looked up; a grey is equal red, green and blue).
_CONVERT = {
    "1": "L",
    "La": "LA",
    "P": "RGB",
    "PA": "RGBA",
    "RGBa": "RGBA",
    "RGBX": "RGB",
    "CMYK": "RGB",
    "YCbCr": "RGB",
}
# Bytes per pixel while decoding: up to 4 8-bit channels, their float copy (3 x 8), the
# quanta, alpha, shade, occupancy, ratio and temporaries (6 x 8), masks and int8 results.
_BYTES_PER_PIXEL = 4 + 8 * 3 + 8 * 6 + 6


def _open_image(path: Path, source: Path) -> Image.Image:
    """Open the image lazily (header only), without Pillow's decompression-bomb refusal:
    the size is checked against :func:`are_stats.inputs.memory_limit` instead."""
    with _IMAGE_LOCK:
        old = Image.MAX_IMAGE_PIXELS
        Image.MAX_IMAGE_PIXELS = None
        try:
            return Image.open(path)
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError, EOFError) as err:
            raise InputError(
                source,
                "image",
                "a PGM or PNG image",
                Described(f"{path}: {err or type(err).__name__}"),
            ) from None
        finally:
            Image.MAX_IMAGE_PIXELS = old


def _read_image(
    path: Path,
    mode: str,
    negate: bool,
    occ_th: float,
    free_th: float,
    source: Path | None = None,
) -> np.ndarray:
    src = path if source is None else source
    if not path.exists():
        raise InputError(src, "image", "an existing image file", Described(f"{path}: no such file"))
    if not path.is_file():
        raise InputError(src, "image", "an image file", Described(f"{path}: not a file"))
    im = _open_image(path, src)
    try:
        width, height = im.size
        if width <= 0 or height <= 0:
            raise InputError(src, "image", "a non-empty image", Described(f"{width} x {height}"))
        if im.mode not in _IMAGE_MODES:
            raise InputError(
                src,
                "image",
                "an 8-bit greyscale or colour image (as map_server reads)",
                Described(f"{path.name} in Pillow mode {im.mode!r}"),
            )
        inputs.check_memory(
            float(width) * float(height) * _BYTES_PER_PIXEL,
            f"the {width} x {height} map image {path.name}",
            src,
        )
        try:
            im.load()
            if "transparency" in im.info and im.mode in ("L", "P", "RGB"):
                im = im.convert("LA" if im.mode == "L" else "RGBA")  # tRNS: alpha, as Magick
            elif im.mode in _CONVERT:
                im = im.convert(_CONVERT[im.mode])
            has_alpha = im.mode in ("LA", "RGBA")
            arr = np.asarray(im)
        except (OSError, ValueError, SyntaxError, EOFError, struct.error) as err:
            raise InputError(
                src,
                "image",
                "a decodable PGM or PNG image",
                Described(f"{path}: {err or type(err).__name__}"),
            ) from None
    finally:
        im.close()
    values = _pixels_to_values(arr, has_alpha, mode, negate, occ_th, free_th)
    return np.ascontiguousarray(values[::-1])


def _pixels_to_values(
    arr: np.ndarray, has_alpha: bool, mode: str, negate: bool, occ_th: float, free_th: float
) -> np.ndarray:
    """Cell values of decoded 8-bit pixels (``L``, ``LA``, ``RGB`` or ``RGBA``, image rows
    top to bottom), as Nav2 reads them.

    Nav2 averages ``pixelColor``'s red, green and blue (a grey pixel has all three equal to
    the grey) and, in ``trinary`` mode of an image with alpha only, the alpha too; quanta are
    summed in doubles (exact) and divided by the channel count, then by ``MaxRGB``.
    """
    if arr.ndim == 2:
        arr = arr[..., None]
    colour = arr[..., :-1] if has_alpha else arr
    if colour.shape[-1] == 1:
        quanta = colour[..., 0].astype(float) * (3.0 * _QUANTUM_PER_LEVEL)
    else:
        quanta = colour.astype(float).sum(axis=-1) * _QUANTUM_PER_LEVEL
    n = 3
    if has_alpha:
        alpha = arr[..., -1]
        opaque = alpha == 255
        if mode == "trinary":
            quanta += alpha.astype(float) * _QUANTUM_PER_LEVEL
            n = 4
    else:
        opaque = np.ones(arr.shape[:-1], bool)
    return _shade_to_values(_shade(quanta, n), opaque, mode, negate, occ_th, free_th)


def coarse_free(
    free_mask: npt.ArrayLike, resolution: float, cell: float, *, source: str | None = None
) -> tuple[np.ndarray, float]:
    """The one coarsener: a free mask on square cells of about ``cell`` metres.

    A coarse cell is free where **at least half** of its map cells are free (so a door that
    straddles two coarse cells stays open in both). Behaviours, their fits and the learned
    entry densities all move on grids made here, so they agree cell for cell (the
    behaviours' occupancy is the complement: a coarse cell is blocked where more than half
    of its map cells are not free, occupied or unknown). Trailing map cells that do not fill
    a coarse cell are dropped; a map smaller than 2 x 2 coarse cells keeps its own cells
    (an error with ``source``).

    Parameters
    ----------
    free_mask : (H, W) bool
        Free map cells (row 0 at the origin).
    resolution : float
        Map cell side (m).
    cell : float
        Target cell side (m), rounded to a whole number of map cells (at least one).
    source : str, optional
        The option or key ``cell`` came from (the behaviours' grid): then ``cell`` must be
        a finite number > 0 and the coarse grid at least 2 x 2 cells, else a ``ValueError``
        names it.

    Returns
    -------
    free : (h, w) bool
    resolution : float
        The coarse cell side.

    Raises
    ------
    ValueError
        With ``source``: a cell that is not a finite number > 0, or a coarse grid of fewer
        than 2 x 2 cells.

    Examples
    --------
    >>> free = np.ones((6, 6), bool)
    >>> free[:3, :2] = False  # 6 of the 9 fine cells of the corner coarse cell
    >>> coarse, res = coarse_free(free, 0.1, 0.3)
    >>> coarse.tolist(), round(res, 9)
    ([[False, True], [True, True]], 0.3)
    """
    free = np.asarray(free_mask, bool)
    res = float(resolution)
    f = _coarse_factor(free.shape, res, cell, source)
    if f is None:
        return free.copy(), res
    h, w = free.shape[0] // f, free.shape[1] // f
    frac = free[: h * f, : w * f].reshape(h, f, w, f).mean(axis=(1, 3))
    return frac >= 0.5, res * f


def coarse_cell(
    shape: tuple[int, int], resolution: float, cell: float, *, source: str | None = None
) -> float:
    """The side (m) of the cells :func:`coarse_free` makes of a map, without making them.

    ``cell`` rounded to a whole number of map cells (at least one); the map's own cells
    when the map is smaller than 2 x 2 coarse cells (an error with ``source``), as
    :func:`coarse_free` does.

    Parameters
    ----------
    shape : (H, W)
        The map's shape in cells.
    resolution : float
        Map cell side (m).
    cell : float
        Target cell side (m).
    source : str, optional
        The option or key ``cell`` came from, as for :func:`coarse_free`.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        With ``source``, as :func:`coarse_free`.

    Examples
    --------
    >>> round(coarse_cell((60, 40), 0.05, 1.0), 9), round(coarse_cell((60, 40), 0.05, 0.12), 9)
    (1.0, 0.1)
    """
    f = _coarse_factor(shape, float(resolution), cell, source)
    return float(resolution) * (1 if f is None else f)


def _coarse_factor(
    shape: tuple[int, ...], res: float, cell: float, source: str | None
) -> int | None:
    """Map cells per coarse cell side, or None when the coarse grid would be under 2 x 2."""
    if source is not None:
        cell = inputs.get_float(cell, source, "", lo=0.0, lo_open=True)
    f = max(1, int(round(min(float(cell) / res, 2.0**31))))
    if shape[0] // f < 2 or shape[1] // f < 2:
        if source is not None:
            raise ValueError(f"{source}: expected a cell much smaller than the map, got {cell}")
        return None
    return f
