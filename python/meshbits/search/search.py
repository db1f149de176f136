"""The state of a search and its steps: :meth:`Search.propose` plans (and builds)
candidates and returns the one to measure, :meth:`Search.measure` measures it,
:meth:`Search.run` repeats them, and :meth:`Search.certify_answer` /
:meth:`Search.bound_answer` certify the answer."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from .. import model
from ..codecs import Encoded
from ..hausdorff import Reference
from ..mesh import distinct_positions
from ..results import Progress, ProgressCallback
from ..simplify import Simplifier
from .candidates import Candidate, Planner
from .certify import Certifier
from .error_model import first_plan, learned
from .level_cache import Codec, LevelCache, Refused
from .levels import Attributes, Level
from .measurements import Iteration, best_measurement, closest_measurement

__all__ = ["Search"]


class Search:
    """The state and steps of the search: :meth:`propose` plans (and builds) candidates
    and returns the one to measure, :meth:`measure` measures it; :meth:`run` repeats
    them.

    Parameters
    ----------
    original : (vertices, faces)
        The welded original.
    reference : Reference
        Its BVH and samples, built once.
    constraint : {"error", "size", "vertices"}
    budget : float
        Length, bits or a vertex count.
    k : float
        The original's grid-normalised K.
    grid_size : float
        ``S`` of the original (length).
    max_bits : int
        Largest ``B`` (format and input precision).
    format : str
        Encoder.
    alpha, connectivity_bits : float
        The paper's size model, for the first plan.
    method : str or None
        ``"meshopt"``, ``"fast-simplification"``, or ``"auto"`` (both compete, see
        :meth:`LevelCache.simplifier_methods`); None with ``simplifier`` or ``lods``.
    simplifier : callable, optional
        ``simplifier(vertices, faces, target_vertices) -> (vertices, faces)``.
    lods : sequence of meshes, optional
        The levels to choose from, with the original.
    samples : int
        Area samples of each candidate.
    certify : bool
        Judge an error budget by a certified upper bound.
    tolerance : float or None
        Refinement tolerance of that bound (length).
    attributes : Attributes, optional
        Vertex attributes to simplify with (meshoptimizer only: they keep their seams)
        and to encode.
    codec : callable, optional
        What encodes a candidate (see :data:`Codec`); default :func:`meshbits.encode`
        in ``format``.
    """

    def __init__(
        self,
        original: tuple[np.ndarray, np.ndarray],
        reference: Reference,
        *,
        constraint: str,
        budget: float,
        k: float,
        grid_size: float,
        max_bits: int,
        format: str,
        alpha: float,
        connectivity_bits: float,
        method: str | None = "auto",
        simplifier: Simplifier | None = None,
        lods: Sequence[Any] | None = None,
        samples: int,
        certify: bool = False,
        tolerance: float | None = None,
        attributes: Attributes | None = None,
        codec: Codec | None = None,
    ) -> None:
        self.original = original
        self.reference = reference
        self.constraint = constraint
        self.budget = float(budget)
        self.samples = int(samples)
        self.certify = certify
        self.tolerance = tolerance
        self.plan: model.Allocation | None = first_plan(
            constraint,
            self.budget,
            float(k),
            grid_size=float(grid_size),
            alpha=float(alpha),
            connectivity_bits=float(connectivity_bits),
        )
        self.measurements: list[Iteration] = []
        #: The levels built, their encodings, and their predicted errors.
        self.cache = LevelCache(
            original,
            reference,
            k=k,
            grid_size=grid_size,
            format=format,
            method=method,
            simplifier=simplifier,
            lods=lods,
            attributes=attributes,
            codec=codec,
            plan=self.plan,
        )
        #: What proposes the candidates.
        self.planner = Planner(
            self.cache,
            self.measurements,
            constraint=constraint,
            budget=self.budget,
            max_bits=int(max_bits),
            alpha=float(alpha),
            connectivity_bits=float(connectivity_bits),
        )
        #: What certifies the answer.
        self.certifier = Certifier(
            self.cache,
            self.measurements,
            reference,
            samples=self.samples,
            constraint=constraint,
            budget=self.budget,
        )

    @property
    def levels(self) -> list[Level]:
        """The levels built so far (0: the original)."""
        return self.cache.levels

    @property
    def refused(self) -> dict[tuple[int, int], str]:
        """``(level, bits) -> why`` of each candidate the encoder refused (skipped)."""
        return self.cache.refused

    @property
    def seconds(self) -> dict[str, float]:
        """Wall time by kind of work: simplify, encode, hausdorff, estimate (seconds)."""
        return self.cache.seconds

    # --- passes -------------------------------------------------------------------------

    def propose(self) -> Candidate | None:
        """The next candidate to measure (built and encoded), or None when none promises
        :data:`STOP_GAIN` over the best result so far. Raises :class:`Refused` when the
        encoder refuses every candidate of the first pass."""
        candidate = self.planner.propose()
        if candidate is None and not self.measurements:
            reasons = sorted(set(self.refused.values()))
            raise Refused(
                f"the encoder refused every candidate ({len(self.refused)} tried): "
                + "; ".join(reasons[:3])
            )
        return candidate

    def measure(self, candidate: Candidate, began: float) -> Iteration:
        """Measure one candidate (its encoding is built) and record it; ``began`` is when
        its pass started (:func:`time.perf_counter`)."""
        level = self.levels[candidate.level]
        encoded = self.cache.encoded(candidate.level, candidate.bits)
        start = time.perf_counter()
        deciding = self.certify and self.constraint == "error" and self.tolerance is not None
        h = self.reference.hausdorff(
            (encoded.vertices, encoded.faces),
            samples=self.samples,
            bounds=self.certify,
            tolerance=self.tolerance,
            check=level.source == "lod",
            threshold=self.budget if deciding else None,
        )
        self.seconds["hausdorff"] += time.perf_counter() - start
        decisive = h.distance if h.upper is None else h.upper
        level.errors[candidate.bits] = learned(h.distance, h.upper, self.budget, deciding)
        if self.constraint == "error":
            met = decisive <= self.budget
        elif self.constraint == "size":
            met = encoded.size_bits <= self.budget
        else:
            met = distinct_positions(encoded.vertices) <= self.budget
        record = Iteration(
            level=candidate.level,
            source=level.source,
            bits=candidate.bits,
            planned_vertices=(
                round(self.plan.whole_vertices)
                if self.constraint == "vertices" and self.plan is not None
                else level.vertex_count
            ),
            vertices=distinct_positions(encoded.vertices),
            faces=len(encoded.faces),
            predicted_error=candidate.error,
            predicted_size_bits=candidate.size_bits,
            measured_error=h.distance,
            measured_size_bits=encoded.size_bits,
            measured_error_upper=h.upper,
            met=met,
            seconds=time.perf_counter() - began,
        )
        self.measurements.append(record)
        return record

    def run(self, max_passes: int, progress: ProgressCallback | None = None) -> None:
        """Plan, build and measure until the search stops or ``max_passes`` are spent."""
        for _ in range(max_passes):
            began = time.perf_counter()
            candidate = self.propose()
            if candidate is None:
                break
            record = self.measure(candidate, began)
            if progress is not None:
                progress(Progress("compress", str(record), record))

    # --- answers ------------------------------------------------------------------------

    def best(self) -> Iteration | None:
        """The best measurement that meets the budget: fewest bytes for an error budget,
        least error for a size budget."""
        return best_measurement(self.measurements, self.constraint, self.budget)

    def closest(self) -> Iteration:
        """The measurement that misses the budget least: the smallest file, the fewest
        vertices, or the least sampled error (a lower bound on every measurement, where
        a certified bound refined only to decide the budget can be loose)."""
        return closest_measurement(self.measurements, self.constraint)

    def encoded(self, measurement: Iteration) -> Encoded:
        """The encoding a measurement measured."""
        return self.levels[measurement.level].encodings[measurement.bits]

    def certify_answer(
        self,
        tolerance: float,
        extra_passes: int,
        progress: ProgressCallback | None = None,
    ) -> None:
        """Certify the answer of an error-budget search that measured sampled distances.

        The best result that met the budget by its sampled distance (a lower bound) is
        measured again with a certified upper bound refined until it is within the budget
        or within ``tolerance`` of the sampled maximum (the refinement stops as soon as a
        point beyond the budget is found): within the budget, it stands; beyond, it no
        longer counts as met (its record now carries the bound) and the next best is
        tried (:meth:`Certifier.certify_best`). When none is left, the search goes on for
        up to ``extra_passes`` passes measuring every candidate certified, and their best
        is certified the same way. Exploring with samples and certifying only the answer
        keeps the search's plans on the sampled errors it was tuned on, at the price of
        one certified measurement per answer tried.
        """
        for round_ in range(2):
            passes_left = round_ == 0 and extra_passes >= 1
            if self.certifier.certify_best(tolerance, passes_left, progress) is not None:
                return
            if round_ == 1 or extra_passes < 1:
                return
            self.certify, self.tolerance = True, tolerance
            self.run(extra_passes, progress)

    def bound_answer(
        self, relative_tolerance: float, progress: ProgressCallback | None = None
    ) -> Iteration:
        """The answer of a size or vertex budget with a certified upper bound on its
        error (:meth:`Certifier.bound_best`)."""
        return self.certifier.bound_best(relative_tolerance, progress)
