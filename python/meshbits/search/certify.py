"""Certifying a search's answer: its best result measured again with a certified upper
bound on the Hausdorff distance (length), so that a result the samples (lower bounds)
said met the budget is only kept when its bound does."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

from ..hausdorff import Hausdorff, Reference
from ..results import Progress, ProgressCallback
from .error_model import learned
from .level_cache import LevelCache
from .measurements import Iteration, best_measurement, closest_measurement

__all__ = ["ANSWER_REFINE_BUDGET", "Certifier"]

#: Largest number of refinement points a size or vertex budget's answer spends on its
#: error bound, per direction (:meth:`Certifier.bound_best`).
ANSWER_REFINE_BUDGET = 1_000_000


class Certifier:
    """Measures a search's answers again with certified bounds, and records what it
    finds in the search's own measurements and level errors (it is owned by the search,
    which gives it those).

    Parameters
    ----------
    cache : LevelCache
        The search's levels (their encodings, and the errors the plans learn from).
    measurements : list of Iteration
        The search's measurements: a result measured again is replaced in place.
    reference : Reference
        The original's BVH and samples.
    samples : int
        Area samples of each measurement.
    constraint : {"error", "size", "vertices"}
    budget : float
        Length, bits or a vertex count.
    """

    def __init__(
        self,
        cache: LevelCache,
        measurements: list[Iteration],
        reference: Reference,
        *,
        samples: int,
        constraint: str,
        budget: float,
    ) -> None:
        self.cache = cache
        self.measurements = measurements
        self.reference = reference
        self.samples = samples
        self.constraint = constraint
        self.budget = budget

    def _best(self) -> Iteration | None:
        return best_measurement(self.measurements, self.constraint, self.budget)

    def _measure_again(self, record: Iteration, **asked: Any) -> Hausdorff:
        """A result's encoded mesh measured against the original again, with ``asked``
        (the bounds :meth:`Reference.hausdorff` takes); timed with the search's
        measurements."""
        level = self.cache.levels[record.level]
        encoded = level.encodings[record.bits]
        begin = time.perf_counter()
        h = self.reference.hausdorff(
            (encoded.vertices, encoded.faces),
            samples=self.samples,
            check=level.source == "lod",
            **asked,
        )
        self.cache.seconds["hausdorff"] += time.perf_counter() - begin
        return h

    def certify_best(
        self, tolerance: float, passes_left: bool, progress: ProgressCallback | None = None
    ) -> Iteration | None:
        """Certify the best result of an error budget that met it by its sampled distance,
        then the next best while the bound misses the budget: each is measured again with
        a certified upper bound refined until it is within the budget or within
        ``tolerance`` (length) of the sampled maximum (the refinement stops as soon as a
        point beyond the budget is found). Returns the best result once it carries a
        bound (within the budget), or None when none is left. ``passes_left`` says
        whether the search goes on after a miss (for the progress lines)."""
        while True:
            best = self._best()
            if best is None or best.measured_error_upper is not None:
                return best
            h = self._measure_again(best, bounds=True, tolerance=tolerance, threshold=self.budget)
            upper = float(h.upper if h.upper is not None else h.distance)
            checked = replace(
                best,
                measured_error=max(best.measured_error, h.distance),
                measured_error_upper=upper,
                met=upper <= self.budget,
            )
            self.measurements[self.measurements.index(best)] = checked
            self.cache.levels[best.level].errors[best.bits] = learned(
                max(best.measured_error, h.distance), upper, self.budget, True
            )
            if progress is not None:
                progress(self._certified_progress(best, checked, upper, passes_left))
            if checked.met:
                return checked

    def _certified_progress(
        self, best: Iteration, checked: Iteration, upper: float, passes_left: bool
    ) -> Progress:
        """The progress line of a result certified by :meth:`certify_best`."""
        more = passes_left or any(
            m.met and m.measured_error_upper is None for m in self.measurements
        )
        verdict = "holds" if checked.met else "misses the budget: not met"
        if not checked.met and more:
            verdict += ", the search goes on"
        if checked.measured_error > self.budget:
            # The refinement stopped at a point beyond the budget: its bound then is
            # whatever it had reached, not a measure of the error.
            found = f"a point {checked.measured_error:.4g} away"
        else:
            found = f"error {checked.measured_error:.4g}, certified <= {upper:.4g}"
        return Progress(
            "compress",
            f"certify: B = {best.bits}, V = {best.vertices}; {found} "
            f"(budget {self.budget:.4g}) (mesh units): {verdict}",
            checked,
        )

    def bound_best(
        self, relative_tolerance: float, progress: ProgressCallback | None = None
    ) -> Iteration:
        """The answer of a size or vertex budget with a certified upper bound on its
        error, refined until within ``relative_tolerance`` of each direction's sampled
        maximum. A size budget's answer is the least error: when bounding it raises its
        error above another result's sampled one, that result is bounded too, until the
        answer has its bound (bounds are compared with bounds, not with samples, which
        only bound below). A bound that does not converge within
        :data:`ANSWER_REFINE_BUDGET` points is not kept (a result whose error is spread
        evenly, as quantization's is on a CAD part at many bits, would refine nearly
        everywhere): the sampled error stands, as before."""
        tried: set[int] = set()
        while True:
            best = self._best() or closest_measurement(self.measurements, self.constraint)
            index = self.measurements.index(best)
            if best.measured_error_upper is not None or index in tried:
                return best
            tried.add(index)
            h = self._measure_again(
                best,
                relative_tolerance=relative_tolerance,
                refine_budget=ANSWER_REFINE_BUDGET,
            )
            converged = bool(h.a_to_b.converged and h.b_to_a.converged)
            bounded = replace(
                best,
                measured_error=max(best.measured_error, h.distance),
                measured_error_upper=float(h.upper) if converged and h.upper is not None else None,
            )
            self.measurements[index] = bounded
            if progress is not None:
                outcome = (
                    f"certified <= {bounded.measured_error_upper:.4g}"
                    if bounded.measured_error_upper is not None
                    else f"no bound within {ANSWER_REFINE_BUDGET:,} refinement points"
                )
                progress(
                    Progress(
                        "compress",
                        f"bound: B = {best.bits}, V = {best.vertices}; error "
                        f"{bounded.measured_error:.4g}, {outcome} (mesh units)",
                        bounded,
                    )
                )
