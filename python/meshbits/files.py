"""Files on disk: an asset's files, written atomically, never over an input.

An asset is one file and, for a ``.gltf``, the buffers and images it names by relative
URI, or for an OBJ, its material libraries and their textures: :func:`external_files`
lists them from their names alone (nothing is parsed beyond the references), so that an
output is refused before any work when it would replace one of them
(:func:`check_not_an_input`), and a report counts the asset's whole size
(:func:`asset_bytes`). This module imports nothing else of meshbits but its errors: every
writer uses it.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from urllib.parse import unquote

from .errors import MeshbitsError

__all__ = [
    "asset_bytes",
    "check_not_an_input",
    "check_writable",
    "external_files",
    "write_atomic",
]

#: MTL statements naming a texture file (its last word; options come before it).
MTL_MAPS = (
    b"map_",
    b"bump",
    b"disp",
    b"decal",
    b"refl",
    b"norm",
)


def _obj_files(path: Path) -> list[tuple[str, Path]]:
    """The material libraries an OBJ names (``mtllib``) and the textures those that exist
    name, as ``(name, path)``."""
    out: list[tuple[str, Path]] = []
    try:
        with path.open("rb") as lines:
            libraries = [
                name
                for line in lines
                if line.startswith(b"mtllib")
                for name in line[6:].decode("utf-8", "replace").split()
            ]
    except OSError:
        return []
    for name in libraries:
        library = path.parent / name
        out.append((name, library))
        try:
            text = library.read_bytes().splitlines()
        except OSError:
            continue
        for line in text:
            words = line.strip().split()
            if len(words) >= 2 and words[0].lower().startswith(MTL_MAPS):
                texture = _texture_name(words[1:], library.parent)
                out.append((texture, library.parent / texture))
    return out


def _texture_name(words: list[bytes], folder: Path) -> str:
    """The file an MTL map statement names: its last word, or its last words joined by
    spaces when those name a file there (``map_Kd fuze uv.jpg``; options come first)."""
    names = [b" ".join(words[-k:]).decode("utf-8", "replace") for k in range(1, len(words) + 1)]
    return next((name for name in names if (folder / name).is_file()), names[0])


def external_files(path: str | Path) -> list[tuple[str, Path]]:
    """The files a ``.gltf`` names by relative URI (its buffers, then its images), or an
    OBJ (its material libraries and their textures), as ``(name, path)``, whether they
    exist or not; none for any other file, or for one that cannot be read as JSON (its
    reader says why when it is loaded)."""
    path = Path(path)
    if path.suffix.lower() == ".obj":
        return _obj_files(path)
    if path.suffix.lower() != ".gltf":
        return []
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        uris = [
            item.get("uri")
            for key in ("buffers", "images")
            for item in document.get(key, [])
            if isinstance(item, dict)
        ]
    except (OSError, ValueError, AttributeError, TypeError):
        return []
    return [
        (uri, path.parent / unquote(uri))
        for uri in uris
        if isinstance(uri, str) and uri and not uri.startswith("data:") and "://" not in uri
    ]


def asset_bytes(path: str | Path) -> int:
    """A file's bytes; for a ``.gltf``, with the buffers and images it names by relative
    URI, for an OBJ with its material libraries and textures (the asset's whole size)."""
    path = Path(path)
    parts = {part.resolve() for _, part in external_files(path) if part.is_file()}
    return path.stat().st_size + sum(part.stat().st_size for part in parts)


def check_not_an_input(path: str | Path, *inputs: str | Path | None) -> Path:
    """Refuse an output that would replace an input: ``path`` itself or, for a ``.gltf``
    output, the buffer file written beside it (``out.bin``), when it is one of
    ``inputs`` or a file a ``.gltf`` input names (its buffers and images); the same file
    by any path (a symlink, a hard link) counts."""
    path = Path(path)
    written = [path]
    if path.suffix.lower() == ".gltf":
        written.append(path.with_name(f"{path.stem}.bin"))
    for given in inputs:
        if given is None:
            continue
        given = Path(given)
        for read in [given, *(part for _, part in external_files(given))]:
            for target in written:
                if _same_file(target, read):
                    what = "" if read == given else f" (a file {given} refers to)"
                    raise MeshbitsError(
                        f"cannot write {target}: it is the input {read}{what}; write the "
                        "output elsewhere"
                    )
    return path


def _same_file(a: Path, b: Path) -> bool:
    """Whether two paths name the same file (the same inode when both exist)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


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
