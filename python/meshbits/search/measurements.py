"""The passes a search measured (:class:`Iteration`), and how they rank: the best one
that meets the budget, or the one that misses it least."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

__all__ = [
    "CLEAR_MARGIN",
    "Iteration",
    "best_measurement",
    "clears",
    "closest_measurement",
]

#: A result within an error budget is preferred when it meets it with this fraction to
#: spare: sampled distances are lower bounds, and an independent measurement with other
#: samples can find up to about 2% more (Open3D, in benches/frontier.py).
CLEAR_MARGIN = 0.015


@dataclass(frozen=True)
class Iteration:
    """One pass of the search: the candidate it measured.

    Attributes
    ----------
    level : int
        Index of the mesh in :attr:`Search.levels` (0: the original).
    source : str
        What the mesh is: ``"original"``, ``"meshopt"`` (simplified to an error target),
        ``"vertices"`` (simplified to a vertex count) or ``"lod"``.
    bits : int
        Bits per coordinate B.
    planned_vertices : int
        The vertex count of the planned candidate (the plan's, for a vertex budget).
    vertices, faces : int
        Of the encoded mesh.
    predicted_error : float
        The plan's error (length).
    predicted_size_bits : float
        The size the plan chose it by (bits): candidates are encoded before one is
        chosen, so this is its encoded size, ``measured_size_bits``.
    measured_error : float
        Sampled symmetric Hausdorff distance between the original and the decoded output
        (length).
    measured_size_bits : int
        Size of the encoded file (bits).
    measured_error_upper : float or None
        With ``certify``: a certified upper bound on the true distance (length).
    met : bool
        Whether this pass met the budget.
    seconds : float
        Wall time of the pass, planning and building included.
    """

    level: int
    source: str
    bits: int
    planned_vertices: int
    vertices: int
    faces: int
    predicted_error: float
    predicted_size_bits: float
    measured_error: float
    measured_size_bits: int
    measured_error_upper: float | None
    met: bool
    seconds: float

    @property
    def decisive_error(self) -> float:
        """The error a budget is judged by: the certified bound when there is one."""
        upper = self.measured_error_upper
        return self.measured_error if upper is None else upper

    def to_dict(self) -> dict[str, Any]:
        """The fields by name."""
        return asdict(self)

    def __str__(self) -> str:
        upper = self.measured_error_upper
        # A pass that missed its budget by a point beyond it stops refining there: its
        # bound can be far above the error and says nothing (the line says it missed).
        shown = upper is not None and (self.met or upper <= 2 * self.measured_error)
        return (
            f"pass: {self.source} mesh, B = {self.bits}, V = {self.vertices}; "
            f"error {self.measured_error:.4g}"
            + (f" (certified <= {upper:.4g})" if shown else "")
            + f" (model {self.predicted_error:.4g}) (mesh units), "
            f"{self.measured_size_bits // 8} bytes" + ("" if self.met else ": misses the budget")
        )


def clears(measurement: Iteration, budget: float) -> bool:
    """Whether a result meets an error budget with :data:`CLEAR_MARGIN` to spare (a
    sampled distance), or at all (a certified bound: the margin is for samples)."""
    if measurement.measured_error_upper is not None:
        return measurement.measured_error_upper <= budget
    return measurement.decisive_error <= (1 - CLEAR_MARGIN) * budget


def best_measurement(
    measurements: Sequence[Iteration], constraint: str, budget: float
) -> Iteration | None:
    """The best measurement that meets the budget: fewest bytes for an error budget (one
    that :func:`clears` it first), least error for a size budget; None when none does."""
    met = [m for m in measurements if m.met]
    if not met:
        return None
    if constraint == "size":
        return min(met, key=lambda m: (m.decisive_error, m.measured_size_bits))
    return min(met, key=lambda m: (not clears(m, budget), m.measured_size_bits, m.decisive_error))


def closest_measurement(measurements: Sequence[Iteration], constraint: str) -> Iteration:
    """The measurement that misses the budget least: the smallest file, the fewest
    vertices, or the least sampled error (a lower bound on every measurement, where
    a certified bound refined only to decide the budget can be loose)."""
    if constraint == "size":
        return min(measurements, key=lambda m: m.measured_size_bits)
    if constraint == "vertices":
        return min(measurements, key=lambda m: m.vertices)
    return min(measurements, key=lambda m: m.measured_error)
