"""The search of a primitive with morph targets (meshopt): its vertices all kept (a
target's displacements would have to follow a simplification), its positions and the
targets' position displacements on one grid of step ``s``, and the fewest bits whose
certified bound over every weight in [0, 1] per target is within the budget.

The budget is not split between the base positions and the displacements by a rule: both
are rounded to the same step ``s`` (as gltfpack does; the displacements are stored in
steps, so the one dequantization of the node or skin scales them), and the bound of the
morphed mesh, :func:`meshbits.codecs.morph_targets.morph_bound`, is measured exactly for
each candidate ``s``: the largest ``|e_0 + sum_i w_i e_i|`` over the corners of the
weight cube, ``e_0`` a vertex's rounding and ``e_i`` its displacements'.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..codecs.primitive import PrimitiveEncoding
from ..codecs.quantized import MESHOPT_MAX_BITS, encode_meshopt_primitive
from ..quantize import cube_grid
from ..search import Iteration, Level
from .primitives import Job, Outcome

__all__ = ["morph_encoding", "search_morph"]


def morph_encoding(job: Job, bits: int, origin: np.ndarray, side: float) -> PrimitiveEncoding:
    """The job's primitive and its targets at ``bits`` on the cube grid at ``origin`` with
    side ``side``: integer codes when its nodes or skins carry its frame, else float32."""
    data = job.data
    encoding = encode_meshopt_primitive(
        data.positions,
        data.faces,
        data.attributes,
        bits,
        origin,
        side,
        job.bits,
        integer_positions=job.framed,
        targets=data.targets,
    )
    encoding.bits = bits
    return encoding


def _first_bits(side: float, budget: float) -> int:
    """A few bits below where a grid's half diagonal reaches the budget: where the search
    of bits starts (the largest rounding is often less than the half diagonal)."""
    if side <= 0 or budget <= 0:
        return 1
    return max(1, math.ceil(math.log2(side * math.sqrt(3) / 2 / budget + 1)) - 2)


def search_morph(
    job: Job, budget: float, certify: bool, constraint: str, measure: object
) -> Outcome:
    """The fewest bits of the job within ``budget`` (mesh units; with ``constraint="size"``
    the most bits within ``budget`` bits of data): its outcome, the measurement's
    ``measured_error`` the sampled distance of the base mesh (weights 0) and its
    ``measured_error_upper`` (with ``certify``) the certified bound over every weight in
    [0, 1]. ``measure`` is the job's reference (its ``hausdorff``)."""
    start = time.perf_counter()
    data = job.data
    origin, side = cube_grid(data.positions.min(axis=0), data.positions.max(axis=0))
    chosen: PrimitiveEncoding | None = None
    if constraint == "error":
        for bits in range(_first_bits(side, budget), MESHOPT_MAX_BITS + 1):
            chosen = morph_encoding(job, bits, origin, side)
            assert chosen.morph_bound is not None
            if chosen.morph_bound <= budget:
                break
    else:
        for bits in range(MESHOPT_MAX_BITS, 0, -1):
            chosen = morph_encoding(job, bits, origin, side)
            if chosen.size_bits <= budget:
                break
    assert chosen is not None and chosen.bits is not None and chosen.morph_bound is not None
    sampled = measure.hausdorff((chosen.vertices, chosen.faces)).distance  # type: ignore[attr-defined]
    met = chosen.morph_bound <= budget if constraint == "error" else chosen.size_bits <= budget
    measurement = Iteration(
        level=0,
        source="original",
        bits=chosen.bits,
        planned_vertices=len(data.positions),
        vertices=len(data.positions),
        faces=len(data.faces),
        predicted_error=chosen.morph_bound,
        predicted_size_bits=chosen.size_bits,
        measured_error=min(sampled, chosen.morph_bound),
        measured_size_bits=chosen.size_bits,
        measured_error_upper=chosen.morph_bound if certify else None,
        met=met,
        seconds=time.perf_counter() - start,
    )
    level = Level(
        source="original",
        vertices=data.positions,
        faces=data.faces,
        attributes=data.attributes or None,
        origin=origin,
        grid_size=side,
    )
    return measurement, chosen, level
