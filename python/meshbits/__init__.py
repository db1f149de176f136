"""meshbits: how many vertices, and how many bits per coordinate, should this mesh keep?

An implementation of King & Rossignac, "Optimal Bit Allocation in 3D Compression" (1999):
shape complexity K, grid quantization, the sampled Hausdorff distance, and the analytic
solvers that pick B and V from a size or error budget.
"""

from __future__ import annotations

from . import _core, model
from ._core import MeshbitsError
from .batch import BatchInterrupted, BatchResult, BatchRow, batch
from .complexity import ShapeComplexity, shape_complexity
from .compress import CompressResult, Iteration, compress, compress_in_frame
from .formats import example_mesh_path, load_mesh, save_mesh
from .hausdorff import (
    Closest,
    ClosestPoints,
    DirectedHausdorff,
    Hausdorff,
    Reference,
    SurfaceSamples,
    hausdorff,
    surface_samples,
)
from .model import (
    Allocation,
    guaranteed_bits,
    plan_for_error,
    plan_for_size,
    plan_for_vertices,
)
from .quantize import (
    Clustered,
    Quantized,
    cluster,
    cube_grid,
    dequantize,
    precision_bits,
    quantize,
)
from .results import Progress
from .scene import SceneResult, compress_scene
from .simplify import Simplified, simplify
from .threads import get_num_threads, set_num_threads, threads
from .units import parse_length, parse_size

__version__: str = _core.__version__

__all__ = [
    "Allocation",
    "BatchInterrupted",
    "BatchResult",
    "BatchRow",
    "Closest",
    "ClosestPoints",
    "Clustered",
    "CompressResult",
    "DirectedHausdorff",
    "Hausdorff",
    "Iteration",
    "MeshbitsError",
    "Progress",
    "Quantized",
    "Reference",
    "SceneResult",
    "ShapeComplexity",
    "Simplified",
    "SurfaceSamples",
    "__version__",
    "batch",
    "cluster",
    "compress",
    "compress_in_frame",
    "compress_scene",
    "cube_grid",
    "dequantize",
    "example_mesh_path",
    "get_num_threads",
    "guaranteed_bits",
    "hausdorff",
    "load_mesh",
    "model",
    "parse_length",
    "parse_size",
    "plan_for_error",
    "plan_for_size",
    "plan_for_vertices",
    "precision_bits",
    "quantize",
    "save_mesh",
    "set_num_threads",
    "shape_complexity",
    "simplify",
    "surface_samples",
    "threads",
]
