"""Codecs: one mesh, or one glTF primitive, to bytes, and what a decoder gets back.

:mod:`.draco` (Draco, meshes and primitives), :mod:`.quantized` (meshoptimizer's glTF
codecs under ``KHR_mesh_quantization``), :mod:`.fixed_width` (quantized PLY and GLB, and
their sizes), :mod:`.size_model` (Eq. 1's alpha and T fitted to measured sizes),
:mod:`.attributes` (bits of normals, texture coordinates, colours, weights),
:mod:`.primitive` (what a primitive encoder returns, and its signature), :mod:`.encoded`
(what a mesh encoder returns) and :mod:`.dispatch` (:func:`encode`, by format name).
Codecs import the kernels, ``meshbits.formats`` (glTF's constants, Draco's decoder) and
leaves; nothing here imports the search, compress or scene.
"""

from __future__ import annotations

from .dispatch import encode
from .draco import draco_codes, encode_draco
from .encoded import Encoded
from .fixed_width import encode_quantized_glb, encode_quantized_ply, fixed_width_size_bits
from .size_model import SizeModelFit, fit_size_model

__all__ = [
    "Encoded",
    "SizeModelFit",
    "draco_codes",
    "encode",
    "encode_draco",
    "encode_quantized_glb",
    "encode_quantized_ply",
    "fit_size_model",
    "fixed_width_size_bits",
]
