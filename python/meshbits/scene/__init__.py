"""Scenes: a glTF document, or an OBJ / PLY with its attributes, compressed whole.

Every triangle primitive is simplified with its attributes (UV seams and hard normal edges
kept), its positions quantized at its own B found by the search of :mod:`meshbits.search`,
its other attributes at bits chosen from their own tolerance
(:mod:`meshbits.codecs.attributes`), and written with ``KHR_draco_mesh_compression``
(Draco, the default) or ``EXT_meshopt_compression`` with ``KHR_mesh_quantization``
(meshoptimizer's codecs). Nodes, materials, textures and images (bytes unchanged),
samplers, skins, animations, cameras, extras and the extensions meshbits does not touch
are copied as they were. See docs/scenes.md.

The error budget is a world-space length: a primitive's error is its mesh's error times the
largest scale of the nodes that instance it. An error budget is met by every primitive at
the fewest bytes each; a size budget is split across primitives by the common world-space
error that fills it (the split that minimises the scene's largest error).

Modules, in import order: :mod:`.primitives` (jobs: primitives sharing accessors as one
geometry, their attribute bits, their frames), :mod:`.primitive_search` (one primitive's
search through the scene's codec), :mod:`.split` (a size budget split across
primitives), :mod:`.shared_grid` (meshopt's grid shared by a frame cluster),
:mod:`.report` (:class:`PrimitiveReport`, :class:`SceneResult`), :mod:`.compress`
(:func:`compress_scene`; the document is written by :mod:`meshbits.formats.gltf.write`)
and :mod:`.info` (:func:`scene_info`, what a merged mesh leaves out).
"""

from __future__ import annotations

from ..codecs.attributes import NORMAL_TOLERANCE_DEGREES, normal_bits, uv_bits
from .compress import CODECS, better_codec, compress_scene
from .info import merged_away, omitted_by_merging, scene_info
from .report import PrimitiveReport, SceneResult

__all__ = [
    "CODECS",
    "NORMAL_TOLERANCE_DEGREES",
    "PrimitiveReport",
    "SceneResult",
    "better_codec",
    "compress_scene",
    "merged_away",
    "normal_bits",
    "omitted_by_merging",
    "scene_info",
    "uv_bits",
]
