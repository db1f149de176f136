"""Mesh files in and out, through trimesh.

Reading: OBJ, PLY, STL, OFF, GLB/glTF and anything else trimesh reads, also gzip-compressed
(``.gz``). A scene with several meshes is concatenated into one mesh in world coordinates
(its node transforms applied); a file with no triangles is refused. Vertices are kept as
stored (``process=False``): welding is the job of each algorithm (see ``merge_vertices``).
"""

from __future__ import annotations

import gzip
import io as _io
import json
import os
import tempfile
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import MeshbitsError, MeshFileError
from .mesh import as_mesh

__all__ = ["check_writable", "example_mesh_path", "load_mesh", "save_mesh", "write_atomic"]


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
    MeshFileError
        The file cannot be parsed, holds no triangles, or holds NaN or infinite
        coordinates or vertex indices out of range (a ``ValueError``).
    """
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such mesh file: {path}")
    suffixes = [s.lower() for s in path.suffixes]
    try:
        if suffixes and suffixes[-1] == ".gz":
            if len(suffixes) < 2:
                raise MeshFileError(f"cannot tell the format of {path}: name it like mesh.ply.gz")
            with gzip.open(path, "rb") as handle:
                data = _io.BytesIO(handle.read())
            loaded = trimesh.load(data, file_type=suffixes[-2].lstrip("."), process=False)
        else:
            loaded = trimesh.load(path, process=False)
        if isinstance(loaded, trimesh.Scene):
            meshes = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
            if not meshes:
                raise MeshFileError(f"{path} holds no triangle mesh")
            loaded = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            raise MeshFileError(f"{path} holds no triangles")
        vertices = np.asarray(loaded.vertices, dtype=np.float64)
        faces = np.asarray(loaded.faces, dtype=np.int64)
    except MeshFileError:
        raise
    except MemoryError as err:
        raise MeshFileError(
            f"cannot read {path}: it declares more data than fits in memory"
        ) from err
    except Exception as err:
        # A corrupt file makes a parser fail in any of many ways (struct, unicode, index,
        # attribute errors...): each is this file's fault, reported as such.
        reason = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise MeshFileError(f"cannot read {path} as a mesh: {reason}") from err
    try:
        as_mesh(vertices, faces)
    except MeshbitsError as err:
        raise MeshFileError(f"{path}: {err}") from err
    return vertices, faces


def check_writable(path: str | Path) -> Path:
    """Refuse an output path whose folder does not exist or cannot be written, or that
    names a folder, before any work is done."""
    path = Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise MeshbitsError(f"cannot write {path}: the folder {folder} does not exist")
    if path.is_dir():
        raise MeshbitsError(f"cannot write {path}: it is a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise MeshbitsError(f"cannot write {path}: the folder {folder} is not writable")
    return path


def _default_mode() -> int:
    """0666 minus the process's umask: the mode ``open(path, "w")`` gives a new file."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def write_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder, renamed
    into place: a failure leaves neither a partial file nor a damaged earlier one."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as out:
            out.write(data)
        # mkstemp makes the file private (0600): give it the mode a plain write would,
        # or the one of the file it replaces.
        os.chmod(temporary, path.stat().st_mode & 0o7777 if path.exists() else _default_mode())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def _gltf_files(mesh: object, path: Path) -> dict[str, bytes]:
    """A text glTF and its binary buffers, the buffers named after the output
    (``mesh.gltf`` -> ``mesh.bin``), so that two outputs in one folder never share one."""
    from trimesh.exchange.gltf import export_gltf

    files = export_gltf(mesh, merge_buffers=True)
    document = json.loads(files.pop("model.gltf"))
    renamed = {}
    buffers = document.get("buffers", [])
    for index, buffer in enumerate(buffers):
        name = f"{path.stem}.bin" if len(buffers) == 1 else f"{path.stem}_{index}.bin"
        renamed[name] = files.pop(buffer["uri"])
        buffer["uri"] = name
    renamed[path.name] = json.dumps(document).encode()
    return renamed


def save_mesh(path: str | Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """Write a mesh atomically; the format is picked from the file extension (PLY, OBJ,
    STL, OFF, GLB, glTF). A ``.gltf`` gets its buffer beside it, named after it
    (``out.gltf`` and ``out.bin``)."""
    import trimesh

    path = Path(path)
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    suffix = path.suffix.lower().lstrip(".")
    if suffix == "gltf":
        files = _gltf_files(mesh, path)
        document = files.pop(path.name)
        for name, data in files.items():
            write_atomic(path.with_name(name), data)
        return write_atomic(path, document)
    data = mesh.export(file_type=suffix)
    return write_atomic(path, data.encode() if isinstance(data, str) else data)
