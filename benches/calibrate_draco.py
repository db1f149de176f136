"""Fit the size model F = (3 alpha B + T) V (paper Eq. 1) to real Draco encodings.

Reproduces the defaults ``DRACO_ALPHA`` and ``DRACO_CONNECTIVITY_BITS`` in
``meshbits/constants.py``: each mesh simplified to 500, 2,000 and 8,000 vertices, encoded
at B = 6, 8, ..., 16 with Draco compression level 7.

    python benches/calibrate_draco.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from meshbits import example_mesh_path, load_mesh
from meshbits.codecs import encode_draco, fit_size_model
from meshbits.simplify import simplify

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"
MESHES = [example_mesh_path()] + [DATA / f"{n}.ply" for n in ("bunny", "horse", "hand", "fandisk")]


def main() -> None:
    rows = []
    print("| mesh | alpha | T (bits/vertex) | relative RMS |")
    print("|---|---:|---:|---:|")
    for path in MESHES:
        mesh = load_mesh(path)
        own = []
        for target in (500, 2000, 8000):
            level = simplify(mesh, target).mesh
            for bits in range(6, 17, 2):
                encoded = encode_draco(level, bits)
                own.append((bits, len(encoded.vertices), encoded.size_bits))
        fit = fit_size_model(*map(np.array, zip(*own, strict=True)))
        print(
            f"| {path.stem} | {fit.alpha:.3f} | {fit.connectivity_bits:.2f} | "
            f"{fit.relative_rms:.1%} |"
        )
        rows += own
    fit = fit_size_model(*map(np.array, zip(*rows, strict=True)))
    print(
        f"| all ({fit.samples} encodings) | {fit.alpha:.3f} | {fit.connectivity_bits:.2f} | "
        f"{fit.relative_rms:.1%} |"
    )


if __name__ == "__main__":
    main()
