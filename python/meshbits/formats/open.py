"""The dispatcher: which format reads or writes a file, by its name.

Reading: PLY, STL and OBJ through the Rust readers (:mod:`.native`: memory-mapped,
parsed in parallel straight into the kernels' arrays), the files they leave aside and
OFF, GLB/glTF and anything else trimesh reads, also gzip-compressed
(``.gz``); GLB/glTF compressed with meshopt (``EXT_meshopt_compression``,
``KHR_meshopt_compression``) or Draco (``KHR_draco_mesh_compression``) through meshbits's
own glTF reader, which refuses a primitive it cannot decode. A scene with several
meshes is concatenated into one mesh in world coordinates (its node transforms applied); a
file with no triangles is refused. Vertices are kept as stored (``process=False``):
welding is the job of each algorithm (see ``merge_vertices``).

Each format module knows its own file (its header check, its reader or writer); this
module holds the tables that pick one, and is the only one that imports them all.
"""

from __future__ import annotations

import io
import logging
import warnings
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import MeshbitsError, MeshFileError
from ..files import write_atomic
from ..mesh import as_mesh
from . import obj, ply, stl
from .drc import read_drc
from .gltf.document import Document
from .gltf.read import check_glb_header, document_from_trimesh, read_gltf
from .gltf.write import write_mesh
from .native import NATIVE_FORMATS, MeshRead, read_native
from .sniff import HeaderCheck, check_mapped, explain, file_type_of, gunzip

__all__ = [
    "HEADER_CHECKS",
    "check_structure",
    "checked_mesh_file",
    "example_mesh_path",
    "load_document",
    "load_mesh",
    "parse_mesh_file",
    "read_mesh",
    "save_mesh",
]

#: The header check of each format that has a header to check, by file type.
HEADER_CHECKS: dict[str, HeaderCheck] = {
    "ply": ply.check_header,
    "off": obj.check_off_header,
    "stl": stl.check_header,
    "glb": check_glb_header,
}

# trimesh logs through the logging module and installs no handler, so that without one
# Python prints its warnings ("unable to load image", ...) on stderr. meshbits reports a
# file's problems through exceptions; the records still reach any handler an application
# configures.
logging.getLogger("trimesh").addHandler(logging.NullHandler())


def example_mesh_path() -> Path:
    """Path of the example mesh shipped in the package: Keenan Crane's *Spot* (public
    domain), 2,930 vertices and 5,856 triangles."""
    return Path(str(resources.files("meshbits") / "data" / "spot.ply"))


def check_structure(file_type: str, buffer: Any, size: int) -> None:
    """Compare what the header of a ``file_type`` file declares with what ``buffer`` (the
    whole file, ``size`` bytes, anything numpy can read and slice) holds; raise
    :class:`MeshFileError` naming the first disagreement. Formats without a header to
    check pass."""
    if size == 0:
        raise MeshFileError("the file is empty")
    check = HEADER_CHECKS.get(file_type)
    if check is not None:
        check(buffer, size)


def checked_mesh_file(path: Path) -> tuple[Path | io.BytesIO, str, bool]:
    """Check a mesh file's structure before a parser reads it (see :func:`load_mesh`):
    returns what to parse (the path, or the inflated bytes of a ``.gz``), the format and
    whether it was compressed. Raises ``FileNotFoundError`` or :class:`MeshFileError`
    naming the file."""
    if not path.is_file():
        raise FileNotFoundError(f"no such mesh file: {path}")
    file_type, compressed = file_type_of(path)
    try:
        source: Path | io.BytesIO = path
        if compressed:
            source = gunzip(path)
            with source.getbuffer() as view:
                check_structure(file_type, view, len(view))
        elif file_type in HEADER_CHECKS:
            check_mapped(path, HEADER_CHECKS[file_type])
    except MeshFileError as err:
        raise MeshFileError(f"cannot read {path}: {err}") from None
    except MemoryError as err:
        raise MeshFileError(f"cannot read {path}: it does not fit in memory") from err
    except OSError as err:
        raise MeshFileError(f"cannot read {path}: {err.strerror or err}") from err
    return source, file_type, compressed


def load_mesh(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh file; return ``(vertices float64 (n, 3), faces uint32 (m, 3))``.

    The faces are ``uint32``, the narrowest dtype every kernel takes without a conversion
    pass (a mesh of 2**32 vertices or more is refused). PLY, STL and OBJ files are read by
    the Rust readers (see :func:`read_mesh`); the rest, and any file those leave aside,
    by the general path: before trimesh parses a PLY, OFF, STL or GLB file, the counts its
    header declares are compared with what the file holds (see :data:`HEADER_CHECKS`): a
    200-byte file that declares 10**12 vertices is refused at once, without allocating
    for them. A ``.gz`` file may inflate to at most
    :data:`~meshbits.formats.sniff.GZIP_MAX_RATIO` times its size (at least
    :data:`~meshbits.formats.sniff.GZIP_MIN_LIMIT` bytes): beyond that it is refused as a
    decompression bomb.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    MeshFileError
        The file cannot be parsed, its header disagrees with its content, it holds no
        triangles, or it holds NaN or infinite coordinates or vertex indices out of range
        (a ``ValueError``). Nothing else, whatever the file holds.
    """
    read = read_mesh(path)
    return read.vertices, read.faces


def read_mesh(path: str | Path) -> MeshRead:
    """Read a triangle mesh file as :func:`load_mesh` does, with what reading changed.

    An uncompressed PLY (binary either endian, or ASCII), STL (binary or ASCII) or OBJ is
    read by the Rust reader of :mod:`.native`: memory-mapped, parsed in parallel into the
    returned arrays, polygons fan-triangulated and counted. A file it does not read exactly
    as trimesh would (another layout, or any damage) goes the general path, whose header
    checks and messages apply: the result is then ``reader="trimesh"``.

    Raises
    ------
    FileNotFoundError, MeshFileError
        As :func:`load_mesh`.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such mesh file: {path}")
    file_type, compressed = file_type_of(path)
    if not compressed and file_type in NATIVE_FORMATS:
        native = read_native(path, file_type)
        if native is not None:
            return native
    vertices, faces = load_general(path)
    return MeshRead(vertices, faces, "trimesh")


def load_general(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The general path of :func:`load_mesh`: the header checks, then trimesh (or
    meshbits's glTF reader, or DracoPy); faces as ``uint32``."""
    # trimesh is imported on first use: it takes longer to import than meshbits.
    import trimesh

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
        return as_mesh(vertices, faces)
    except MeshbitsError as err:
        raise MeshFileError(f"{path}: {err}") from err


def parse_mesh_file(path: Path, source: Path | io.BytesIO, file_type: str, compressed: bool) -> Any:
    """A checked mesh file (what :func:`checked_mesh_file` returned for ``path``) as a
    trimesh object: a Draco file (what ``meshbits compress -o x.drc`` writes) decoded with
    DracoPy; a GLB or glTF read by meshbits's glTF reader (the one the scene commands
    use: it decodes ``EXT_meshopt_compression``, ``KHR_meshopt_compression`` and
    ``KHR_draco_mesh_compression`` and checks every reference first), its triangle
    primitives in world coordinates as one; anything else parsed by trimesh.

    One glTF reader serves every command: trimesh does not decode meshopt, read a Draco
    primitive it could not decode as zeros with only a log message (a GLB with one byte
    of its Draco data changed gave ``k`` a mesh at the origin), and refused a valid
    document whose root node holds a skin and a camera ("No path from world->1!")."""
    import trimesh

    if file_type == "drc":
        data = source.read() if isinstance(source, io.BytesIO) else path.read_bytes()
        return trimesh.Trimesh(*read_drc(data, path), process=False)
    if file_type in ("glb", "gltf"):
        if isinstance(source, io.BytesIO):
            document = read_gltf(path, file_type, source.getvalue())
        else:
            document = load_document(path)
        try:
            vertices, faces = document.world_triangles()
        except MeshFileError as err:
            raise MeshFileError(f"cannot read {path}: {err}") from None
        return trimesh.Trimesh(vertices, faces, process=False)
    if compressed:
        return trimesh.load(source, file_type=file_type, process=False)
    return trimesh.load(path, process=False)


def load_document(path: str | Path) -> Document:
    """Read a scene file into a glTF document.

    ``.glb`` and ``.gltf`` (with its buffers and images) are read as they are; OBJ (with
    its MTL and textures), PLY (with colours), STL, OFF and the rest of what trimesh
    reads, gzip-compressed too, go through trimesh's glTF export.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    MeshFileError
        The file cannot be read as a scene.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    suffix = path.suffix.lower()
    try:
        if suffix in (".glb", ".gltf"):
            return read_gltf(path, suffix.lstrip("."))
        # Checked and parsed as load_mesh does; its messages name the file.
        source, file_type, compressed = checked_mesh_file(path)
        loaded = parse_mesh_file(path, source, file_type, compressed)
        return document_from_trimesh(loaded, path, file_type)
    except (MeshbitsError, FileNotFoundError):
        raise
    except Exception as err:
        suffixes = [x.lower() for x in path.suffixes]
        kind = suffixes[-2] if suffix == ".gz" and len(suffixes) > 1 else suffix
        raise MeshFileError(f"cannot read {path}: {explain(kind.lstrip('.'), err)}") from err


def save_mesh(path: str | Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """Write a mesh atomically; the format is picked from the file extension (PLY, OBJ,
    STL, OFF, GLB, glTF). A ``.gltf`` gets its buffer beside it, named after it
    (``out.gltf`` and ``out.bin``)."""
    import trimesh

    path = Path(path)
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    suffix = path.suffix.lower().lstrip(".")
    if suffix in ("glb", "gltf"):
        return write_mesh(path, mesh)
    if suffix in ("obj", "off"):
        return write_atomic(path, obj.text_mesh(suffix, mesh.vertices, mesh.faces))
    data = mesh.export(file_type=suffix)
    return write_atomic(path, data.encode() if isinstance(data, str) else data)
