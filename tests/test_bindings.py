"""The native contract of ``meshbits._core``, called directly, without the Python layer."""

from __future__ import annotations

import numpy as np
import pytest

from meshbits import MeshbitsError, _core

TOL = (1e-12, 1e-3, 1e-3)
V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
F = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]], dtype=np.uint32)


def call(vertices, faces, estimator="circumsphere"):
    return _core.shape_complexity(vertices, faces, estimator, True, False, *TOL)


def test_release_build():
    assert _core.BUILD_PROFILE == "release", "benchmarks and tests need a release build"


def test_valid_call_returns_raw_dict():
    out = call(V, F)
    assert out["edges"] == 6 and out["interior_edges"] == 6
    assert out["k_raw"] > 0 and len(out["bbox_min"]) == 3


def test_no_implicit_dtype_cast():
    with pytest.raises(TypeError):
        call(V, F.astype(np.int32))
    with pytest.raises(TypeError):
        call(V.astype(np.float32), F)


def test_int64_faces_are_read_as_they_are():
    assert call(V, F.astype(np.int64)) == call(V, F)
    with pytest.raises(MeshbitsError, match="negative"):
        call(V, np.array([[0, 1, -1]], dtype=np.int64))


def test_layout_is_checked_in_rust():
    with pytest.raises(ValueError, match="C-contiguous"):
        call(np.asfortranarray(V), F)
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        call(np.ascontiguousarray(V[:, :2]), F)


def test_kernel_errors_are_meshbits_errors():
    with pytest.raises(MeshbitsError, match="refers to vertex 9"):
        call(V, np.array([[0, 1, 9]], dtype=np.uint32))
    bad = V.copy()
    bad[2, 1] = np.nan
    with pytest.raises(MeshbitsError, match="vertex 2 has a NaN"):
        call(bad, F)
    with pytest.raises(MeshbitsError, match="empty"):
        call(V, np.zeros((0, 3), dtype=np.uint32))
    with pytest.raises(ValueError, match="estimator"):
        call(V, F, "curvy")
    assert issubclass(MeshbitsError, ValueError)


def test_thread_setting_round_trips():
    previous = _core.get_num_threads()
    try:
        _core.set_num_threads(1)
        assert _core.get_num_threads() == 1
        assert call(V, F)["k_raw"] > 0
    finally:
        _core.set_num_threads(previous)


def test_stubs_match_the_built_module():
    """python/meshbits/_core.pyi against the compiled module, by mypy's stubtest: names,
    signatures, classes."""
    import subprocess
    import sys

    pytest.importorskip("mypy")
    run = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "meshbits._core"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stdout + run.stderr


def test_kernel_errors_pickle_across_processes():
    """Batch workers send refusals back to the parent: the exception must pickle."""
    import pickle

    error = pickle.loads(pickle.dumps(MeshbitsError("bits out of range")))
    assert isinstance(error, MeshbitsError) and str(error) == "bits out of range"
