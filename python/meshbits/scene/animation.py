"""Animations compressed (:func:`compress_animations`): every sampler of a glTF's
animations thinned to fewer keys and its values quantized, within a stated tolerance in
world units, measured as how far any node, and anything it carries, moves from its
original path (:mod:`.animation_paths`).

For each animation:

1. Its samplers are read and checked (:mod:`.animation_input`); a sampler used by no
   channel, by a channel without a node, or a cubic spline is copied as it is, and an
   animation with bad keys (not finite, times not increasing) or a
   ``KHR_animation_pointer`` channel is copied whole. Each is counted in the report.
2. The times it is measured at: every key time of its samplers, and ``BETWEEN`` evenly
   spaced times inside each interval between them.
3. Each channel gets a share of the tolerance ``tau`` in its own terms
   (:func:`meshbits.scene.keyframes.value_error`), from how far one unit of its error
   can move a point of the world: a translation ``f tau / s_parent`` (``s_parent`` the
   largest stretch of its parent's world transform over the animation); a rotation or
   scale ``f tau / rho`` (``rho`` the farthest the node's subtree reaches from its origin
   in world units, influence radii included; a subtree reaching nowhere takes the
   animation's largest reach); weights ``f tau / sigma`` (``sigma`` the mesh's largest
   world stretch). Values are quantized within a fraction ``q`` of that share
   (:func:`meshbits.scene.keyframes.encode_track`), then keys removed within all of it
   (:func:`meshbits.scene.keyframes.thin_keys`); samplers of the same key times keep the
   union of their kept keys when that costs fewer bytes
   (:func:`meshbits.scene.animation_streams.share_keys`).
4. The whole animation is measured: every node's ``dev_n(t)`` at every time of step 2.
   For each ``q`` of :data:`QUANTIZATION_SHARES`, the first share ``f`` of 1, 1/2, ...,
   1/64 whose largest deviation is within ``tau``; the answer of fewer bytes is written.
   If there is none, the animation is copied as it is (counted).

An animation whose samplers would all become one key keeps the last key of a sampler that
ended it, so its duration is unchanged.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..formats.gltf.document import Document
from ..formats.gltf.write import EncodedAnimations, json_text
from .animation_input import SamplerInput, accessor_bytes, read_samplers
from .animation_paths import Skeleton, node_deviations, read_skeleton, world_matrices
from .animation_streams import WrittenSampler, assemble, layout_bytes, share_keys
from .keyframes import EncodedTrack, encode_track, midpoints, sample_track, thin_keys

__all__ = ["AnimationReport", "compress_animations"]

#: Times measured inside each interval between an animation's key times.
BETWEEN = 3
#: Shares of the tolerance each channel is given, tried in this order.
SHARES = tuple(2.0**-k for k in range(7))
#: Fractions of a channel's share its quantization may take, each tried (the layout of
#: fewer bytes is written).
QUANTIZATION_SHARES = (0.25, 0.75)
#: Times measured at once (bounds the memory of the world matrices).
CHUNK = 512


@dataclass(frozen=True)
class AnimationReport:
    """What :func:`compress_animations` did.

    Attributes
    ----------
    tolerance : float
        The stated tolerance (world units): no node, and no point within its influence
        radius (a skinned vertex), moves farther than this from its original path at any
        measured time.
    largest_deviation : float
        The largest such distance measured over the compressed animations (world units).
    animations, samplers : int
        In the input.
    compressed : int
        Samplers written thinned and quantized.
    copied : dict
        Samplers written as they were, counted by why.
    keys_before, keys_after : int
        Keys of the compressed samplers, before and after.
    bytes_before, bytes_after : int
        Bytes of every sampler's data (input and output accessors, each once), in the
        input and in the output (compressed bytes where meshopt compresses them).
    times_measured : int
        Times at which every node's deviation was measured, over all animations.
    """

    tolerance: float
    largest_deviation: float = 0.0
    animations: int = 0
    samplers: int = 0
    compressed: int = 0
    copied: dict[str, int] = field(default_factory=dict)
    keys_before: int = 0
    keys_after: int = 0
    bytes_before: int = 0
    bytes_after: int = 0
    times_measured: int = 0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @staticmethod
    def input_kept(report: AnimationReport) -> AnimationReport:
        """The report when the input file itself was written: every sampler copied."""
        return AnimationReport(
            tolerance=report.tolerance,
            animations=report.animations,
            samplers=report.samplers,
            copied={"the input file written as it was": report.samplers} if report.samplers else {},
            bytes_before=report.bytes_before,
            bytes_after=report.bytes_before,
        )

    def note(self) -> str:
        """The report's sentence, for the scene's message ('' without animations)."""
        if not self.samplers:
            return ""
        copied = sum(self.copied.values())
        text = (
            f"; animations: {self.compressed} of {self.samplers} samplers compressed, "
            f"{self.bytes_before:,} -> {self.bytes_after:,} bytes, every node's path within "
            f"{self.tolerance:.4g} (largest {self.largest_deviation:.4g})"
        )
        if copied:
            reasons = "; ".join(f"{n} {why}" for why, n in self.copied.items())
            text += f", {copied} copied as they were ({reasons})"
        return text


@dataclass
class _Measure:
    """An animation's measurement: the times, the skeleton, and each node's sensitivities
    (parent stretch, reach, morph stretch) over the original animation."""

    skeleton: Skeleton
    times: np.ndarray
    parent_scale: np.ndarray
    reach: np.ndarray
    morph_scale: np.ndarray


def _sampled(
    samplers: list[SamplerInput], tracks: dict[int, tuple[np.ndarray, np.ndarray]], at: np.ndarray
) -> tuple[dict[tuple[int, str], np.ndarray], dict[int, np.ndarray]]:
    """Every channel's values at times ``at`` (``(node, path) -> (m, w)``), the sampler's
    written keys where ``tracks`` has them (``sampler -> (times, values)``), else its
    input's; and the weights by node."""
    out: dict[tuple[int, str], np.ndarray] = {}
    weights: dict[int, np.ndarray] = {}
    for s in samplers:
        if s.path is None:
            continue
        times, values = tracks.get(s.index, (s.times, s.values))
        sampled = sample_track(times, values, s.interpolation, s.path, at)
        for node in s.nodes:
            if s.path == "weights":
                weights[node] = sampled
            else:
                out[(node, s.path)] = sampled
    return out, weights


def _morph_scales(skeleton: Skeleton, world: np.ndarray) -> np.ndarray:
    """Each node's largest world stretch of its morph targets' displacements at each
    time (``(count, nodes)``; its skin's joints' for a skinned mesh)."""
    out = np.linalg.norm(world[..., :3, :3], ord=2, axis=(-2, -1))
    for node, (joints, ibm) in skeleton.skin_joints.items():
        bound = world[:, joints] @ ibm[None, : len(joints)]
        out[:, node] = np.linalg.norm(bound[..., :3, :3], ord=2, axis=(-2, -1)).max(axis=1)
    return out


def _measure(skeleton: Skeleton, samplers: list[SamplerInput], times: np.ndarray) -> _Measure:
    """The sensitivities of every node over the original animation (module docstring)."""
    n = len(skeleton.parents)
    subtrees = [skeleton.subtree(i) for i in range(n)]
    parent_scale, reach, morph = np.ones(n), np.zeros(n), np.zeros(n)
    for start in range(0, len(times), CHUNK):
        at = times[start : start + CHUNK]
        tracks, _ = _sampled(samplers, {}, at)
        world = world_matrices(skeleton, tracks, len(at))
        stretch = np.linalg.norm(world[..., :3, :3], ord=2, axis=(-2, -1))
        origins = world[..., :3, 3]
        morph = np.maximum(morph, _morph_scales(skeleton, world).max(axis=0))
        for i in range(n):
            parent = int(skeleton.parents[i])
            if parent >= 0:
                parent_scale[i] = max(parent_scale[i], float(stretch[:, parent].max()))
            below = subtrees[i]
            far = np.linalg.norm(origins[:, below] - origins[:, i : i + 1], axis=-1)
            far += skeleton.radius[below][None, :] * stretch[:, below]
            reach[i] = max(reach[i], float(far.max()))
    floor = float(reach.max()) if reach.max() > 0 else 1.0
    reach = np.where(reach > 0, reach, floor)
    return _Measure(skeleton, times, parent_scale, reach, np.maximum(morph, 1e-300))


def _share(measure: _Measure, sampler: SamplerInput, tolerance: float) -> float:
    """A sampler's tolerance in its own terms (module docstring, step 3)."""
    shares = []
    for node in sampler.nodes:
        if sampler.path == "translation":
            shares.append(tolerance / measure.parent_scale[node])
        elif sampler.path == "weights":
            shares.append(tolerance / measure.morph_scale[node])
        else:
            shares.append(tolerance / measure.reach[node])
    return float(min(shares))


def _target_reach(skeleton: Skeleton, sampler: SamplerInput) -> np.ndarray | None:
    """``D_k`` of the targets a weights sampler drives (the largest over its nodes)."""
    if sampler.path != "weights":
        return None
    width = sampler.values.shape[1]
    reach = np.zeros(width)
    for node in sampler.nodes:
        own = skeleton.morph_reach.get(node, np.zeros(0))[:width]
        reach[: len(own)] = np.maximum(reach[: len(own)], own)
    return reach


def _thinned(
    sampler: SamplerInput, share: float, quantization: float, meshopt: bool, skeleton: Skeleton
) -> tuple[np.ndarray, EncodedTrack] | None:
    """A sampler's kept keys and their encoding within ``share``; None if no encoding is
    within ``quantization`` of it."""
    assert sampler.path is not None
    reach = _target_reach(skeleton, sampler)
    encoded = encode_track(sampler.path, sampler.values, quantization * share, meshopt, reach)
    if encoded is None:
        return None
    kept = thin_keys(
        sampler.times,
        sampler.values,
        encoded.decoded,
        sampler.interpolation,
        sampler.path,
        share,
        reach,
    )
    return kept, encoded


def _subset(track: EncodedTrack, kept: np.ndarray) -> EncodedTrack:
    """The encoded rows of the kept keys."""
    rows = np.frombuffer(track.raw, dtype=np.uint8).reshape(len(track.decoded), track.stride)
    plain = np.frombuffer(track.plain, dtype=np.uint8).reshape(len(track.decoded), -1)
    return EncodedTrack(
        rows[kept].tobytes(),
        track.stride,
        track.filter,
        track.decoded[kept],
        track.bits,
        track.component_type,
        track.normalized,
        plain[kept].tobytes(),
    )


def _keep_duration(samplers: list[SamplerInput], kept: dict[int, np.ndarray]) -> None:
    """Give back a sampler its last key when thinning would end the animation earlier."""
    end = max(float(s.times[-1]) for s in samplers)
    ends = [
        float(s.times[kept[s.index][-1]]) if s.index in kept else float(s.times[-1])
        for s in samplers
    ]
    if max(ends) >= end:
        return
    for s in samplers:
        if s.index in kept and float(s.times[-1]) == end:
            kept[s.index] = np.append(kept[s.index], len(s.times) - 1)
            return


def _largest_deviation(
    measure: _Measure,
    samplers: list[SamplerInput],
    tracks: dict[int, tuple[np.ndarray, np.ndarray]],
) -> float:
    """The largest ``dev_n(t)`` over every node and measured time."""
    skeleton, largest = measure.skeleton, 0.0
    for start in range(0, len(measure.times), CHUNK):
        at = measure.times[start : start + CHUNK]
        before, weights_before = _sampled(samplers, {}, at)
        after, weights_after = _sampled(samplers, tracks, at)
        change = {}
        for s in samplers:
            if s.path == "weights" and s.index in tracks:
                reach = _target_reach(skeleton, s)
                for node in s.nodes:
                    change[node] = np.abs(weights_after[node] - weights_before[node]) @ reach
        original = world_matrices(skeleton, before, len(at))
        written = world_matrices(skeleton, after, len(at))
        deviation = node_deviations(skeleton, original, written, change)
        largest = max(largest, float(deviation.max(initial=0.0)))
    return largest


def _attempt(
    measure: _Measure,
    samplers: list[SamplerInput],
    share: float,
    quantization: float,
    meshopt: bool,
) -> tuple[dict[int, tuple[np.ndarray, EncodedTrack]], dict[int, str]]:
    """Every compressible sampler thinned at ``share`` of the tolerance: ``sampler ->
    (kept keys, encoding of every key)``, and the samplers no encoding could take."""
    chosen: dict[int, tuple[np.ndarray, EncodedTrack]] = {}
    refused: dict[int, str] = {}
    for s in samplers:
        if s.copied is not None:
            continue
        if s.path == "weights" and _target_reach(measure.skeleton, s) is None:
            refused[s.index] = "weights of a node without morph targets"
            continue
        result = _thinned(s, _share(measure, s, share), quantization, meshopt, measure.skeleton)
        if result is None:
            refused[s.index] = "no encoding within its share of the tolerance"
        else:
            chosen[s.index] = result
    kept = {k: v[0] for k, v in chosen.items()}
    _keep_duration(samplers, kept)
    return {k: (kept[k], chosen[k][1]) for k in chosen}, refused


def _cheaper_layout(
    measure: _Measure,
    samplers: list[SamplerInput],
    chosen: dict[int, tuple[np.ndarray, EncodedTrack]],
    deviation: float,
    tolerance: float,
    meshopt: bool,
) -> tuple[dict[int, tuple[np.ndarray, EncodedTrack]], float]:
    """The kept keys of :func:`meshbits.scene.animation_streams.share_keys` when they
    cost fewer bytes and are still within the tolerance (measured again), with the
    largest deviation; else ``chosen`` as it was."""
    by_index = samplers_by_index(samplers)
    shared = share_keys(
        {
            k: (by_index[k].times, kept, track, by_index[k].path or "")
            for k, (kept, track) in chosen.items()
        },
        meshopt,
        _subset,
    )
    if all(np.array_equal(shared[k], kept) for k, (kept, _) in chosen.items()):
        return chosen, deviation
    tracks = {
        k: (by_index[k].times[shared[k]], track.decoded[shared[k]])
        for k, (_, track) in chosen.items()
    }
    again = _largest_deviation(measure, samplers, tracks)
    if again > tolerance:
        return chosen, deviation
    return {k: (shared[k], track) for k, (_, track) in chosen.items()}, again


_Found = tuple[dict[int, tuple[np.ndarray, EncodedTrack]], dict[int, str], float]


def _search(
    measure: _Measure,
    samplers: list[SamplerInput],
    tolerance: float,
    quantization: float,
    meshopt: bool,
) -> _Found | None:
    """The first share of :data:`SHARES` whose animation is within ``tolerance``: the
    samplers written (``sampler -> (kept keys, their encoding)``), those refused, the
    largest deviation; None when none is."""
    by_index = samplers_by_index(samplers)
    for share in SHARES:
        chosen, refused = _attempt(measure, samplers, share * tolerance, quantization, meshopt)
        tracks = {
            k: (by_index[k].times[kept], track.decoded[kept]) for k, (kept, track) in chosen.items()
        }
        for s in samplers:
            if s.index in refused:
                s.copied = refused[s.index]
        deviation = _largest_deviation(measure, samplers, tracks)
        if deviation <= tolerance:
            chosen, deviation = _cheaper_layout(
                measure, samplers, chosen, deviation, tolerance, meshopt
            )
            written = {k: (kept, _subset(track, kept)) for k, (kept, track) in chosen.items()}
            return written, refused, deviation
    return None


def _found_bytes(found: _Found, samplers: list[SamplerInput], meshopt: bool) -> int:
    """What a search's answer costs written (:func:`layout_bytes`)."""
    by_index = samplers_by_index(samplers)
    return layout_bytes(
        [
            WrittenSampler(0, k, by_index[k].times[kept], by_index[k].path or "", track)
            for k, (kept, track) in found[0].items()
        ],
        meshopt,
    )


def _compress_animation(
    skeleton: Skeleton, samplers: list[SamplerInput], tolerance: float, meshopt: bool
) -> tuple[dict[int, tuple[np.ndarray, EncodedTrack]], dict[int, str], float, int]:
    """One animation's samplers written (``sampler -> (kept keys, their encoding)``),
    those copied and why, the largest deviation measured and the times measured at: the
    answer of fewer bytes over :data:`QUANTIZATION_SHARES`."""
    keyed = [s.times for s in samplers if s.path is not None]
    union = np.unique(np.concatenate(keyed)) if keyed else np.zeros(0)
    times = midpoints(union, BETWEEN)
    if not len(times) or tolerance <= 0:
        return {}, {}, 0.0, 0
    measure = _measure(skeleton, samplers, times)
    best: _Found | None = None
    for quantization in QUANTIZATION_SHARES:
        found = _search(measure, samplers, tolerance, quantization, meshopt)
        if found is not None and (
            best is None
            or _found_bytes(found, samplers, meshopt) < _found_bytes(best, samplers, meshopt)
        ):
            best = found
    if best is None:
        reason = f"not within the tolerance at 1/{int(1 / SHARES[-1])} of it a channel"
        return {}, {s.index: reason for s in samplers if s.copied is None}, 0.0, len(times)
    return (*best, len(times))


def samplers_by_index(samplers: list[SamplerInput]) -> dict[int, SamplerInput]:
    """Samplers by their index in their animation."""
    return {s.index: s for s in samplers}


def _input_bytes(document: Document) -> int:
    """Bytes of every sampler's input and output accessors, each once."""
    accessors = {
        sampler[key]
        for animation in document.json.get("animations", [])
        for sampler in animation.get("samplers", [])
        for key in ("input", "output")
    }
    return sum(accessor_bytes(document, a) for a in accessors)


#: Why an animation whose compressed data would not be smaller is copied.
NOT_SMALLER = "compressed, it would not be smaller"


def _animation(
    document: Document, skeleton: Skeleton, index: int, tolerance: float, meshopt: bool
) -> tuple[list[SamplerInput], str | None, dict[int, tuple[np.ndarray, EncodedTrack]], float, int]:
    """Animation ``index`` compressed: its samplers (each copied one saying why), why it
    is copied whole (or None), the samplers written, the largest deviation and the times
    measured. Its samplers are copied when their compressed data and accessors would not
    be fewer bytes than the input's."""
    samplers, whole = read_samplers(document, index)
    if whole is not None:
        return samplers, whole, {}, 0.0, 0
    chosen, refused, deviation, times = _compress_animation(skeleton, samplers, tolerance, meshopt)
    if tolerance <= 0:
        refused = {s.index: "a tolerance of 0" for s in samplers}
    for s in samplers:
        if s.copied is None and s.index in refused:
            s.copied = refused[s.index]
    if chosen:
        found: _Found = (chosen, refused, deviation)
        specs = document.json["animations"][index]["samplers"]
        used = {specs[k][key] for k in chosen for key in ("input", "output")}
        before = sum(accessor_bytes(document, x) for x in used) + len(
            json_text([document.json["accessors"][x] for x in used])
        )
        if _found_bytes(found, samplers, meshopt) >= before:
            for s in samplers:
                if s.index in chosen:
                    s.copied = NOT_SMALLER
            return samplers, None, {}, 0.0, times
    return samplers, None, chosen, deviation, times


def compress_animations(
    document: Document, tolerance: float, meshopt: bool
) -> tuple[EncodedAnimations | None, AnimationReport]:
    """Every animation of ``document`` compressed within ``tolerance`` (world units;
    module docstring), its values with meshoptimizer's filters when ``meshopt``, else
    rotations as normalized shorts and the rest as float32. Returns the data to write
    (None when nothing is compressed) and the report."""
    animations = document.json.get("animations", [])
    total = sum(len(a.get("samplers", [])) for a in animations)
    if not total:
        return None, AnimationReport(tolerance=tolerance, animations=len(animations))
    skeleton = read_skeleton(document)
    written: list[WrittenSampler] = []
    copied: dict[str, int] = {}
    copied_accessors: set[int] = set()
    largest, measured, keys_before, keys_after = 0.0, 0, 0, 0
    for a, animation in enumerate(animations):
        samplers, whole, chosen, deviation, times = _animation(
            document, skeleton, a, tolerance, meshopt
        )
        largest, measured = max(largest, deviation), measured + times
        by_index = samplers_by_index(samplers)
        for k, sampler in enumerate(animation.get("samplers", [])):
            if k in chosen:
                kept, track = chosen[k]
                s = by_index[k]
                written.append(WrittenSampler(a, k, s.times[kept], s.path or "", track))
                keys_before, keys_after = keys_before + len(s.times), keys_after + len(kept)
                continue
            why = whole or (by_index[k].copied if k in by_index else None) or "not compressed"
            copied[why] = copied.get(why, 0) + 1
            copied_accessors.update((sampler["input"], sampler["output"]))
    encoded = assemble(written, meshopt) if written else None
    after = sum(accessor_bytes(document, x) for x in copied_accessors)
    if encoded is not None:
        after += sum(
            len(s["data"]) if s["data"] is not None else len(s["raw"]) for s in encoded.streams
        )
    return encoded, AnimationReport(
        tolerance=tolerance,
        largest_deviation=largest,
        animations=len(animations),
        samplers=total,
        compressed=len(written),
        copied=copied,
        keys_before=keys_before,
        keys_after=keys_after,
        bytes_before=_input_bytes(document),
        bytes_after=after,
        times_measured=measured,
    )
