"""The native module's exception classes: one per kind of refusal, each a MeshbitsError
and a ValueError, raised for its case with the kernel's message, picklable."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import meshbits
from meshbits import _core, errors
from meshbits.errors import (
    EmptyMeshError,
    IndexOutOfRangeError,
    MeshbitsError,
    NonFiniteError,
    OutsideBoxError,
    ParameterError,
    ShapeError,
)

V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
F = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]], dtype=np.uint32)
CLASSES = [
    ShapeError,
    NonFiniteError,
    IndexOutOfRangeError,
    EmptyMeshError,
    ParameterError,
    OutsideBoxError,
]


def complexity(vertices, faces, estimator="circumsphere"):
    return _core.shape_complexity(vertices, faces, estimator, True, False, 1e-12, 1e-3, 1e-3)


@pytest.mark.parametrize("cls", CLASSES)
def test_each_class_is_a_meshbits_error_and_a_value_error(cls):
    assert issubclass(cls, MeshbitsError) and issubclass(cls, ValueError)
    assert cls is not MeshbitsError
    assert getattr(_core, cls.__name__) is cls
    assert cls.__name__ in errors.__all__
    error = pickle.loads(pickle.dumps(cls("a message")))
    assert type(error) is cls and str(error) == "a message"


def test_the_package_names_are_unchanged():
    for cls in CLASSES:
        assert cls.__name__ not in meshbits.__all__
    assert meshbits.MeshbitsError is MeshbitsError


def test_shape_dtype_layout_is_a_shape_error():
    with pytest.raises(ShapeError, match=r"vertices must have shape \(n, 3\), got \(4, 2\)"):
        complexity(np.ascontiguousarray(V[:, :2]), F)
    with pytest.raises(ShapeError, match="vertices must be C-contiguous"):
        _core.build_tree(np.asfortranarray(V), F)
    with pytest.raises(ShapeError, match=r"C-contiguous \(n, 4\) float32"):
        _core.meshopt_encode_octahedral(np.zeros((3, 3), dtype=np.float32), 8)


def test_a_nan_vertex_is_a_non_finite_error():
    bad = V.copy()
    bad[2, 1] = np.nan
    with pytest.raises(NonFiniteError, match=r"^vertex 2 has a NaN or infinite coordinate$"):
        complexity(bad, F)
    with pytest.raises(NonFiniteError, match="vertex 2 has a NaN"):
        _core.build_tree(bad, F)
    tree = _core.build_tree(V, F)
    with pytest.raises(NonFiniteError, match="vertex 2 has a NaN"):
        _core.hausdorff_directed(bad, F, tree, 100, 0, False, False, None, 0, False)


def test_a_face_index_out_of_range_is_an_index_out_of_range_error():
    with pytest.raises(IndexOutOfRangeError, match="face 0 refers to vertex 9, out of range"):
        complexity(V, np.array([[0, 1, 9]], dtype=np.uint32))
    with pytest.raises(IndexOutOfRangeError, match=r"negative vertex index \(-1\)"):
        complexity(V, np.array([[0, 1, -1]], dtype=np.int64))
    with pytest.raises(IndexOutOfRangeError, match="refers to vertex 7"):
        _core.meshopt_encode_triangles(np.array([[0, 1, 7]], dtype=np.uint32), 4)


def test_no_faces_is_an_empty_mesh_error():
    none = np.zeros((0, 3), dtype=np.uint32)
    with pytest.raises(EmptyMeshError, match="empty"):
        complexity(V, none)
    with pytest.raises(EmptyMeshError, match="the tree holds no triangles"):
        _core.build_tree(V, none).query(V)


def test_a_parameter_out_of_range_is_a_parameter_error():
    with pytest.raises(ParameterError, match="bits must be an integer from 1 to 32, got 0"):
        _core.quantize(V, 0, "cube", None, None, False)
    with pytest.raises(ParameterError, match="grid must be 'cube' or 'axes'"):
        _core.quantize(V, 8, "sphere", None, None, False)
    with pytest.raises(ParameterError, match="estimator must be"):
        complexity(V, F, "curvy")
    with pytest.raises(ParameterError, match="unknown meshopt mode"):
        _core.meshopt_decode(b"", 0, 4, "STRIPS")


def test_a_point_outside_the_box_is_an_outside_box_error():
    with pytest.raises(OutsideBoxError, match=r"^point 1 lies outside the quantization box$"):
        _core.quantize(V, 8, "cube", (0.0, 0.0, 0.0), (0.5, 1.0, 1.0), False)
