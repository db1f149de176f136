"""The encodings a scene is written with: each job's search answer, and with meshopt the
jobs of one frame cluster quantized again on one shared grid (their meshes' nodes carry
one dequantization), or, where that grid misses a budget, as float32 positions."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..codecs.primitive import PrimitiveEncoding
from ..codecs.quantized import MESHOPT_INTEGER_BITS, encode_meshopt_primitive
from ..constants import CERTIFY_TOLERANCE
from ..quantize import cube_grid
from .primitive_search import search_primitive
from .primitives import Job, Outcome

__all__ = [
    "RESEARCH_SHRINK",
    "SHARED_GRID_EXTRA_BITS",
    "Encodings",
    "final_encodings",
    "shared_grids",
]

#: How many bits finer than the finest its jobs chose a cluster's shared meshopt grid
#: may go when one of them misses its budget on it (each halves the rounding).
SHARED_GRID_EXTRA_BITS = 3

#: A member that misses its budget on its cluster's shared grid is searched again within
#: its budget times this, over how far it missed (its sampled distance there over its
#: budget): its own grid's rounding, which its first answer was measured with, no longer
#: carries it.
RESEARCH_SHRINK = 0.9

#: Searches job ``i`` again within a local error budget (mesh units): its outcome.
Research = Callable[[int, float], Outcome]

#: Each job's encoding (None: kept as it was), its measured error and its certified bound
#: (None where not certified), in its mesh's units.
Encodings = tuple[list[PrimitiveEncoding | None], list[float], list[float | None]]


def final_encodings(
    jobs: list[Job],
    outcomes: list[Outcome],
    codec: str,
    certify: bool,
    target_error: float,
    margin: float,
    seed: int | None = None,
    measure: bool = True,
) -> Encodings:
    """Each job's encoding, measured error and certified bound (None where not
    certified; None encodings for jobs kept as they were): with meshopt, quantized again
    on one grid per cluster (:func:`shared_grids`; with a ``seed``, a certified member
    that misses its budget there is searched again, and ``outcomes`` takes its new
    answer)."""
    measured = [0.0 if o[0] is None else o[0].measured_error for o in outcomes]
    uppers = [None if o[0] is None or not certify else o[0].measured_error_upper for o in outcomes]
    encodings = [o[1] for o in outcomes]
    if codec == "meshopt":
        budgets = (
            [
                max(target_error - margin - job.skin_rounding, target_error / 2) / job.scale
                for job in jobs
            ]
            if certify
            else None
        )
        research: Research | None = None
        if seed is not None and certify and measure:

            def research(i: int, local: float) -> Outcome:
                return search_primitive(jobs[i], local, codec, seed, certify)

        encodings, measured, uppers = shared_grids(jobs, outcomes, budgets, measure, research)
    return encodings, measured, uppers


class _Measured:
    """The encodings of a scene's jobs as they are replaced, each measured again against
    its job's reference (and with ``budgets``, certified again against its budget)."""

    def __init__(
        self,
        jobs: list[Job],
        outcomes: list[Outcome],
        budgets: list[float] | None,
        measure: bool,
    ) -> None:
        self.jobs, self.budgets, self.measure = jobs, budgets, measure
        self.encodings: list[Any] = [o[1] for o in outcomes]
        self.measured = [0.0 if o[0] is None else o[0].measured_error for o in outcomes]
        self.uppers = [None if o[0] is None else o[0].measured_error_upper for o in outcomes]

    def replace(self, i: int, encoding: PrimitiveEncoding) -> None:
        """Job ``i`` is written with ``encoding``: measured again (unless not asked)."""
        self.encodings[i] = encoding
        if not self.measure:
            return
        reference = self.jobs[i].reference
        assert reference is not None
        mesh = (encoding.vertices, encoding.faces)
        if encoding.morph_bound is not None:
            # Morph targets: the certified bound over every weight, and the base's
            # sampled distance.
            sampled = reference.hausdorff(mesh).distance
            self.measured[i] = min(sampled, encoding.morph_bound)
            self.uppers[i] = None if self.budgets is None else encoding.morph_bound
            return
        if self.budgets is None:
            self.measured[i], self.uppers[i] = reference.hausdorff(mesh).distance, None
            return
        budget = self.budgets[i]
        h = reference.hausdorff(
            mesh, bounds=True, tolerance=CERTIFY_TOLERANCE * budget, threshold=budget
        )
        self.measured[i] = h.distance
        self.uppers[i] = float(h.upper) if h.upper is not None else None

    def all_within(self, members: list[int]) -> bool:
        """Whether every member is certified within its budget (or none is asked)."""
        budgets = self.budgets
        return budgets is None or all(
            (upper := self.uppers[i]) is not None and upper <= budgets[i] for i in members
        )


def shared_grids(
    jobs: list[Job],
    outcomes: list[Outcome],
    budgets: list[float] | None = None,
    measure: bool = True,
    research: Research | None = None,
) -> Encodings:
    """meshopt: the jobs of one cluster share their meshes' node transforms, so integer
    positions need one dequantization for all of them: they are quantized again on one
    cube grid over their boxes, with the bits whose step is at most the finest any of them
    chose. Where that takes more than 16 bits, or some job of the cluster stores float32
    positions (skinned, instanced, beyond 16 bits), every job stores float32 positions on
    its own grid instead, which need no shared transform; before that, with ``research``,
    the members that missed their budgets are searched again (:func:`_searched_again`).
    What changed is measured again
    (unless ``measure`` is False; with ``budgets``, one per job, certified again against
    them). Returns the encodings, their errors and their certified bounds (None where not
    certified, and for jobs kept as they were)."""
    clusters: dict[int, list[int]] = {}
    for i, (job, outcome) in enumerate(zip(jobs, outcomes, strict=True)):
        if outcome[0] is not None:
            clusters.setdefault(job.cluster, []).append(i)
    state = _Measured(jobs, outcomes, budgets, measure)
    for members in clusters.values():
        for i in members:
            state.encodings[i].bits = outcomes[i][0].bits
        integer = all(state.encodings[i].dequantize is not None for i in members)
        if integer and len(members) == 1:
            continue
        if integer and _on_one_grid(state, members, outcomes):
            continue
        if integer and research is not None and _searched_again(state, members, outcomes, research):
            continue
        _on_own_float_grids(state, members, outcomes)
    return state.encodings, state.measured, state.uppers


def _on_one_grid(state: _Measured, members: list[int], outcomes: list[Outcome]) -> bool:
    """Quantize a cluster's jobs again on one cube grid over their boxes, at the bits
    whose step is at most the finest any of them chose, then finer (up to
    :data:`SHARED_GRID_EXTRA_BITS` more, within 16 bits) while one misses its budget.
    Whether some grid kept them all within their budgets."""
    levels = [outcomes[i][2] for i in members]
    lo = np.min([np.minimum(lv.origin, lv.vertices.min(axis=0)) for lv in levels], axis=0)
    hi = np.max([lv.vertices.max(axis=0) for lv in levels], axis=0)
    origin, side = cube_grid(lo, np.maximum(hi, lo))
    finest = min(
        lv.grid_size / (2 ** outcomes[i][0].bits - 1) for i, lv in zip(members, levels, strict=True)
    )
    bits = max(1, math.ceil(math.log2(side / finest + 1))) if side > 0 else 1
    # The shared grid's points are not the ones each job was measured on: where one now
    # misses its budget, finer grids are tried before float32 positions.
    for shared_bits in range(bits, min(bits + SHARED_GRID_EXTRA_BITS, MESHOPT_INTEGER_BITS) + 1):
        for i, level in zip(members, levels, strict=True):
            encoding = encode_meshopt_primitive(
                level.vertices,
                level.faces,
                level.attributes,
                shared_bits,
                origin,
                side,
                state.jobs[i].bits,
                targets=state.jobs[i].data.targets or None,
            )
            encoding.bits = shared_bits
            state.replace(i, encoding)
        if state.all_within(members):
            return True
    return False


def _searched_again(
    state: _Measured, members: list[int], outcomes: list[Outcome], research: Research
) -> bool:
    """The members the finest shared grid left over their budgets, searched again within
    ``budget * RESEARCH_SHRINK * budget / missed`` (``missed``: their sampled distance
    there, at least the budget), and the shared grid tried again with their new answers
    (``outcomes`` takes them). A first answer filled its budget with its own grid's
    rounding, which can pull a simplified level back within it: BrainStem at 0.00095 m
    had a 1.4 m cable at 11 bits on its own grid, 1.06 mm away on the shared grid at 16
    bits, and all 59 primitives of its skin went to float32 positions (geometry 371 kB
    against 289 kB at a budget eight times smaller). Whether the grid now holds them."""
    budgets = state.budgets
    assert budgets is not None
    missed = [i for i in members if (upper := state.uppers[i]) is None or not upper <= budgets[i]]
    if not missed:
        return False
    for i in missed:
        over = max(state.measured[i], budgets[i])
        outcome = research(i, budgets[i] * RESEARCH_SHRINK * budgets[i] / over)
        if outcome[0] is None or outcome[1] is None or outcome[1].dequantize is None:
            return False
        outcomes[i] = outcome
    return _on_one_grid(state, members, outcomes)


def _on_own_float_grids(state: _Measured, members: list[int], outcomes: list[Outcome]) -> None:
    """Every job of a cluster that stores integer positions stores float32 positions on
    its own grid at its own bits instead (no shared transform needed)."""
    for i in members:
        if state.encodings[i].dequantize is None:
            continue
        level = outcomes[i][2]
        bits = outcomes[i][0].bits
        encoding = encode_meshopt_primitive(
            level.vertices,
            level.faces,
            level.attributes,
            bits,
            level.origin,
            level.grid_size,
            state.jobs[i].bits,
            integer_positions=False,
            targets=state.jobs[i].data.targets or None,
        )
        encoding.bits = bits
        state.replace(i, encoding)
