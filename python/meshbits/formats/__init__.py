"""File formats: mesh and scene files in and out, as arrays or glTF documents.

:mod:`.open` is the dispatcher (:func:`load_mesh`, :func:`load_document`,
:func:`read_mesh`, :func:`save_mesh`); each format has its own module (:mod:`.ply`,
:mod:`.obj` for OBJ and OFF, :mod:`.stl`, :mod:`.drc`, :mod:`.gltf`), :mod:`.native`
holds the Rust readers of PLY, STL and OBJ, and :mod:`.sniff` holds what they share
before a parser reads a file. Formats import leaves (errors, files, mesh, _core), never
the dispatcher, nor the codecs (which import formats: glTF's constants, Draco's decoder).
"""

from __future__ import annotations

from .gltf import Document, PrimitiveData
from .native import MeshRead
from .open import example_mesh_path, load_document, load_mesh, read_mesh, save_mesh

__all__ = [
    "Document",
    "MeshRead",
    "PrimitiveData",
    "example_mesh_path",
    "load_document",
    "load_mesh",
    "read_mesh",
    "save_mesh",
]
