"""Time the model solvers (pure Python + numpy). Prints a table; asserts nothing.

python benches/bench_model.py
"""

from __future__ import annotations

import time

import numpy as np

from meshbits import model


def per_call(fn, repeat: int) -> float:
    fn()
    start = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - start) / repeat


def main() -> None:
    rng = np.random.default_rng(0)
    vertices = 10.0 ** rng.uniform(2, 9, 100_000)
    rows = [
        (
            "plan_for_size(1e5 bits, K=50), exact",
            per_call(
                lambda: model.plan_for_size(
                    1e5, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
                ),
                200,
            ),
        ),
        (
            "plan_for_size(1e5 bits, K=50), asymptotic",
            per_call(
                lambda: model.plan_for_size(
                    1e5, 50.0, method="asymptotic", grid_size=1.0, alpha=1.0, connectivity_bits=4.0
                ),
                200,
            ),
        ),
        (
            "plan_for_error(1e-3, K=50), exact",
            per_call(
                lambda: model.plan_for_error(
                    1e-3, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
                ),
                200,
            ),
        ),
        (
            "plan_for_vertices(1e4, K=50), exact",
            per_call(
                lambda: model.plan_for_vertices(
                    1e4, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
                ),
                200,
            ),
        ),
        (
            "optimal_bits, 100000 vertex counts, exact",
            per_call(
                lambda: model.optimal_bits(vertices, 50.0, alpha=1.0, connectivity_bits=4.0), 3
            ),
        ),
        (
            "tessellation_error, 100000 vertex counts",
            per_call(lambda: model.tessellation_error(vertices, 50.0, grid_size=1.0), 20),
        ),
    ]
    width = max(len(name) for name, _ in rows)
    print(f"{'call':<{width}}  time")
    for name, seconds in rows:
        print(f"{name:<{width}}  {seconds * 1e3:9.3f} ms")


if __name__ == "__main__":
    main()
