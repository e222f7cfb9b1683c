"""Link covers kept on disk: fitting them loads trimesh and its meshes, about 0.3 s per arm.

:func:`cover_links` is a pure function of the arm's collision geometry and the cover's
settings, so its result is stored once per input under ``<cache>/covers/`` (the folder of
:func:`cpbc.model.meshes.cache_dir`: ``$CPBC_CACHE_DIR``, else ``$XDG_CACHE_HOME/cpbc`` or
``~/.cache/cpbc``). A file's name is a hash of everything the fit reads: every collision
geometry's parent frame, placement and shape (a mesh's file bytes and scale), which frames
move, the links asked for, padding, kind and tolerance, and the source of
:mod:`cpbc.constraints.covering` itself, so an edited mesh, URDF or fitting method is fitted
again. An unreadable or unwritable cache is no error: the cover is fitted as if there were
none. Files are written atomically, so worker processes fitting the same arm at once never
read half a file.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from cpbc.constraints import covering
from cpbc.constraints.covering import LinkPrimitive, cover_links, cover_points
from cpbc.model.meshes import cache_dir


def cached_cover(
    model: pin.Model,
    collision: pin.GeometryModel,
    links: Sequence[str] | None = None,
    padding: float = 0.0,
    kind: str = "spheres",
    tolerance: float = 0.01,
) -> list[LinkPrimitive]:
    """:func:`cpbc.constraints.covering.cover_links`, read from the cache when it holds this
    input, else fitted and stored."""
    key = cover_key(model, collision, links, padding, kind, tolerance)
    return _stored_or_fitted(key, lambda: cover_links(model, collision, links, padding, kind,
                                                      tolerance))


def cached_point_cover(
    points: dict[str, np.ndarray],
    moving: set[str],
    links: Sequence[str] | None = None,
    padding: float = 0.0,
    kind: str = "spheres",
    tolerance: float = 0.01,
) -> list[LinkPrimitive]:
    """:func:`cpbc.constraints.covering.cover_points` (an MJCF arm's links), cached as
    :func:`cached_cover` is, under a hash of the points themselves."""
    h = hashlib.sha256()
    h.update(Path(covering.__file__).read_bytes())
    h.update(repr((None if links is None else list(links), float(padding), kind,
                   float(tolerance), sorted(moving))).encode())
    for name in sorted(points):
        h.update(name.encode())
        h.update(np.ascontiguousarray(points[name], dtype=float).tobytes())
    return _stored_or_fitted(h.hexdigest()[:32], lambda: cover_points(
        points, moving, links, padding, kind, tolerance))


def _stored_or_fitted(key: str, fit: Callable[[], list[LinkPrimitive]]
                      ) -> list[LinkPrimitive]:
    """The cover stored under ``key``, else ``fit()``'s, stored there."""
    path = cache_dir() / "covers" / f"{key}.npz"
    stored = _read(path)
    if stored is not None:
        return stored
    prims = fit()
    _write(path, prims)
    return prims


def cover_key(
    model: pin.Model,
    collision: pin.GeometryModel,
    links: Sequence[str] | None,
    padding: float,
    kind: str,
    tolerance: float,
) -> str:
    """A hash of every input of the fit (module docstring)."""
    h = hashlib.sha256()
    h.update(Path(covering.__file__).read_bytes())
    h.update(repr((None if links is None else list(links), float(padding), kind,
                   float(tolerance))).encode())
    h.update(repr(sorted(covering.moving_frames(model))).encode())
    for geom in collision.geometryObjects:
        frame = model.frames[geom.parentFrame]
        h.update(frame.name.encode())
        h.update(np.asarray(frame.placement.actInv(geom.placement).homogeneous, float).tobytes())
        shape = geom.geometry
        h.update(type(shape).__name__.encode())
        mesh = Path(str(geom.meshPath))
        if str(geom.meshPath) and mesh.is_file():
            h.update(mesh.read_bytes())
            h.update(np.asarray(geom.meshScale, dtype=float).tobytes())
        else:  # a primitive shape: its parameters
            h.update(repr(sorted((name, repr(getattr(shape, name)))
                                 for name in ("radius", "halfLength", "halfSide")
                                 if hasattr(shape, name))).encode())
    return h.hexdigest()[:32]


def _read(path: Path) -> list[LinkPrimitive] | None:
    try:
        with np.load(path, allow_pickle=False) as f:
            return [LinkPrimitive(str(n), str(fr), s, e, float(r)) for n, fr, s, e, r in
                    zip(f["names"], f["frames"], f["starts"], f["ends"], f["radii"],
                        strict=True)]
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):  # absent, damaged
        return None


def _write(path: Path, prims: Sequence[LinkPrimitive]) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".part")
        with os.fdopen(fd, "wb") as f:
            np.savez(
                f,
                names=np.array([p.name for p in prims], dtype=str),
                frames=np.array([p.frame for p in prims], dtype=str),
                starts=np.array([p.start for p in prims], dtype=float).reshape(-1, 3),
                ends=np.array([p.end for p in prims], dtype=float).reshape(-1, 3),
                radii=np.array([p.radius for p in prims], dtype=float),
            )
        os.replace(tmp, path)
    except OSError:  # a read-only home: fit again next time
        pass
