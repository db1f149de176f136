"""meshbits: how many vertices, and how many bits per coordinate, should this mesh keep?

An implementation of King & Rossignac, "Optimal Bit Allocation in 3D Compression" (1999):
shape complexity K, grid quantization, the sampled Hausdorff distance, and the analytic
solvers that pick B and V from a size or error budget.
"""

from __future__ import annotations

import os

from . import _core
from ._core import MeshbitsError
from .complexity import ShapeComplexity, shape_complexity
from .io import example_mesh_path, load_mesh, save_mesh
from .quantize import Clustered, Quantized, cluster, dequantize, quantize
from .threads import get_num_threads, set_num_threads, threads

__version__: str = _core.__version__

__all__ = [
    "Clustered",
    "MeshbitsError",
    "Quantized",
    "ShapeComplexity",
    "__version__",
    "cluster",
    "dequantize",
    "example_mesh_path",
    "get_num_threads",
    "load_mesh",
    "quantize",
    "save_mesh",
    "set_num_threads",
    "shape_complexity",
    "threads",
]

if hasattr(os, "register_at_fork"):
    # A child forked after the parent used rayon's pool can hang on it: children run on a
    # fresh one-thread pool instead.
    os.register_at_fork(after_in_child=lambda: _core.set_num_threads(1))
