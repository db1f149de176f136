"""The inputs of a batch: a folder, a glob pattern, a manifest or one file; the output
name of each; and the digest that tells a rerun an input is unchanged."""

from __future__ import annotations

import csv
import glob
import hashlib
import io
import json
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from ..errors import MeshbitsError
from ..files import external_files

__all__ = [
    "IN_OUTPUT_FOLDER",
    "MANIFEST_SUFFIXES",
    "MESH_SUFFIXES",
    "Inputs",
    "find_inputs",
    "input_digest",
    "output_names",
]

#: File names searched for in a folder or a glob's matches (case-insensitive).
MESH_SUFFIXES = (".ply.gz", ".ply", ".obj", ".stl", ".off", ".glb", ".gltf", ".drc")
#: What a manifest file is named like.
MANIFEST_SUFFIXES = (".csv", ".jsonl", ".ndjson")


@dataclass(frozen=True)
class Inputs:
    """The files of a batch.

    Attributes
    ----------
    root : Path
        The folder outputs are mirrored from.
    paths : tuple of Path
        Distinct input files (absolute), sorted for a folder or glob, in manifest order.
    ignored : dict
        Files seen that are not mesh files, counted by suffix (``"(none)"``: no suffix), and
        mesh files inside the output folder (``"(in the output folder)"``).
    duplicates : int
        Paths listed more than once.
    blank : int
        Manifest rows without a path.
    """

    root: Path
    paths: tuple[Path, ...]
    ignored: dict[str, int]
    duplicates: int = 0
    blank: int = 0


def _mesh_suffix(name: str) -> str | None:
    lower = name.lower()
    return next((s for s in MESH_SUFFIXES if lower.endswith(s)), None)


#: The key of ``ignored`` that counts mesh files skipped because they are inside the
#: output folder (earlier outputs, never inputs).
IN_OUTPUT_FOLDER = "(in the output folder)"


def _ignored_suffix(path: Path) -> str:
    return path.suffix.lower() or "(none)"


def _is_glob(text: str) -> bool:
    return any(c in text for c in "*?[")


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
    except ValueError:
        return False
    return True


def find_inputs(source: str | os.PathLike[str], *, exclude: str | Path | None = None) -> Inputs:
    """The mesh files named by ``source``.

    Parameters
    ----------
    source
        A folder (searched recursively for ``.ply .ply.gz .obj .stl .off .glb .gltf .drc``), a
        glob pattern (``**`` matches sub-folders), a manifest (``.csv`` with a ``path``
        column, or ``.jsonl`` / ``.ndjson`` with a ``"path"`` key on each line; relative
        paths are relative to the manifest's folder), or one mesh file.
    exclude
        A folder whose files are never inputs (the output folder).

    Raises
    ------
    MeshbitsError
        Nothing is at ``source``, or a manifest cannot be read.
    """
    text = os.fspath(source)
    path = Path(text).expanduser()
    skip = Path(exclude).expanduser().resolve() if exclude is not None else None
    ignored: Counter[str] = Counter()

    def keep(found: Path) -> bool:
        if skip is not None and _inside(found.resolve(), skip):
            if _mesh_suffix(found.name) is not None:
                ignored[IN_OUTPUT_FOLDER] += 1
            return False
        if _mesh_suffix(found.name) is None:
            ignored[_ignored_suffix(found)] += 1
            return False
        return True

    if path.is_dir():
        root = path.resolve()
        files = sorted(p for p in root.rglob("*") if p.is_file() and keep(p))
        return Inputs(root, tuple(p.resolve() for p in files), dict(ignored))
    if path.is_file() and path.name.lower().endswith(MANIFEST_SUFFIXES):
        return _read_manifest(path)
    if path.is_file():
        return Inputs(path.resolve().parent, (path.resolve(),), {})
    if _is_glob(text):
        parts = Path(text).expanduser().parts
        first = next(i for i, part in enumerate(parts) if _is_glob(part))
        root = (Path(*parts[:first]) if first else Path(".")).resolve()
        matches = sorted(Path(m) for m in glob.glob(str(path), recursive=True))
        files = [m.resolve() for m in matches if m.is_file() and keep(m)]
        return Inputs(root, tuple(dict.fromkeys(files)), dict(ignored))
    raise MeshbitsError(f"no such folder, file or glob match: {text}")


def _read_manifest(path: Path) -> Inputs:
    """A CSV manifest (a ``path`` column) or a JSON Lines one (a ``"path"`` key)."""
    entries: list[str] = []
    blank = 0
    try:
        content = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise MeshbitsError(f"manifest {path} is not UTF-8 text: {err}") from None
    if path.suffix.lower() == ".csv":
        reader = csv.DictReader(io.StringIO(content))
        if reader.fieldnames is None or "path" not in [n.strip() for n in reader.fieldnames]:
            raise MeshbitsError(f"manifest {path} has no 'path' column (a CSV header line)")
        column = next(n for n in reader.fieldnames if n.strip() == "path")
        for record in reader:
            value = (record.get(column) or "").strip()
            if value:
                entries.append(value)
            else:
                blank += 1
    else:
        for number, line in enumerate(content.splitlines(), start=1):
            if not line.strip():
                continue
            try:
                record = json.loads(line)
            except json.JSONDecodeError as err:
                raise MeshbitsError(f"manifest {path}, line {number}: not JSON ({err})") from None
            if not isinstance(record, dict):
                raise MeshbitsError(f"manifest {path}, line {number}: not a JSON object")
            value = record.get("path")
            if value is None or (isinstance(value, str) and not value.strip()):
                blank += 1
                continue
            if not isinstance(value, str):
                raise MeshbitsError(f"manifest {path}, line {number}: 'path' is not a string")
            entries.append(value.strip())
    folder = path.resolve().parent
    resolved = [
        (folder / Path(e).expanduser()).resolve()
        if not Path(e).expanduser().is_absolute()
        # resolve() of an absolute path only normalises it
        else Path(e).expanduser().resolve()
        for e in entries
    ]
    distinct = tuple(dict.fromkeys(resolved))
    if distinct and not all(_inside(p, folder) for p in distinct):
        root = Path(os.path.commonpath([str(p.parent) for p in distinct]))
    else:
        root = folder
    return Inputs(root, distinct, {}, duplicates=len(resolved) - len(distinct), blank=blank)


def input_digest(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes; for a ``.gltf``, also of the buffers and images it
    names by relative URI (the parts that change its meaning)."""
    path = Path(path)
    digest = hashlib.sha256()

    def feed(file: Path) -> None:
        with open(file, "rb") as handle:
            while chunk := handle.read(1 << 20):
                digest.update(chunk)

    feed(path)
    for uri, part in external_files(path):
        if part.is_file():
            digest.update(b"\0" + uri.encode() + b"\0")
            feed(part)
    return digest.hexdigest()


def output_names(inputs: Inputs, out_dir: Path, fmt: str) -> list[tuple[str, str]]:
    """(relative input, relative output) per input: the input's sub-folder under OUT_DIR,
    its name with the mesh suffix replaced by the format (``a.ply.gz`` -> ``a.drc``), or
    kept before it (``a.ply.drc``) when two inputs would write one output."""
    pairs = []
    for path in inputs.paths:
        try:
            relative = path.relative_to(inputs.root)
        except ValueError:  # pragma: no cover - the root is a common ancestor
            relative = Path(path.name)
        suffix = _mesh_suffix(relative.name) or relative.suffix
        stem = relative.name[: len(relative.name) - len(suffix)] if suffix else relative.name
        pairs.append((relative, (relative.parent / f"{stem}.{fmt}")))
    counts = Counter(str(out).lower() for _, out in pairs)
    names = []
    for relative, out in pairs:
        if counts[str(out).lower()] > 1:
            out = relative.parent / f"{relative.name}.{fmt}"
        names.append((relative.as_posix(), out.as_posix()))
    return names
