"""Typed stubs for the native module ``meshbits._core`` (see ``rust/python.rs``)."""

from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "BUILD_PROFILE",
    "MeshbitsError",
    "TriangleTree",
    "__version__",
    "build_tree",
    "build_trees",
    "cluster",
    "dequantize",
    "faces_as_u32",
    "get_num_threads",
    "hausdorff_directed",
    "quantize",
    "set_num_threads",
    "shape_complexity",
    "surface_samples",
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
def set_num_threads(threads: int) -> None: ...
def get_num_threads() -> int: ...
