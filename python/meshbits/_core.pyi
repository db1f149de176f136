"""Typed stubs for the native module ``meshbits._core`` (see ``rust/python/``)."""

import os
from typing import TypedDict, final

import numpy as np
import numpy.typing as npt

# What the kernels return, key by key (the dicts are plain ``dict`` at runtime; these names
# exist only for type checkers). Lengths in the mesh's units.

_Codes = npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.uint32]

class _ComplexityBase(TypedDict):
    k_raw: float
    area: float
    bbox_min: list[float]
    bbox_max: list[float]
    edges: int
    interior_edges: int
    boundary_edges: int
    nonmanifold_edges: int
    flat_edges: int
    ill_conditioned_edges: int
    degenerate_edges: int
    merged_vertices: int
    degenerate_faces: int

class _ComplexityDict(_ComplexityBase, total=False):
    """With ``per_edge``: one row per unique edge."""

    edge_vertices: npt.NDArray[np.uint32]
    edge_kind: npt.NDArray[np.uint8]
    edge_radius: npt.NDArray[np.float64]
    edge_weight: npt.NDArray[np.float64]
    edge_contribution: npt.NDArray[np.float64]

class _DirectedBase(TypedDict):
    n_samples: int
    n_vertex_samples: int
    max: float
    argmax: list[float]
    argmax_closest: list[float]
    argmax_face: int

class _DirectedDict(_DirectedBase, total=False):
    """``statistics``: mean .. p99; ``bounds``: upper .. converged; ``return_samples``:
    samples .. vertex_distances."""

    mean: float
    rms: float
    p50: float
    p95: float
    p99: float
    upper: float
    refined_points: int
    refined_cells: int
    converged: bool | None
    samples: npt.NDArray[np.float64]
    sample_faces: npt.NDArray[np.uint32]
    distances: npt.NDArray[np.float64]
    vertex_distances: npt.NDArray[np.float64]

class _SamplesDict(TypedDict):
    points: npt.NDArray[np.float64]
    faces: npt.NDArray[np.uint32]
    n_vertex_samples: int

class _GridDict(TypedDict):
    origin: list[float]
    step: list[float]
    box_min: list[float]
    box_max: list[float]
    grid_size: float
    bound: float
    bits: int

class _QuantizedDict(_GridDict):
    codes: _Codes
    positions: npt.NDArray[np.float64]
    max_displacement: float

class _ClusteredDict(_GridDict):
    vertices: npt.NDArray[np.float64]
    faces: npt.NDArray[np.uint32]
    codes: _Codes
    vertex_map: npt.NDArray[np.int64]
    face_index: npt.NDArray[np.uint32]
    merged_vertices: int
    unreferenced_vertices: int
    degenerate_faces: int
    duplicate_faces: int
    max_displacement: float

class _SimplifiedBase(TypedDict):
    vertex_ids: npt.NDArray[np.uint32]
    faces: npt.NDArray[np.uint32]
    error: float

class _SimplifiedDict(_SimplifiedBase, total=False):
    """``update_positions``: the moved positions and attributes."""

    positions: npt.NDArray[np.float64]
    attributes: npt.NDArray[np.float32]

__all__ = [
    "BUILD_PROFILE",
    "EmptyMeshError",
    "IndexOutOfRangeError",
    "MeshbitsError",
    "NonFiniteError",
    "OutsideBoxError",
    "ParameterError",
    "SampledMesh",
    "ShapeError",
    "TriangleTree",
    "__version__",
    "box_overlap",
    "build_tree",
    "build_trees",
    "cluster",
    "dequantize",
    "faces_as_u32",
    "get_num_threads",
    "hausdorff_directed",
    "hausdorff_from_samples",
    "meshopt_decode",
    "meshopt_encode_exponential",
    "meshopt_encode_octahedral",
    "meshopt_encode_quaternions",
    "meshopt_encode_triangles",
    "meshopt_encode_vertices",
    "meshopt_reorder",
    "quantize",
    "read_mesh",
    "sample_mesh",
    "set_num_threads",
    "shape_complexity",
    "simplify",
    "surface_samples",
    "weld",
]
__version__: str
BUILD_PROFILE: str

class MeshbitsError(ValueError): ...

# One class per refusal of the kernels (``rust/error.rs``), all under ``MeshbitsError``.
class ShapeError(MeshbitsError): ...
class NonFiniteError(MeshbitsError): ...
class IndexOutOfRangeError(MeshbitsError): ...
class EmptyMeshError(MeshbitsError): ...
class ParameterError(MeshbitsError): ...
class OutsideBoxError(MeshbitsError): ...

def shape_complexity(
    vertices: npt.NDArray[np.float64],
    faces: npt.NDArray[np.uint32] | npt.NDArray[np.int64],
    estimator: str,
    merge_vertices: bool,
    per_edge: bool,
    flat_angle: float,
    ill_angle: float,
    ill_cocircular: float,
) -> _ComplexityDict: ...

@final
class TriangleTree:
    @property
    def n_faces(self) -> int: ...
    @property
    def n_vertices(self) -> int: ...
    @property
    def depth(self) -> int: ...
    @property
    def centre(self) -> list[float]: ...
    @property
    def box_overlap(self) -> float: ...
    def query(
        self, points: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.uint32]]: ...
    def farther_than(
        self, points: npt.NDArray[np.float64], distance: float
    ) -> npt.NDArray[np.bool_]: ...
    def validate(self) -> None: ...

def build_tree(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.uint32]
) -> TriangleTree: ...
def build_trees(
    meshes: list[tuple[npt.NDArray[np.float64], npt.NDArray[np.uint32]]],
) -> list[TriangleTree]: ...
def hausdorff_directed(
    vertices: npt.NDArray[np.float64],
    faces: npt.NDArray[np.uint32],
    tree: TriangleTree,
    samples: int,
    seed: int,
    statistics: bool,
    bounds: bool,
    tolerance: float | None,
    refine_budget: int,
    return_samples: bool,
    threshold: float | None = None,
    relative_tolerance: float | None = None,
) -> _DirectedDict: ...
def surface_samples(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.uint32], samples: int, seed: int
) -> _SamplesDict: ...
def quantize(
    vertices: npt.NDArray[np.float64],
    bits: int,
    grid: str,
    box_min: tuple[float, float, float] | None,
    box_max: tuple[float, float, float] | None,
    centered: bool,
) -> _QuantizedDict: ...
def dequantize(
    codes: npt.NDArray[np.int64],
    origin: tuple[float, float, float],
    step: tuple[float, float, float],
) -> npt.NDArray[np.float64]: ...
def box_overlap(vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.uint32]) -> float: ...
def faces_as_u32(
    faces: npt.NDArray[np.int64], vertex_count: int
) -> npt.NDArray[np.uint32] | None: ...
def read_mesh(
    path: str | os.PathLike[str], format: str
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint32], dict[str, int]] | str: ...
def meshopt_encode_vertices(data: npt.NDArray[np.uint8], stride: int) -> bytes: ...
def meshopt_encode_triangles(faces: npt.NDArray[np.uint32], vertex_count: int) -> bytes: ...
def meshopt_encode_octahedral(
    vectors: npt.NDArray[np.float32], bits: int
) -> npt.NDArray[np.uint8]: ...
def meshopt_encode_quaternions(
    quaternions: npt.NDArray[np.float32], bits: int
) -> npt.NDArray[np.uint8]: ...
def meshopt_encode_exponential(
    values: npt.NDArray[np.float32], bits: int, mode: str
) -> npt.NDArray[np.uint8]: ...
def meshopt_reorder(
    faces: npt.NDArray[np.uint32], vertex_count: int
) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint32]]: ...
def meshopt_decode(
    data: bytes, count: int, stride: int, mode: str, filter: str | None = None
) -> bytes: ...
def weld(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.uint32]
) -> tuple[npt.NDArray[np.uint32], int]: ...
def cluster(
    vertices: npt.NDArray[np.float64],
    faces: npt.NDArray[np.uint32] | npt.NDArray[np.int64],
    bits: int,
    grid: str,
    box_min: tuple[float, float, float] | None,
    box_max: tuple[float, float, float] | None,
    centered: bool,
    duplicates: str,
) -> _ClusteredDict: ...

@final
class SampledMesh:
    @property
    def n_samples(self) -> int: ...
    @property
    def n_vertex_samples(self) -> int: ...

def sample_mesh(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.uint32], samples: int, seed: int
) -> SampledMesh: ...
def hausdorff_from_samples(
    source: SampledMesh,
    tree: TriangleTree,
    statistics: bool,
    bounds: bool,
    tolerance: float | None,
    refine_budget: int,
    return_samples: bool,
    threshold: float | None = None,
    relative_tolerance: float | None = None,
) -> _DirectedDict: ...
def simplify(
    vertices: npt.NDArray[np.float64],
    faces: npt.NDArray[np.uint32],
    target_faces: int | None,
    target_error: float | None,
    lock_border: bool,
    locked: npt.NDArray[np.bool_] | None,
    attributes: npt.NDArray[np.float32] | None,
    weights: npt.NDArray[np.float32] | None,
    prune: bool,
    weld: bool,
    update_positions: bool,
) -> _SimplifiedDict: ...
def set_num_threads(threads: int) -> None: ...
def get_num_threads() -> int: ...
