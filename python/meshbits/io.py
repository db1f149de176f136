"""Mesh files in and out, through trimesh.

Reading: OBJ, PLY, STL, OFF, GLB/glTF and anything else trimesh reads, also gzip-compressed
(``.gz``); GLB/glTF compressed with meshopt (``EXT_meshopt_compression``,
``KHR_meshopt_compression``) or Draco (``KHR_draco_mesh_compression``) through meshbits's
own glTF reader, which refuses a primitive it cannot decode. A scene with several
meshes is concatenated into one mesh in world coordinates (its node transforms applied); a
file with no triangles is refused. Vertices are kept as stored (``process=False``):
welding is the job of each algorithm (see ``merge_vertices``).
"""

from __future__ import annotations

import contextlib
import gzip
import io as _io
import json
import logging
import mmap
import os
import warnings
import zlib
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ._filecheck import check_structure, explain
from .errors import MeshbitsError, MeshFileError
from .files import write_atomic
from .mesh import as_mesh

__all__ = [
    "GZIP_MAX_RATIO",
    "GZIP_MIN_LIMIT",
    "example_mesh_path",
    "load_mesh",
    "save_mesh",
]

#: A ``.gz`` mesh may inflate to at most this many times its compressed size (meshes
#: compress 1.5 to 3 times; zeros, a thousand times)...
GZIP_MAX_RATIO = 100
#: ...or to this many bytes (64 MiB), whichever is larger.
GZIP_MIN_LIMIT = 64 << 20

# trimesh logs through the logging module and installs no handler, so that without one
# Python prints its warnings ("unable to load image", ...) on stderr. meshbits reports a
# file's problems through exceptions; the records still reach any handler an application
# configures.
logging.getLogger("trimesh").addHandler(logging.NullHandler())


def example_mesh_path() -> Path:
    """Path of the example mesh shipped in the package: Keenan Crane's *Spot* (public
    domain), 2,930 vertices and 5,856 triangles."""
    return Path(str(resources.files("meshbits") / "data" / "spot.ply"))


def checked_mesh_file(path: Path) -> tuple[Path | _io.BytesIO, str, bool]:
    """Check a mesh file's structure before a parser reads it (see :func:`load_mesh`):
    returns what to parse (the path, or the inflated bytes of a ``.gz``), the format and
    whether it was compressed. Raises ``FileNotFoundError`` or :class:`MeshFileError`
    naming the file."""
    if not path.is_file():
        raise FileNotFoundError(f"no such mesh file: {path}")
    suffixes = [s.lower() for s in path.suffixes]
    compressed = bool(suffixes) and suffixes[-1] == ".gz"
    if compressed and len(suffixes) < 2:
        raise MeshFileError(f"cannot tell the format of {path}: name it like mesh.ply.gz")
    file_type = suffixes[-2 if compressed else -1].lstrip(".") if suffixes else ""
    if not file_type:
        raise MeshFileError(f"cannot tell the format of {path}: name it like mesh.ply")
    try:
        source: Path | _io.BytesIO = path
        if compressed:
            source = _gunzip(path)
            with source.getbuffer() as view:
                check_structure(file_type, view, len(view))
        else:
            _check_file(path, file_type)
    except MeshFileError as err:
        raise MeshFileError(f"cannot read {path}: {err}") from None
    except MemoryError as err:
        raise MeshFileError(f"cannot read {path}: it does not fit in memory") from err
    except OSError as err:
        raise MeshFileError(f"cannot read {path}: {err.strerror or err}") from err
    return source, file_type, compressed


def load_mesh(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh file; return ``(vertices float64 (n, 3), faces int64 (m, 3))``.

    Before trimesh parses a PLY, OFF, STL or GLB file, the counts its header declares are
    compared with what the file holds (see ``meshbits._filecheck``): a 200-byte file that
    declares 10**12 vertices is refused at once, without allocating for them. A ``.gz``
    file may inflate to at most :data:`GZIP_MAX_RATIO` times its size (at least
    :data:`GZIP_MIN_LIMIT` bytes): beyond that it is refused as a decompression bomb.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    MeshFileError
        The file cannot be parsed, its header disagrees with its content, it holds no
        triangles, or it holds NaN or infinite coordinates or vertex indices out of range
        (a ``ValueError``). Nothing else, whatever the file holds.
    """
    import trimesh

    path = Path(path)
    source, file_type, compressed = checked_mesh_file(path)
    try:
        # Corrupt data makes parsers cast NaN to int, overflow and the like: the file is
        # refused or read all the same, the warnings tell the caller nothing more.
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = parse_mesh_file(path, source, file_type, compressed)
            if isinstance(loaded, trimesh.Scene):
                meshes = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
                if not meshes:
                    raise MeshFileError(f"{path} holds no triangle mesh")
                loaded = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
            if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
                raise MeshFileError(f"{path} holds no triangle mesh")
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
        raise MeshFileError(f"cannot read {path}: {explain(file_type, err)}") from err
    try:
        as_mesh(vertices, faces)
    except MeshbitsError as err:
        raise MeshFileError(f"{path}: {err}") from err
    return vertices, faces


def parse_mesh_file(
    path: Path, source: Path | _io.BytesIO, file_type: str, compressed: bool
) -> Any:
    """A checked mesh file (what :func:`checked_mesh_file` returned for ``path``) as a
    trimesh object: a Draco file (what ``meshbits compress -o x.drc`` writes) decoded with
    DracoPy; a GLB or glTF read by meshbits's glTF reader (the one the scene commands
    use: it decodes ``EXT_meshopt_compression``, ``KHR_meshopt_compression`` and
    ``KHR_draco_mesh_compression`` and checks every reference first), its triangle
    primitives in world coordinates as one; anything else parsed by trimesh."""
    import trimesh

    if file_type == "drc":
        from .encode import decode_draco

        data = source.read() if isinstance(source, _io.BytesIO) else path.read_bytes()
        try:
            return trimesh.Trimesh(*decode_draco(data), process=False)
        except MeshFileError as err:
            raise MeshFileError(f"{path}: {err}") from None
    if file_type in ("glb", "gltf"):
        from .gltf import load_gltf_document

        data = source.getvalue() if isinstance(source, _io.BytesIO) else None
        document = load_gltf_document(path, file_type, data)
        if document is not None:
            try:
                vertices, faces = document.world_triangles()
            except MeshFileError as err:
                raise MeshFileError(f"cannot read {path}: {err}") from None
            return trimesh.Trimesh(vertices, faces, process=False)
    if compressed:
        return trimesh.load(source, file_type=file_type, process=False)
    return trimesh.load(path, process=False)


def _check_file(path: Path, file_type: str) -> None:
    """:func:`meshbits._filecheck.check_structure` on a file, read through a memory map
    (only the pages the check touches are read)."""
    if file_type not in ("ply", "off", "stl", "glb"):
        return
    with open(path, "rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        if size == 0:
            check_structure(file_type, b"", 0)
        mapped = mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
        try:
            try:
                check_structure(file_type, mapped, size)
            except MeshFileError as err:
                # Re-raised once the map is closed: the traceback's frames hold numpy
                # views of the map, which keep it from closing.
                refusal = str(err)
            else:
                refusal = None
        finally:
            with contextlib.suppress(BufferError):  # only after an unexpected error
                mapped.close()
    if refusal is not None:
        raise MeshFileError(refusal)


def _gunzip(path: Path) -> _io.BytesIO:
    """The decompressed content of a gzip file, refused beyond the bomb limit."""
    limit = max(GZIP_MIN_LIMIT, GZIP_MAX_RATIO * path.stat().st_size)
    out = _io.BytesIO()
    try:
        with gzip.open(path, "rb") as handle:
            while chunk := handle.read(1 << 20):
                out.write(chunk)
                if out.tell() > limit:
                    raise MeshFileError(
                        f"it inflates to more than {limit:,} bytes, over {GZIP_MAX_RATIO} "
                        f"times its size: no mesh compresses that well (a decompression bomb?)"
                    )
    except (gzip.BadGzipFile, zlib.error) as err:
        raise MeshFileError(f"it is not a valid gzip file ({err})") from err
    except EOFError:
        raise MeshFileError("the gzip data is truncated") from None
    out.seek(0)
    return out


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
    if suffix in ("obj", "off"):
        return write_atomic(path, _text_mesh(suffix, mesh.vertices, mesh.faces))
    data = mesh.export(file_type=suffix)
    return write_atomic(path, data.encode() if isinstance(data, str) else data)


def _text_mesh(suffix: str, vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """An OBJ or OFF whose coordinates read back exactly: each written with 17 significant
    digits (trimesh writes a fixed 8 decimals, which rounds a small mesh away)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if suffix == "obj":
        head, v_fmt, f_rows = "", "v %.17g %.17g %.17g", f + 1
        f_fmt = "f %d %d %d"
    else:
        head, v_fmt, f_rows = f"OFF\n{len(v)} {len(f)} 0\n", "%.17g %.17g %.17g", f
        f_fmt = "3 %d %d %d"
    lines = [v_fmt % tuple(row) for row in v.tolist()]
    lines += [f_fmt % tuple(row) for row in f_rows.tolist()]
    return (head + "\n".join(lines) + "\n").encode()
