"""Typed stubs for the native module ``meshbits._core`` (see ``rust/python.rs``)."""

from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "BUILD_PROFILE",
    "MeshbitsError",
    "SampledMesh",
    "TriangleTree",
    "__version__",
    "build_tree",
    "build_trees",
    "cluster",
    "dequantize",
    "faces_as_u32",
    "get_num_threads",
    "hausdorff_directed",
    "hausdorff_from_samples",
    "meshopt_encode_octahedral",
    "meshopt_encode_triangles",
    "meshopt_encode_vertices",
    "meshopt_reorder",
    "quantize",
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

def shape_complexity(
    vertices: npt.NDArray[np.float64],
    faces: npt.NDArray[np.uint32],
    estimator: str,
    merge_vertices: bool,
    per_edge: bool,
    flat_angle: float,
    ill_angle: float,
    ill_cocircular: float,
) -> dict[str, Any]: ...

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
    def query(
        self, points: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.uint32]]: ...
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
) -> dict[str, Any]: ...
def surface_samples(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.uint32], samples: int, seed: int
) -> dict[str, Any]: ...
def quantize(
    vertices: npt.NDArray[np.float64],
    bits: int,
    grid: str,
    box_min: tuple[float, float, float] | None,
    box_max: tuple[float, float, float] | None,
    centered: bool,
) -> dict[str, Any]: ...
def dequantize(
    codes: npt.NDArray[np.int64],
    origin: tuple[float, float, float],
    step: tuple[float, float, float],
) -> npt.NDArray[np.float64]: ...
def faces_as_u32(
    faces: npt.NDArray[np.int64], vertex_count: int
) -> npt.NDArray[np.uint32] | None: ...
def meshopt_encode_vertices(data: npt.NDArray[np.uint8], stride: int) -> bytes: ...
def meshopt_encode_triangles(faces: npt.NDArray[np.uint32], vertex_count: int) -> bytes: ...
def meshopt_encode_octahedral(
    vectors: npt.NDArray[np.float32], bits: int
) -> npt.NDArray[np.uint8]: ...
def meshopt_reorder(
    faces: npt.NDArray[np.uint32], vertex_count: int
) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint32]]: ...
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
) -> dict[str, Any]: ...

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
) -> dict[str, Any]: ...
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
) -> dict[str, Any]: ...
def set_num_threads(threads: int) -> None: ...
def get_num_threads() -> int: ...
