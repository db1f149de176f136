from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

DATA = Path(__file__).parent / "data"
sys.path.insert(0, str(Path(__file__).parent))


def load(name: str) -> tuple[np.ndarray, np.ndarray]:
    mesh = trimesh.load(DATA / name, process=False, force="mesh")
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


@pytest.fixture(scope="session")
def bunny() -> tuple[np.ndarray, np.ndarray]:
    return load("bunny.ply")


@pytest.fixture(scope="session")
def horse() -> tuple[np.ndarray, np.ndarray]:
    return load("horse.ply")


@pytest.fixture(
    scope="session",
    params=["bunny.ply", "horse.ply", "hand.ply", "fandisk.ply", "suzanne.ply", "bunny_res4.ply"],
)
def real_mesh(request: pytest.FixtureRequest) -> tuple[str, np.ndarray, np.ndarray]:
    return (request.param, *load(request.param))


#: numpy dtype of each glTF accessor componentType, and the components of each type: for
#: the tests' own accessor readers, written from the glTF 2.0 spec, not from meshbits.
GLTF_DTYPES = {
    5120: np.int8,
    5121: np.uint8,
    5122: np.int16,
    5123: np.uint16,
    5125: np.uint32,
    5126: np.float32,
}
GLTF_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
