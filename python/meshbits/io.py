"""Mesh files in and out, through trimesh.

Reading: OBJ, PLY, STL, OFF, GLB/glTF and anything else trimesh reads, also gzip-compressed
(``.gz``). A scene with several meshes is concatenated into one mesh in world coordinates
(its node transforms applied); a file with no triangles is refused. Vertices are kept as
stored (``process=False``): welding is the job of each algorithm (see ``merge_vertices``).
"""

from __future__ import annotations

import gzip
import io as _io
from importlib import resources
from pathlib import Path

import numpy as np

__all__ = ["example_mesh_path", "load_mesh", "save_mesh"]


def example_mesh_path() -> Path:
    """Path of the example mesh shipped in the package: Keenan Crane's *Spot* (public
    domain), 2,930 vertices and 5,856 triangles."""
    return Path(str(resources.files("meshbits") / "data" / "spot.ply"))


def load_mesh(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh file; return ``(vertices float64 (n, 3), faces int64 (m, 3))``.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        The file cannot be parsed, or holds no triangles.
    """
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such mesh file: {path}")
    suffixes = [s.lower() for s in path.suffixes]
    try:
        if suffixes and suffixes[-1] == ".gz":
            if len(suffixes) < 2:
                raise ValueError(f"cannot tell the format of {path}: name it like mesh.ply.gz")
            with gzip.open(path, "rb") as handle:
                data = _io.BytesIO(handle.read())
            loaded = trimesh.load(data, file_type=suffixes[-2].lstrip("."), process=False)
        else:
            loaded = trimesh.load(path, process=False)
    except (ValueError, KeyError, IndexError, OSError, NotImplementedError) as err:
        raise ValueError(f"cannot read {path} as a mesh: {err}") from err
    if isinstance(loaded, trimesh.Scene):
        meshes = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
        if not meshes:
            raise ValueError(f"{path} holds no triangle mesh")
        loaded = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ValueError(f"{path} holds no triangles")
    return np.asarray(loaded.vertices, dtype=np.float64), np.asarray(loaded.faces, dtype=np.int64)


def save_mesh(path: str | Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """Write a mesh; the format is picked from the file extension (PLY, OBJ, STL, OFF, GLB)."""
    import trimesh

    path = Path(path)
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    mesh.export(path)
    return path
