"""The 3D map M_3D (paper Sect. 3.1): a set of occupied voxel keys at one resolution.

Keys follow OctoMap: voxel ``k = floor(p / resolution)`` per axis (OctoMap adds 32768 to get
its unsigned 16-bit keys), voxel centres at ``(k + 0.5) * resolution``. Keys are stored
sorted and unique as packed int64 so that insert, remove and query are vectorised set
operations.

OctoMap ``.bt`` files are read and written by a documented reader (the maximum-likelihood
binary format of ``OcTree::writeBinary``): no compiled binding is needed. After the text
header (``# Octomap OcTree binary file``, ``id OcTree``, ``size N``, ``res R``, ``data``)
the tree is stored depth first; each inner node is two bytes holding 2 bits per child
(children 0-3 in the first byte, 4-7 in the second; bits ``(2i, 2i+1)`` of child ``i``):
``(0, 0)`` unknown, ``(0, 1)`` occupied leaf, ``(1, 0)`` free leaf, ``(1, 1)`` inner node
whose own two bytes follow (after all 8 flags of the parent, in child order). Child ``i``
sets bit ``15 - depth`` of the key's x (``i & 1``), y (``i & 2``) and z (``i & 4``). Leaves
above the maximum depth 16 (pruned blocks) cover ``2^(16 - depth)`` voxels per axis and are
expanded.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from are_stats import inputs
from are_stats._atomic import atomic_path
from are_stats._checks import check_finite, check_positive
from are_stats.inputs import Described, InputError

if TYPE_CHECKING:
    import trimesh

__all__ = ["VoxelMap"]

_BITS = 21
_OFF = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1
_BT_HEADER = "# Octomap OcTree binary file"
_TREE_DEPTH = 16
_TREE_MAX = 32768
_MIN_RES, _MAX_RES = 1e-6, 1e4
# Memory per expanded voxel while reading: (n, 3) int64 keys, their grid copy and the packed
# int64 key, plus np.unique's sort buffers.
_BYTES_PER_VOXEL = 96
_BT_STEPS_PER_BYTE = 64


def _pack(keys: np.ndarray) -> np.ndarray:
    k = keys.astype(np.int64) + _OFF
    if ((k < 0) | (k > _MASK)).any():
        raise ValueError(
            f"points: voxel keys must lie within +-{_OFF} voxels of the origin, "
            f"got a key of {int(np.abs(keys).max())}"
        )
    return (k[:, 0] << (2 * _BITS)) | (k[:, 1] << _BITS) | k[:, 2]


def _unpack(packed: np.ndarray) -> np.ndarray:
    return (
        np.stack([(packed >> (2 * _BITS)) & _MASK, (packed >> _BITS) & _MASK, packed & _MASK], 1)
        - _OFF
    )


class VoxelMap:
    """Occupied voxels of M_3D at a fixed resolution.

    Parameters
    ----------
    resolution : float
        Voxel side in metres.
    keys : (n, 3) int, optional
        Initial occupied voxel keys.

    Examples
    --------
    >>> vm = VoxelMap(0.1)
    >>> vm.insert_points([[0.05, 0.05, 0.05], [0.07, 0.01, 0.09], [1.0, 0.0, 0.0]])
    >>> len(vm), vm.query([[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]]).tolist()
    (2, [True, False])
    """

    def __init__(self, resolution: float, keys: npt.ArrayLike | None = None) -> None:
        self.resolution = float(check_positive("resolution", resolution))
        self._packed = np.zeros(0, dtype=np.int64)
        if keys is not None:
            k = np.asarray(keys)
            if k.ndim != 2 or k.shape[1] != 3 or not np.issubdtype(k.dtype, np.integer):
                raise ValueError(f"keys: expected an (n, 3) integer array, got shape {k.shape}")
            self._packed = np.unique(_pack(k))

    # ---------------------------------------------------------------- keys
    def key_of(self, points: npt.ArrayLike) -> np.ndarray:
        """``(n, 3)`` int64 voxel keys of ``(n, 3)`` points."""
        p = check_finite("points", points)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points: expected an (n, 3) array, got shape {p.shape}")
        return np.floor(p / self.resolution).astype(np.int64)

    @property
    def keys(self) -> np.ndarray:
        """``(n, 3)`` int64 occupied keys, sorted."""
        return _unpack(self._packed)

    @property
    def packed(self) -> np.ndarray:
        """``(n,)`` int64 sorted packed keys (for fast set operations)."""
        return self._packed

    def centres(self) -> np.ndarray:
        """``(n, 3)`` float centres of the occupied voxels."""
        return (self.keys + 0.5) * self.resolution

    def __len__(self) -> int:
        return int(self._packed.size)

    def __repr__(self) -> str:
        return f"VoxelMap(resolution={self.resolution}, n_occupied={len(self)})"

    def copy(self) -> VoxelMap:
        """A copy."""
        out = VoxelMap(self.resolution)
        out._packed = self._packed.copy()
        return out

    # ---------------------------------------------------------------- updates
    def insert_points(self, points: npt.ArrayLike) -> None:
        """Mark the voxels containing ``(n, 3)`` points occupied."""
        self.insert_keys(self.key_of(points))

    def remove_points(self, points: npt.ArrayLike) -> None:
        """Mark the voxels containing ``(n, 3)`` points not occupied."""
        self.remove_keys(self.key_of(points))

    def insert_keys(self, keys: npt.ArrayLike) -> None:
        """Add ``(n, 3)`` integer keys."""
        k = np.asarray(keys, dtype=np.int64).reshape(-1, 3)
        self._packed = np.union1d(self._packed, _pack(k))

    def remove_keys(self, keys: npt.ArrayLike) -> None:
        """Remove ``(n, 3)`` integer keys."""
        k = np.asarray(keys, dtype=np.int64).reshape(-1, 3)
        self._packed = np.setdiff1d(self._packed, _pack(k), assume_unique=False)

    def query(self, points: npt.ArrayLike) -> np.ndarray:
        """``(n,)`` bool: whether the voxel of each point is occupied."""
        return self.contains_keys(self.key_of(points))

    def contains_keys(self, keys: npt.ArrayLike) -> np.ndarray:
        """``(n,)`` bool: whether each ``(n, 3)`` key is occupied."""
        k = np.asarray(keys, dtype=np.int64).reshape(-1, 3)
        q = _pack(k)
        idx = np.searchsorted(self._packed, q)
        idx = np.minimum(idx, max(self._packed.size - 1, 0))
        if self._packed.size == 0:
            return np.zeros(q.shape, bool)
        return self._packed[idx] == q

    def union(self, other: VoxelMap) -> VoxelMap:
        """A new map with the voxels of both (same resolution)."""
        if other.resolution != self.resolution:
            raise ValueError(
                f"other: expected resolution {self.resolution}, got {other.resolution}"
            )
        out = VoxelMap(self.resolution)
        out._packed = np.union1d(self._packed, other._packed)
        return out

    # ---------------------------------------------------------------- meshes
    @classmethod
    def from_mesh(cls, mesh: trimesh.Trimesh, resolution: float) -> VoxelMap:
        """Surface voxelisation: every voxel that the mesh surface passes through.

        The mesh is subdivided until no edge is longer than ``resolution / 2``, then the
        voxels of its vertices are marked (points are at most a quarter voxel apart, so no
        voxel crossed by the surface is missed by more than that margin).
        """
        out = cls(resolution)
        out.insert_points(surface_points(mesh, out.resolution))
        return out

    # ---------------------------------------------------------------- OctoMap
    @classmethod
    def from_octomap_bt(cls, path: str | os.PathLike) -> VoxelMap:
        """Read the occupied leaves of an OctoMap ``.bt`` file (see the module docstring)
        into a map of the file's resolution (its ``res`` header line).

        Raises
        ------
        FileNotFoundError
            If the file does not exist.
        ValueError
            If the header or the tree data are malformed.
        """
        p = Path(path)
        size_b = inputs.check_file(p, "an OctoMap .bt file")
        inputs.check_memory(
            size_b * 2, f"reading the {inputs.format_bytes(size_b)} OctoMap file", p
        )
        # the tree is walked one inner node (2 bytes) at a time
        inputs.check_work(size_b * _BT_STEPS_PER_BYTE, "walking the OctoMap tree", p)
        raw = p.read_bytes()
        pos = 0

        def line() -> str:
            nonlocal pos
            end = raw.find(b"\n", pos)
            if end < 0:
                raise ValueError(f"{p}: truncated OctoMap header")
            text = raw[pos:end].decode("ascii", errors="replace").strip()
            pos = end + 1
            return text

        if line() != _BT_HEADER:
            raise ValueError(f"{p}: not an OctoMap binary file (first line is not {_BT_HEADER!r})")
        meta: dict[str, str] = {}
        while True:
            text = line()
            if not text or text.startswith("#"):
                continue
            if text == "data":
                break
            key, _, val = text.partition(" ")
            meta[key] = val.strip()
        if meta.get("id", "OcTree") != "OcTree":
            raise ValueError(f"{p}: expected an OcTree, got id {meta.get('id')!r}")
        if "res" not in meta:
            raise InputError(p, "header", "a line 'res R' (the resolution)", Described("none"))
        try:
            res = float(meta["res"])
        except ValueError:
            res = math.nan
        if not _MIN_RES <= res <= _MAX_RES:
            raise InputError(
                p, "header 'res'", f"a resolution in [{_MIN_RES:g}, {_MAX_RES:g}] m", meta["res"]
            )
        try:
            size = int(meta.get("size", "1"))
        except ValueError:
            size = -1
        if size < 0:
            raise InputError(p, "header 'size'", "a node count >= 0", meta.get("size"))
        out = cls(res)
        if size == 0:
            return out
        keys = _read_bt_tree(raw, pos, p)
        if keys.size:
            out._packed = np.unique(_pack(keys - _TREE_MAX))
        return out

    def to_octomap_bt(self, path: str | os.PathLike, force: bool = False) -> Path:
        """Write the occupied voxels as an OctoMap ``.bt`` file (finest-level leaves)."""
        keys = self.keys + _TREE_MAX
        if len(keys) and ((keys < 0) | (keys >= 2 * _TREE_MAX)).any():
            raise ValueError("VoxelMap: keys beyond OctoMap's 16-bit range cannot be written")
        chunks: list[bytes] = []
        n_nodes = _write_bt_node(keys, 0, chunks) if len(keys) else 0
        header = f"{_BT_HEADER}\nid OcTree\nsize {n_nodes}\nres {self.resolution!r}\ndata\n"
        with atomic_path(path, force=force) as tmp:
            tmp.write_bytes(header.encode("ascii") + b"".join(chunks))
        return Path(path)


def surface_points(mesh: trimesh.Trimesh, resolution: float) -> np.ndarray:
    """``(n, 3)`` points on the mesh surface no more than ``resolution / 2`` apart."""
    # lazy: trimesh adds 2.7 s CPU to `import are_stats.environment`
    import trimesh

    v, f = trimesh.remesh.subdivide_to_size(
        np.asarray(mesh.vertices), np.asarray(mesh.faces), max_edge=resolution / 2.0
    )
    return np.asarray(v)


def _read_bt_tree(raw: bytes, pos: int, p: Path) -> np.ndarray:
    data = np.frombuffer(raw, dtype=np.uint8, offset=pos)
    out: list[np.ndarray] = []
    # stack of (depth, key) of inner nodes whose two flag bytes are next in the stream
    cursor = 0
    n_voxels = 0
    stack = [(0, (0, 0, 0))]
    while stack:
        depth, key = stack.pop()
        if cursor + 2 > data.size:
            raise InputError(p, f"byte {pos + cursor}", "more tree data", Described("end of file"))
        flags = int(data[cursor]) | (int(data[cursor + 1]) << 8)
        cursor += 2
        inner = []
        half = 1 << (_TREE_DEPTH - depth - 1)
        for i in range(8):
            b = (flags >> (2 * i)) & 3
            if b == 0:
                continue
            ck = (
                key[0] + (half if i & 1 else 0),
                key[1] + (half if i & 2 else 0),
                key[2] + (half if i & 4 else 0),
            )
            if b == 3:
                if depth + 1 >= _TREE_DEPTH:
                    raise ValueError(f"{p}: OctoMap tree deeper than {_TREE_DEPTH} levels")
                inner.append((depth + 1, ck))
            elif b == 2:  # bit 2i set, 2i+1 clear: occupied leaf
                span = half
                n_voxels += span**3
                inputs.check_memory(
                    n_voxels * _BYTES_PER_VOXEL,
                    f"the {n_voxels} occupied voxels of the pruned OctoMap tree",
                    p,
                )
                r = np.arange(span)
                g = np.stack(np.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3)
                out.append(g + np.array(ck))
        # children are read in order: push in reverse so child 0 is popped first
        stack.extend(reversed(inner))
    if cursor != data.size:
        raise ValueError(f"{p}: {data.size - cursor} unexpected bytes after the OctoMap tree")
    return np.concatenate(out) if out else np.zeros((0, 3), dtype=np.int64)


def _write_bt_node(keys: np.ndarray, depth: int, chunks: list[bytes]) -> int:
    """Write the node holding ``keys`` at ``depth``; return the number of nodes written."""
    shift = _TREE_DEPTH - depth - 1
    child = (
        ((keys[:, 0] >> shift) & 1)
        | (((keys[:, 1] >> shift) & 1) << 1)
        | (((keys[:, 2] >> shift) & 1) << 2)
    )
    flags = 0
    parts = []
    for i in range(8):
        sel = keys[child == i]
        if len(sel) == 0:
            continue
        if depth + 1 == _TREE_DEPTH:
            flags |= 2 << (2 * i)  # occupied leaf
        else:
            flags |= 3 << (2 * i)
            parts.append(sel)
    chunks.append(bytes([flags & 0xFF, (flags >> 8) & 0xFF]))
    n = 1 + (
        int(np.count_nonzero(np.bincount(child, minlength=8))) if depth + 1 == _TREE_DEPTH else 0
    )
    for sel in parts:
        n += _write_bt_node(sel, depth + 1, chunks)
    return n
