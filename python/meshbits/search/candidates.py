"""Proposing candidates: which (level, B) a search measures next.

For an error budget ``E``, each ``B`` from the least one whose quantization alone fits
(``E_Q(B) < E``) up to :data:`BITS_ABOVE` more leaves room ``t*(B)`` for tessellation;
meshoptimizer is asked for a level at the error target ``tau`` expected to give
``t*(B)`` (interpolated between the measured levels, in log-log), and the original
itself is a candidate at the least ``B``. The candidate of fewest bytes predicted to meet
``E`` is measured. A measured level that met ``E`` at some ``B`` is not tried at more
bits, one that missed it not at fewer: at a fixed level the least passing ``B`` is
sought. For a size budget ``F``, each ``B`` near the model's optimum gets the finest
level whose encoding fits ``F``, and the one of least predicted error is measured. The
search stops when no candidate promises :data:`STOP_GAIN` more than the best result so
far. Sizes are those of real encodings of the candidates (bits); errors are lengths.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..constants import MODEL_MIN_BITS, MODEL_MIN_VERTICES
from ..mesh import distinct_positions
from ..simplify import closest_level
from .error_model import (
    allowed_tessellation,
    combined_error,
    interpolate,
    paper_vertices,
    quantization_error,
)
from .level_cache import LevelCache, Refused
from .levels import Level
from .measurements import Iteration, best_measurement, clears

__all__ = [
    "AIM",
    "BITS_ABOVE",
    "BITS_AROUND",
    "CHEAP_VERTICES",
    "EXPLORE_AIM",
    "EXPLORE_WIDE",
    "FIT_AIM",
    "FIT_TRIES",
    "FIT_USED",
    "PASSES_AFTER_MET",
    "PASSES_AFTER_MET_LARGE",
    "STOP_GAIN",
    "VERTEX_TRIES",
    "Candidate",
    "Planner",
]

#: Until a result meets an error budget, candidates are aimed at this fraction of it:
#: the combined-error model is within 3-6% at its 90th percentile.
AIM = 0.96

#: Once one does, candidates predicted up to this fraction of it are tried: measured
#: errors scatter around the prediction (quantization can lower a level's error), and
#: a miss costs a pass, not the result.
EXPLORE_AIM = 1.06

#: When no candidate is left after an error budget is met, a level already built that is
#: predicted up to this fraction of it is still tried, if it would be smaller (one pass
#: each, within :data:`PASSES_AFTER_MET`). On the fandisk (a CAD part, where a vertex
#: target's error jumps between nearby counts) at 0.001 S, a 455-vertex level predicted at
#: 1.175 times the budget measured 0.97 times it at B = 11: 1,787 bytes instead of 1,989
#: (the brute-force oracle's best: 1,718). Wider searches that also built levels for the
#: wider aim gave the nefertiti 14-16% bigger files (their passes after the first met
#: result went to misses).
EXPLORE_WIDE = 1.2

#: The search stops when no candidate promises this relative gain (fewer bytes, or less
#: error) over the best result so far.
STOP_GAIN = 0.03

#: Passes spent looking for a better result once one meets the budget (for an original
#: of more than :data:`BASE_FACES` faces, :data:`PASSES_AFTER_MET_LARGE`).
PASSES_AFTER_MET = 2

#: Passes after a met one for a large original, where a pass costs seconds: none. (On
#: the dragon's 0.001 S budget the one pass after its first met result, 4.8 s, tried
#: B = 10 with fewer vertices and missed the budget, as every B = 10 level does there.)
PASSES_AFTER_MET_LARGE = 0

#: Bits tried above the least ``B`` whose quantization alone fits an error budget.
BITS_ABOVE = 2

#: Bits tried on each side of the model's optimum for a size budget.
BITS_AROUND = 2

#: Simplifications tried to reach a vertex budget (a simplifier's vertex target is
#: approximate).
VERTEX_TRIES = 3

#: Simplifications tried to fit a size budget at one B.
FIT_TRIES = 3

#: A level for a size budget is aimed at this fraction of it (Draco's bytes per vertex
#: vary by a few percent between levels)...
FIT_AIM = 0.98

#: ...and is fine once its file uses this fraction of it.
FIT_USED = 0.94

#: Meshes of at most this many vertices are cheap to encode whole.
CHEAP_VERTICES = 100_000


@dataclass(frozen=True)
class Candidate:
    """A (level, B) a search may measure: its level's index, its bits per coordinate, its
    encoded size (bits) and its predicted error (length; the measured one once
    measured)."""

    level: int
    bits: int
    size_bits: float
    error: float


class Planner:
    """Plans the candidates of a search from its levels and its measurements so far,
    building the levels and encodings it needs in ``cache``.

    Parameters
    ----------
    cache : LevelCache
        The search's levels.
    measurements : list of Iteration
        The search's measurements (read, never written).
    constraint : {"error", "size", "vertices"}
    budget : float
        Length, bits or a vertex count.
    max_bits : int
        Largest ``B``.
    alpha, connectivity_bits : float
        The paper's size model (bits per coordinate bit, bits per vertex of
        connectivity).
    """

    def __init__(
        self,
        cache: LevelCache,
        measurements: list[Iteration],
        *,
        constraint: str,
        budget: float,
        max_bits: int,
        alpha: float,
        connectivity_bits: float,
    ) -> None:
        self.cache = cache
        self.measurements = measurements
        self.constraint = constraint
        self.budget = budget
        self.max_bits = max_bits
        self.alpha = alpha
        self.connectivity_bits = connectivity_bits

    @property
    def levels(self) -> list[Level]:
        """The levels built so far (the cache's)."""
        return self.cache.levels

    @property
    def grid_size(self) -> float:
        """``S`` of the original (length)."""
        return self.cache.grid_size

    def _best(self) -> Iteration | None:
        return best_measurement(self.measurements, self.constraint, self.budget)

    def _clears(self, measurement: Iteration) -> bool:
        return clears(measurement, self.budget)

    def propose(self) -> Candidate | None:
        """The candidate to measure next (built and encoded), or None when none promises
        :data:`STOP_GAIN` over the best result so far."""
        if self.constraint == "vertices":
            return None if self.measurements else self._vertices_candidate()
        first_met = next(
            (
                i
                for i, m in enumerate(self.measurements)
                if m.met and (self.constraint != "error" or self._clears(m))
            ),
            None,
        )
        after = PASSES_AFTER_MET_LARGE if self.cache.large else PASSES_AFTER_MET
        if first_met is not None and len(self.measurements) - 1 - first_met >= after:
            return None
        best = self._best()
        if self.constraint == "error":
            ranked = sorted(self.error_candidates(), key=lambda c: (c.size_bits, c.error))
            if best is not None:
                limit = (1 - STOP_GAIN) * best.measured_size_bits
                ranked = [c for c in ranked if c.size_bits < limit]
        else:
            ranked = sorted(self._size_candidates(), key=lambda c: (c.error, c.size_bits))
            if best is not None:
                ranked = [c for c in ranked if c.error < (1 - STOP_GAIN) * best.decisive_error]
        if ranked:
            return ranked[0]
        if not self.measurements:
            return self._fallback()
        if best is None and self.constraint == "error":
            return self._last_resort()
        return self._clearing(best) or self.exploring(best) or self.exploring_finer(best)

    def exploring(self, best: Iteration | None) -> Candidate | None:
        """Once an error budget is met with room to spare and no candidate is left, the
        built level at a B of :meth:`error_bits` with the fewest predicted bytes, at
        least :data:`STOP_GAIN` fewer than the best, that is predicted within
        :data:`EXPLORE_WIDE` of the budget; None when there is none. No level is built
        for it: this is a pass spent on the scatter of the predictions."""
        if self.constraint != "error" or best is None:
            return None
        limit = (1 - STOP_GAIN) * best.measured_size_bits
        wide = []
        for index, level in enumerate(self.levels):
            for bits in self.error_bits():
                if self._tried(index, bits) or not self._may_meet(level, bits):
                    continue
                if level.source == "original" and not self._original_worth_encoding(bits):
                    continue
                candidate = self.candidate(index, bits)
                if candidate is None:
                    continue
                if candidate.error <= EXPLORE_WIDE * self.budget and candidate.size_bits < limit:
                    wide.append(candidate)
        return min(wide, key=lambda c: (c.size_bits, c.error), default=None)

    def exploring_finer(self, best: Iteration | None) -> Candidate | None:
        """Once a size budget is met and no candidate promises :data:`STOP_GAIN` less
        error, the encoding that fits with the most vertices of a level finer than the
        best's, among those predicted within :data:`EXPLORE_AIM` of the best's measured
        error; None when there is none. No level is built for it.

        A level's predicted tessellation error is its quick estimate (a maximum over
        fewer points, a lower bound) scaled, and the maximum often stays at one feature
        over a range of vertex counts: on the Max Planck bust at 4 kB,
        fast-simplification's levels of 1,062 to 1,383 vertices all estimated 4.11e-3 S,
        so the least predicted error went to the most bits (1,062 vertices at B = 12:
        4.21e-3 S sampled, 4.75e-3 certified), where 1,383 vertices at B = 10 measure
        4.02e-3 (4.55e-3 certified). Off the plateau's feature a finer level of the same
        simplifier is no worse, and the error quantization adds is what the model
        predicts best."""
        if self.constraint != "size" or best is None:
            return None
        finest = self.levels[best.level].vertex_count
        limit = EXPLORE_AIM * best.decisive_error
        finer = [
            candidate
            for index, level in enumerate(self.levels)
            if level.vertex_count > finest and not level.errors
            for bits, encoded in list(level.encodings.items())
            if encoded.size_bits <= self.budget
            for candidate in [self.candidate(index, bits)]
            if candidate is not None and candidate.error <= limit
        ]
        return max(
            finer,
            key=lambda c: (self.levels[c.level].vertex_count, -c.error),
            default=None,
        )

    def _last_resort(self) -> Candidate | None:
        """Nothing measured meets an error budget and no level is expected to (a level
        that missed it by its certified bound, say, and the lesson scaled every level's
        estimate up): the finest level built and never measured, finer than every level
        measured, then the original, each at the least B expected to meet the budget that
        it was not measured at; None when every B was."""
        fitting = self.error_bits()
        first = fitting[0] if len(fitting) else self.max_bits
        finest_missed = max(
            (self.levels[m.level].vertex_count for m in self.measurements), default=0
        )
        finest = max(
            (
                i
                for i, level in enumerate(self.levels)
                if i > 0 and level.vertex_count > finest_missed and not level.errors
            ),
            key=lambda i: self.levels[i].vertex_count,
            default=None,
        )
        for index in [finest, 0] if finest is not None else [0]:
            for bits in range(first, self.max_bits + 1):
                if not self._tried(index, bits) and self._may_meet(self.levels[index], bits):
                    candidate = self.candidate(index, bits)
                    if candidate is not None:
                        return candidate
        return None

    def _clearing(self, best: Iteration | None) -> Candidate | None:
        """When the best result meets an error budget without :data:`CLEAR_MARGIN` to
        spare, its level at one more bit (a last pass); else None."""
        if self.constraint != "error" or best is None or self._clears(best):
            return None
        bits = best.bits + 1
        if bits > self.max_bits or self._tried(best.level, bits):
            return None
        return self.candidate(best.level, bits)

    def _aim(self) -> float:
        """What error candidates are aimed at (length): see :data:`AIM`."""
        return (EXPLORE_AIM if self._best() is not None else AIM) * self.budget

    def _stored_bits(self, bits: int) -> int:
        """The most bits stored in the same bytes as ``bits``: a fixed-width format keeps
        each coordinate in whole bytes (float32 in PLY; 8 or 16 bits in a quantized GLB),
        so at the same size those give the least error. ``bits`` itself for Draco and a
        caller's codec."""
        if self.cache.codec is None and self.cache.format == "ply":
            return self.max_bits
        if self.cache.codec is None and self.cache.format == "glb":
            return min(8 if bits <= 8 else 16, self.max_bits)
        return bits

    def _planning_bits(self) -> range:
        """The B whose quantization error leaves the room an error budget's levels are
        planned for: the least B whose quantization alone fits, and
        :data:`BITS_ABOVE` more."""
        aim = self._aim()
        first = next(
            (b for b in range(1, self.max_bits + 1) if quantization_error(b, self.grid_size) < aim),
            None,
        )
        if first is None:
            return range(0)
        above = 1 if self.cache.large else BITS_ABOVE
        return range(first, min(first + above, self.max_bits) + 1)

    def error_bits(self) -> list[int]:
        """The B an error budget's candidates are encoded at: :meth:`_planning_bits`,
        each raised to the most bits stored in the same bytes (:meth:`_stored_bits`)."""
        return sorted({self._stored_bits(b) for b in self._planning_bits()})

    def error_candidates(self) -> list[Candidate]:
        """Candidates expected to meet the error budget: for each B, a level whose
        tessellation error fills the room quantization leaves; and every level built so
        far, at each B where it is expected to meet the budget."""
        aim = self._aim()
        bits_range = self.error_bits()
        for bits in self._planning_bits():
            room = allowed_tessellation(
                aim, quantization_error(bits, self.grid_size), self.cache.delta(bits=bits)
            )
            for method in self.cache.simplifier_methods():
                self.cache.level_for(room, room, method)
        out = []
        for index, level in enumerate(self.levels):
            for bits in bits_range:
                if self._tried(index, bits) or not self._may_meet(level, bits):
                    continue
                if level.source == "original" and not self._original_worth_encoding(bits):
                    continue
                candidate = self.candidate(index, bits)
                if candidate is not None and candidate.error <= aim:
                    out.append(candidate)
        return out

    def _original_worth_encoding(self, bits: int) -> bool:
        """Whether the original at ``bits`` may be the smallest candidate: always when
        encoding it is cheap or done; else unless the simplified levels' bits per vertex
        at ``bits``, halved, times its vertex count exceed the smallest of them."""
        if bits in self.levels[0].encodings or self.cache.available <= CHEAP_VERTICES:
            return True
        sizes = [
            (lv.encodings[bits].size_bits, lv.vertex_count)
            for lv in self.levels[1:]
            if bits in lv.encodings
        ]
        if not sizes:
            return False
        rate = min(size / count for size, count in sizes)
        return 0.5 * rate * self.cache.available < min(size for size, _ in sizes)

    def _may_meet(self, level: Level, bits: int) -> bool:
        """Whether ``bits`` is still worth trying on a level for an error budget: not
        when the level missed the budget at as many bits or more (fewer cannot do
        better), nor when it met it with fewer (more only cost bytes)."""
        for measured_bits, error in level.errors.items():
            if measured_bits >= bits and error > self.budget:
                return False
            if measured_bits < bits and error <= self.budget:
                return False
        return True

    def _size_bits(self) -> list[int]:
        """The B a size budget's candidates are built at: :data:`BITS_AROUND` on each side
        of the plan's B and of the best result's."""
        centre = [round(self.cache.plan.bits)] if self.cache.plan is not None else [8]
        best = self._best()
        if best is not None:
            centre.append(best.bits)
        wanted = {
            b
            for c in centre
            for b in range(c - BITS_AROUND, c + BITS_AROUND + 1)
            if 1 <= b <= self.max_bits
        }
        return sorted(wanted)

    def _size_candidates(self) -> list[Candidate]:
        """For each B near the optimum, the finest level whose encoding fits the size;
        the original at the most bits that fit; and every encoding built so far that
        fits, with each level at the most bits stored in the same bytes
        (:meth:`_stored_bits`) where that fits too."""
        for bits in self._size_bits():
            for method in self.cache.simplifier_methods():
                self._fitting_level(bits, method)
        self._original_most_bits()
        for index, level in enumerate(self.levels):
            for bits in [b for b, e in level.encodings.items() if e.size_bits <= self.budget]:
                self.cache.size_of(index, self._stored_bits(bits))
        out = []
        for index, level in enumerate(self.levels):
            for bits, encoded in list(level.encodings.items()):
                if encoded.size_bits <= self.budget and not self._tried(index, bits):
                    candidate = self.candidate(index, bits)
                    if candidate is not None:
                        out.append(candidate)
        return out

    def _original_most_bits(self) -> None:
        """Encode the original at the most bits whose file fits the size budget (a
        bisection on B: sizes grow with B), when that is cheap or may fit. The bisection
        starts at the least B the encoder accepts: at 1 or 2 bits every face of a mesh
        can collapse (refused), which says nothing about 8 bits fitting (the 5,203-vertex
        Stanford dragon at 16 kB: the original at B = 8, 14,072 bytes and 3.1e-3 S, was
        never tried, and the answer was a simplification at 4.9e-3 S certified)."""
        lo = 1
        while not self._original_fits(lo):
            if (0, lo) not in self.cache.refused or lo >= self.max_bits:
                return
            lo += 1
        hi = self.max_bits
        while lo < hi:
            mid = (lo + hi + 1) // 2
            lo, hi = (mid, hi) if self._original_fits(mid) else (lo, mid - 1)

    def _fitting_level(self, bits: int, method: str | None) -> int | None:
        """The finest level whose encoding at ``bits`` fits the size budget: the original
        if it fits, else a simplification sized by the bits per vertex seen."""
        if not self.cache.can_simplify():
            fit = [
                i
                for i, level in enumerate(self.levels)
                if level.vertex_count <= CHEAP_VERTICES or bits in level.encodings
                if self.cache.size_of(i, bits) <= self.budget
            ]
            return max(fit, key=lambda i: self.levels[i].vertex_count, default=None)
        if self._original_fits(bits):
            return 0
        vertices = FIT_AIM * self.budget / self._rate(bits)
        fitting: int | None = None
        aim = FIT_AIM
        for _ in range(FIT_TRIES):
            if vertices < MODEL_MIN_VERTICES:
                break
            index = self.cache.simplified(method, vertices=vertices, aim=self._fit_aim(vertices))
            if index is None or index == 0:
                break
            size = self.cache.size_of(index, bits)
            count = self.levels[index].vertex_count
            if size <= self.budget:
                if fitting is None or count > self.levels[fitting].vertex_count:
                    fitting = index
                if size >= FIT_USED * self.budget:
                    break
            if size > self.budget:
                aim *= FIT_AIM  # bytes per vertex grow as levels coarsen: aim lower
            vertices = count * aim * self.budget / size
        return fitting

    def _fit_aim(self, vertices: float) -> float:
        """Where a size budget's meshopt level locks the original vertices it strays from
        (length): the tessellation error the built levels show at ``vertices`` (before
        any, the paper's Eq. 18 at half the error, which gives E_T from V as it gives V
        from E_T: :func:`paper_vertices`)."""
        inverse = sorted(
            (float(lv.vertex_count), 1.0 / t)
            for lv in self.levels[1:]
            if lv.method == "meshopt" and lv.quick is not None
            for t in [self.cache.tessellation(lv)]
            if t > 0
        )
        if not inverse:
            return paper_vertices(self.cache.k, self.grid_size, vertices)
        return 1.0 / interpolate(inverse, vertices, inverse[0][1] / inverse[0][0])

    def _original_fits(self, bits: int) -> bool:
        """Whether the original encoded at ``bits`` fits the size budget (not encoded when
        it is large and the levels' bits per vertex say it cannot)."""
        original = self.levels[0]
        if bits not in original.encodings and self.cache.available > CHEAP_VERTICES:
            # Encoding a large original is worth it only when it can fit.
            rates = [
                lv.encodings[b].size_bits / lv.vertex_count
                for lv in self.levels[1:]
                for b in lv.encodings
                if b <= bits
            ]
            if not rates or 0.5 * min(rates) * self.cache.available > self.budget:
                return False
        return self.cache.size_of(0, bits) <= self.budget

    def _rate(self, bits: int) -> float:
        """Bits per vertex of a simplified level at ``bits``: the encodings seen at that
        B, else the paper's ``3 alpha B + T`` scaled by what was seen."""
        seen = [
            (level.encodings[b].size_bits / level.vertex_count, b)
            for level in self.levels[1:]
            for b in level.encodings
        ]
        same = [rate for rate, b in seen if b == bits]
        if same:
            return float(np.median(same))
        paper = 3.0 * self.alpha * bits + self.connectivity_bits
        if seen:
            model_rates = [3.0 * self.alpha * b + self.connectivity_bits for _, b in seen]
            scale = np.median([r / m for (r, _), m in zip(seen, model_rates, strict=True)])
            return float(scale * paper)
        return paper

    def _vertices_candidate(self) -> Candidate | None:
        """A vertex budget's one candidate: the level closest to the budget whose encoding
        holds at most that many vertices, at the plan's B."""
        assert self.cache.plan is not None
        bits = int(np.clip(self.cache.plan.whole_bits, 1, self.max_bits))
        target = min(self.budget, self.cache.available)
        if self.cache.lods:
            index = 1 + closest_level([(lv.vertices, lv.faces) for lv in self.levels[1:]], target)
        elif target >= self.cache.available:
            index = 0
        else:
            # A simplifier's vertex target is approximate (meshoptimizer's is a face
            # count), and the encoder may split vertices: aim lower while the encoded
            # level holds more vertices than the budget.
            method = self.cache.simplifier_method()
            aim = target
            index = 0
            for _ in range(VERTEX_TRIES):
                index = self.cache.simplified(method, vertices=aim) or 0
                try:
                    count = distinct_positions(self.cache.encoded(index, bits).vertices)
                except Refused:
                    break
                if index == 0 or count <= self.budget:
                    break
                # At least 4% lower: a level within 3% of the target is reused.
                aim *= min(0.96, 0.99 * self.budget / count)
        return self.candidate(index, bits)

    def _fallback(self) -> Candidate | None:
        """Nothing is expected to meet the budget: the most accurate output for an error
        budget, the smallest for a size budget (at the next B where the encoder refuses
        one); None when the encoder refuses every B."""
        if self.constraint == "error":
            fitting = self.error_bits()
            first = fitting[0] if len(fitting) else self.max_bits
            order = [*range(first, self.max_bits + 1), *range(first - 1, 0, -1)]
            return next(filter(None, (self.candidate(0, b) for b in order)), None)
        index = None
        if self.cache.can_simplify():
            index = self.cache.simplified(
                self.cache.simplifier_method(), vertices=MODEL_MIN_VERTICES
            )
        if index is None:
            index = min(range(len(self.levels)), key=lambda i: self.levels[i].vertex_count)
        coarsest_first = range(int(MODEL_MIN_BITS), self.max_bits + 1)
        return next(filter(None, (self.candidate(index, b) for b in coarsest_first)), None)

    def candidate(self, index: int, bits: int) -> Candidate | None:
        """Level ``index`` at ``bits``, encoded, with its predicted error; None when the
        encoder cannot encode it."""
        level = self.levels[index]
        error = level.errors.get(bits)
        if error is None:
            q = quantization_error(bits, level.grid_size)
            error = combined_error(self.cache.tessellation(level), q, self.cache.delta(level, bits))
        size = self.cache.size_of(index, bits)
        if not math.isfinite(size):
            return None
        return Candidate(index, bits, size, error)

    def _tried(self, index: int, bits: int) -> bool:
        """Whether level ``index`` was measured at ``bits``, or the encoder refused it."""
        return bits in self.levels[index].errors or (index, bits) in self.cache.refused
