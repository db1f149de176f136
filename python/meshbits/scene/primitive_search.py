"""One primitive's search: the fewest bytes within its local error budget, or the least
error within its own size budget, through the search of :mod:`meshbits.search` with the
scene's primitive codec (Draco or meshopt, its attributes at their bits)."""

from __future__ import annotations

import functools

from ..codecs.attributes import attribute_weights
from ..codecs.draco import draco_max_bits, encode_draco_primitive
from ..codecs.primitive import PrimitiveEncoder, PrimitiveEncoding
from ..codecs.quantized import MESHOPT_MAX_BITS, encode_meshopt_primitive
from ..complexity import shape_complexity
from ..constants import (
    ANSWER_RELATIVE_TOLERANCE,
    CERTIFY_TOLERANCE,
    DRACO_ALPHA,
    DRACO_CONNECTIVITY_BITS,
    FLAT_K,
)
from ..hausdorff import Reference, default_samples
from ..quantize import precision_bits
from ..search import (
    BASE_FACES,
    Attributes,
    Codec,
    Refused,
    Search,
)
from .morph_search import search_morph
from .primitives import KEPT, Job, Outcome

__all__ = ["SCENE_PASSES", "SCENE_SAMPLES", "job_reference", "primitive_codec", "search_primitive"]

#: Area samples per mesh of a primitive's measurements (fewer than a single mesh's: a
#: scene has many), for primitives of at most ``BASE_FACES`` faces; larger ones take
#: :func:`default_samples` (10 per face up to a million): with 100,000 the dragon's
#: sampled answer at 0.001 S failed certification.
SCENE_SAMPLES = 100_000

#: Passes per primitive, and certified passes after an answer that fails certification
#: (compress's defaults: with 4 and 2, the hand at 0.002 S and the dragon at 0.001 S
#: missed budgets that compress meets).
SCENE_PASSES = 6


def primitive_codec(codec: str, job: Job) -> Codec:
    """The job's primitive encoder (``codec``: ``"draco"`` or ``"meshopt"``) as the search
    calls a codec, its attribute bits bound; with meshopt, integer positions only for a job
    in a frame of its own (its nodes carry the dequantization)."""
    encoder: PrimitiveEncoder = encode_draco_primitive
    if codec == "meshopt":
        encoder = functools.partial(encode_meshopt_primitive, integer_positions=job.framed)

    def encode(vertices, faces, attributes, bits, origin, grid_size) -> PrimitiveEncoding:
        return encoder(vertices, faces, attributes, bits, origin, grid_size, job.bits)

    return encode


def job_reference(job: Job, seed: int) -> Reference:
    """The job's original (its BVH and samples), with its K and grid, built once."""
    if job.reference is None:
        original = (job.data.positions, job.data.faces)
        samples = default_samples(len(job.data.faces))
        if len(job.data.faces) <= BASE_FACES:
            samples = min(samples, SCENE_SAMPLES)
        job.reference = Reference(original, samples=samples, seed=seed)
        complexity = shape_complexity(original)
        job.k = max(complexity.k, FLAT_K)
        job.grid_size = complexity.grid_size
    return job.reference


def search_primitive(
    job: Job,
    budget: float,
    codec: str,
    seed: int,
    certify: bool,
    constraint: str = "error",
) -> Outcome:
    """The fewest bytes of one primitive within a local error budget, or with
    ``constraint="size"`` the least error within ``budget`` bits of its own (cached).
    :data:`KEPT` when the encoder refuses every candidate: the job is then kept as it
    was, and says why."""
    if job.kept is not None:
        return KEPT
    if (constraint, budget, certify) in job.results:
        return job.results[(constraint, budget, certify)]
    data = job.data
    reference = job_reference(job, seed)
    if data.targets:
        outcome = search_morph(job, budget, certify, constraint, reference)
        job.results[(constraint, budget, certify)] = outcome
        return outcome
    attributes = None
    if data.attributes:
        attributes = Attributes(
            values=data.attributes,
            weights=attribute_weights(list(data.attributes), budget, job.bits),
            interpolate=not data.skinned,
        )

    max_bits = min(
        MESHOPT_MAX_BITS if codec == "meshopt" else draco_max_bits(job.grid_size),
        precision_bits(data.positions),
    )
    search = Search(
        (data.positions, data.faces),
        reference,
        constraint=constraint,
        budget=budget,
        k=job.k,
        grid_size=job.grid_size,
        max_bits=max_bits,
        format="draco",
        alpha=DRACO_ALPHA,
        connectivity_bits=DRACO_CONNECTIVITY_BITS,
        method="meshopt" if attributes is not None else "auto",
        samples=reference.samples,
        attributes=attributes,
        codec=primitive_codec(codec, job),
    )
    try:
        search.run(SCENE_PASSES)
    except Refused as err:
        job.kept = f"{codec} could not encode it: {err}"
        return KEPT
    if certify and constraint == "error":
        search.certify_answer(CERTIFY_TOLERANCE * budget, SCENE_PASSES)
    elif certify:
        search.bound_answer(ANSWER_RELATIVE_TOLERANCE)
    chosen = search.best() or search.closest()
    outcome = (chosen, search.encoded(chosen), search.levels[chosen.level])
    job.skipped = tuple(
        f"level {index} at {bits} bits: {why}" for (index, bits), why in search.refused.items()
    )
    job.results[(constraint, budget, certify)] = outcome
    return outcome
