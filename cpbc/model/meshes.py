"""Mesh files MuJoCo can read: other formats (Collada ``.dae``, …) converted once, cached on disk.

MuJoCo decodes only binary STL, OBJ and its own MSH; URDFs often reference Collada meshes (the
Kinova Jaco2 of example-robot-data, UR visuals) or ASCII STL (its simple humanoid). Pinocchio
reads those through coal and assimp, so the conversion uses the same loader: the STL holds
exactly the triangles Pinocchio collides with
(at scale 1; the URDF's ``scale`` attribute still applies in both engines).

The cache lives outside the repository: ``$CPBC_CACHE_DIR`` if set, else
``$XDG_CACHE_HOME/cpbc`` or ``~/.cache/cpbc``, under ``meshes/``. A file's name carries a hash
of the source's bytes, so an edited source is converted again; files are written atomically so
that worker processes converting the same mesh at once do not see half a file.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

from cpbc.errors import ModelError

MUJOCO_MESH_SUFFIXES = frozenset({".stl", ".obj", ".msh"})


def cache_dir() -> Path:
    """The folder of cpbc's cached files (created on first use by the writers)."""
    if os.environ.get("CPBC_CACHE_DIR"):
        return Path(os.environ["CPBC_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "cpbc"


def needs_conversion(path: Path) -> bool:
    """Whether MuJoCo cannot decode this mesh file as it is."""
    return path.suffix.lower() not in MUJOCO_MESH_SUFFIXES or is_ascii_stl(path)


def is_ascii_stl(path: Path) -> bool:
    """Whether a ``.stl`` file is ASCII: it starts with ``solid`` and its size is not that of
    a binary STL with the facet count of its bytes 80-84 (a binary header may say "solid")."""
    if path.suffix.lower() != ".stl":
        return False
    try:
        with path.open("rb") as f:
            head = f.read(84)
        size = path.stat().st_size
    except OSError:
        return False
    binary = len(head) == 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")
    return head.lstrip().startswith(b"solid") and not binary


def _triangles(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangle indices (T, 3) of a mesh, read by coal (assimp)."""
    try:  # comes with pin (hpp-fcl before pin 3.4); imported here: STL-only arms never need it
        import coal
    except ImportError:  # pragma: no cover - older pin
        import hppfcl as coal

    try:
        bvh = coal.MeshLoader().load(str(path), np.ones(3))
    except (RuntimeError, ValueError) as exc:
        raise ModelError(f"cannot read mesh {path}: {exc}") from None
    vertices = np.asarray(bvh.vertices(), dtype=float).reshape(-1, 3)
    tris = np.array([[t[0], t[1], t[2]] for t in
                     (bvh.tri_indices(i) for i in range(bvh.num_tris))], dtype=np.int64)
    if vertices.size == 0 or tris.size == 0:
        raise ModelError(f"mesh {path} holds no triangles")
    return vertices, tris.reshape(-1, 3)


def _binary_stl(vertices: np.ndarray, tris: np.ndarray) -> bytes:
    """Binary STL bytes: an 80-byte header, the count, then per facet normal, 3 vertices."""
    corners = vertices[tris]  # (T, 3, 3)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    record = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    facets = np.zeros(len(tris), dtype=record)
    facets["n"], facets["v"] = normals, corners
    header = b"cpbc: converted for MuJoCo".ljust(80, b" ")
    return header + np.uint32(len(tris)).tobytes() + facets.tobytes()


def mujoco_mesh(path: Path) -> Path:
    """``path`` itself if MuJoCo reads its format, else a cached STL conversion of it."""
    if not needs_conversion(path):
        return path
    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:20]
    target = cache_dir() / "meshes" / f"{path.stem}-{digest}.stl"
    if target.is_file():
        return target
    data = _binary_stl(*_triangles(path))
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, suffix=".part")
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, target)
    except OSError as exc:
        raise ModelError(
            f"cannot write the converted mesh of {path} to {target.parent}: {exc}; set "
            "CPBC_CACHE_DIR to a writable folder"
        ) from None
    return target
