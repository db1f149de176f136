"""A size budget split across a scene's primitives: the common world-space error whose
primitives fill the file (the split of bytes that minimises the scene's largest error,
:func:`split_size`), or for a lone primitive its own size search (:func:`size_one`)."""

from __future__ import annotations

import math
from collections.abc import Callable

from .primitive_search import search_primitive
from .primitives import KEPT, Job, Outcome

__all__ = [
    "SIZE_ONE_MARGIN",
    "SIZE_ONE_TRIES",
    "SIZE_SPLIT_AIM",
    "SIZE_SPLIT_FILL",
    "SIZE_SPLIT_PASSES",
    "log_line",
    "size_one",
    "split_size",
]

#: Passes of the size split: common world errors tried.
SIZE_SPLIT_PASSES = 8

#: Searches of a lone primitive's size budget (each after the file was over) and the
#: bytes kept to spare when its share shrinks.
SIZE_ONE_TRIES = 3
SIZE_ONE_MARGIN = 16

#: The size split stops at a file of at least this fraction of the budget.
SIZE_SPLIT_FILL = 0.97

#: The size split aims at this fraction of the budget (measured sizes scatter around the
#: log-log line).
SIZE_SPLIT_AIM = 0.985

#: The outcomes of every job searched within one common world error (world units).
RunAt = Callable[[float], list[Outcome]]
#: Bytes of the file written with the given outcomes.
FileBytes = Callable[[list[Outcome]], int]


def split_size(
    jobs: list[Job], size_bits: float, run_at: RunAt, world_size: float, file_bytes: FileBytes
) -> tuple[list[Outcome], float]:
    """The common world-space error whose primitives fill the size budget: the split of
    bytes that minimises the scene's largest error. Each try is judged by the bytes of the
    file it makes (``file_bytes``: the document rebuilt around it, images, JSON and the
    codec's own entries included). The next error comes from the sizes measured so far,
    bytes against error on a log-log scale: the line through the two tries that bracket
    the budget, or through the last two (bytes fall about as 1/E) until they do. It stops
    when a file fills :data:`SIZE_SPLIT_FILL` of the budget, when the bracket is within 2%,
    or after :data:`SIZE_SPLIT_PASSES` tries. The answer is the try within the budget with
    the least measured world-space error (not the least target)."""
    budget_bytes = size_bits / 8
    aim = SIZE_SPLIT_AIM * budget_bytes
    error = 0.002 * world_size
    best = None  # (measured world error, outcomes, target error)
    tried: list[tuple[float, int]] = []
    for _ in range(SIZE_SPLIT_PASSES):
        outcomes = run_at(error)
        total = file_bytes(outcomes)
        tried.append((error, total))
        if total <= budget_bytes:
            measured = max(
                (
                    o[0].measured_error * job.scale
                    for o, job in zip(outcomes, jobs, strict=True)
                    if o[0] is not None
                ),
                default=0.0,
            )
            if best is None or measured < best[0]:
                best = (measured, outcomes, error)
            if total >= SIZE_SPLIT_FILL * budget_bytes:
                break
        fitting = [(e, t) for e, t in tried if t <= budget_bytes]
        over = [(e, t) for e, t in tried if t > budget_bytes]
        if fitting and over:
            e_fit, t_fit = min(fitting)  # the finest try that fits
            e_over, t_over = max(over)  # the coarsest try over the budget
            if e_fit / e_over < 1.02:
                break
            bracket = (min(e_fit, e_over), max(e_fit, e_over))
            error = log_line(e_fit, t_fit, e_over, t_over, aim, inside=bracket)
        elif len(tried) >= 2:
            (e0, t0), (e1, t1) = tried[-2], tried[-1]
            error = log_line(e0, t0, e1, t1, aim, inside=None)
        else:
            error *= min(max(total / aim, 1 / 16), 16.0)
    if best is None:
        error, _ = min(tried, key=lambda et: et[1])
        return run_at(error), error
    return best[1], best[2]


def size_one(
    job: Job,
    size_bits: float,
    fixed: int,
    codec: str,
    seed: int,
    certify: bool,
    file_bytes: FileBytes,
) -> tuple[list[Outcome], float]:
    """A scene with one primitive to compress: its own size search (as ``compress`` runs
    it), for the budget less what the file keeps besides it (``fixed`` bytes, estimated,
    less than the budget). The answer's file tells the rest exactly; when it is over, the
    primitive's share shrinks by the excess (:data:`SIZE_ONE_TRIES` searches at most).
    Returns the outcome and, as the common error, the answer's certified bound (or its
    error), in world units."""
    budget_bytes = size_bits / 8
    share = budget_bytes - fixed
    outcome = KEPT
    for _ in range(SIZE_ONE_TRIES):
        outcome = search_primitive(job, 8 * share, codec, seed, certify, "size")
        if outcome[0] is None:
            return [outcome], 0.0
        primitive = outcome[1].size_bits // 8
        total = file_bytes([outcome])
        if total <= budget_bytes:
            break
        share = primitive - (total - budget_bytes) - SIZE_ONE_MARGIN
        if share <= 0:
            break
    record = outcome[0]
    upper = record.measured_error_upper
    error = record.measured_error if upper is None else upper
    return [outcome], error * job.scale


def log_line(
    e0: float, t0: float, e1: float, t1: float, aim: float, inside: tuple[float, float] | None
) -> float:
    """The error at which the line through ``(e0, t0)`` and ``(e1, t1)`` (error, bytes),
    on log-log axes, reaches ``aim`` bytes. Its slope is kept between -3 and -1/3 (bytes
    fall as the error grows; a flat or rising pair gives -1); ``inside`` keeps the answer
    at least a tenth of the log-distance from either end of a bracket; without one, a step
    is at most 16 times either way."""
    slope = -1.0
    if e0 > 0 and e1 > 0 and t0 > 0 and t1 > 0 and e0 != e1:
        fitted = math.log(t1 / t0) / math.log(e1 / e0)
        if fitted < 0:
            slope = min(max(fitted, -3.0), -1 / 3)
    error = e1 * (aim / max(t1, 1)) ** (1 / slope)
    if inside is not None:
        lo, hi = math.log(inside[0]), math.log(inside[1])
        margin = 0.1 * (hi - lo)
        return math.exp(min(max(math.log(error), lo + margin), hi - margin))
    return min(max(error, e1 / 16), e1 * 16)
