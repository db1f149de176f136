"""Compressed samplers laid out for the writer
(:class:`meshbits.formats.gltf.write.EncodedAnimations`): as gltfpack lays them out, one
bufferView per kind of record (key times; rotations; translations and scales; weights)
shared by every sampler of the file, each sampler's accessors at their offsets in it, so
that meshoptimizer's vertex codec compresses similar records together. Key times that
several samplers keep alike are written once. With meshopt each bufferView is written the
smallest of three ways that all give a reader the same values: its filter's records
through the vertex codec (``EXT_meshopt_compression``, mode ``ATTRIBUTES``), the values
themselves through the vertex codec (no filter), or the values plainly (small streams,
where the codec's headers cost more than they save); the vertex codec only for records
of a multiple of 4 bytes, at most 256. Without meshopt, plainly."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .. import _core
from ..formats.gltf.write import EncodedAnimations, json_number, json_text
from .keyframes import EncodedTrack

__all__ = ["WrittenSampler", "assemble", "layout_bytes", "share_keys"]

#: Largest record the vertex codec encodes (bytes).
VERTEX_CODEC_STRIDE = 256


@dataclass(frozen=True)
class WrittenSampler:
    """A sampler as written: its ``animation`` and ``sampler`` indices, the kept key
    ``times`` (float32 values), its ``path`` and its values (``track``: the kept keys)."""

    animation: int
    sampler: int
    times: np.ndarray = field(repr=False)
    path: str
    track: EncodedTrack = field(repr=False)


@dataclass
class _Stream:
    """A bufferView being laid out: its records under its filter (``parts``) and as a
    reader gets them (``plain``)."""

    stride: int
    filter: str
    parts: list[bytes] = field(default_factory=list)
    plain: list[bytes] = field(default_factory=list)
    length: int = 0

    def add(self, raw: bytes, plain: bytes | None = None) -> int:
        offset = self.length
        self.parts.append(raw)
        self.plain.append(raw if plain is None else plain)
        self.length += len(raw)
        return offset

    def written(self, meshopt: bool) -> dict:
        """The stream as the writer takes it: the smallest way (module docstring)."""
        raw, plain = b"".join(self.parts), b"".join(self.plain)
        best: dict = {"raw": plain, "data": None, "stride": self.stride, "filter": "NONE"}
        best["count"] = len(plain) // self.stride
        if not meshopt or self.stride % 4 or self.stride > VERTEX_CODEC_STRIDE:
            return best
        options = [(self.filter, raw)] if self.filter != "NONE" else []
        options.append(("NONE", plain))
        for name, records in options:
            data = _core.meshopt_encode_vertices(np.frombuffer(records, np.uint8), self.stride)
            if len(data) < len(best["data"] if best["data"] is not None else plain):
                best = {**best, "data": data, "filter": name}
        return best


def _value_accessor(written: WrittenSampler, stream: int, offset: int) -> dict:
    """The accessor of a sampler's values: weights as scalars, one per target and key."""
    track = written.track
    width = track.decoded.shape[1]
    keys = len(track.decoded)
    spec: dict = {
        "bufferView": stream,
        "byteOffset": offset,
        "componentType": track.component_type,
        "count": keys * width if written.path == "weights" else keys,
        "type": "SCALAR" if written.path == "weights" else {3: "VEC3", 4: "VEC4"}[width],
    }
    if track.normalized:
        spec["normalized"] = True
    return spec


def assemble(samplers: list[WrittenSampler], meshopt: bool) -> EncodedAnimations:
    """The streams, accessors and sampler map of the compressed samplers."""
    streams: dict[tuple, _Stream] = {}
    accessors: list[dict] = []
    times_seen: dict[bytes, int] = {}
    mapping: dict[tuple[int, int], tuple[int, int]] = {}

    def stream(key: tuple, stride: int, filter_name: str) -> tuple[int, _Stream]:
        if key not in streams:
            streams[key] = _Stream(stride, filter_name)
        return list(streams).index(key), streams[key]

    for written in samplers:
        times = written.times.astype("<f4")
        raw_times = times.tobytes()
        if raw_times not in times_seen:
            number, target = stream(("times",), 4, "NONE")
            accessors.append(
                {
                    "bufferView": number,
                    "byteOffset": target.add(raw_times),
                    "componentType": 5126,
                    "count": len(times),
                    "type": "SCALAR",
                    "min": [json_number(times[0])],
                    "max": [json_number(times[-1])],
                }
            )
            times_seen[raw_times] = len(accessors) - 1
        track = written.track
        key = ("values", track.filter, track.stride, track.component_type)
        number, target = stream(key, track.stride, track.filter)
        accessors.append(_value_accessor(written, number, target.add(track.raw, track.plain)))
        mapping[(written.animation, written.sampler)] = (times_seen[raw_times], len(accessors) - 1)
    out = [item.written(meshopt) for item in streams.values()]
    return EncodedAnimations(out, accessors, mapping)


def layout_bytes(samplers: list[WrittenSampler], meshopt: bool) -> int:
    """Bytes a set of samplers costs written alone: its streams and its accessors' JSON."""
    encoded = assemble(samplers, meshopt)
    data = sum(len(s["raw"] if s["data"] is None else s["data"]) for s in encoded.streams)
    return data + len(json_text(encoded.accessors))


def _layout(
    tracks: dict[int, tuple[np.ndarray, np.ndarray, EncodedTrack, str]],
    keys: dict[int, np.ndarray],
    meshopt: bool,
    subset: Callable[[EncodedTrack, np.ndarray], EncodedTrack],
) -> int:
    """:func:`layout_bytes` of the samplers of ``keys`` keeping those keys."""
    written = [
        WrittenSampler(0, k, tracks[k][0][kept], tracks[k][3], subset(tracks[k][2], kept))
        for k, kept in keys.items()
    ]
    return layout_bytes(written, meshopt)


def share_keys(
    tracks: dict[int, tuple[np.ndarray, np.ndarray, EncodedTrack, str]],
    meshopt: bool,
    subset: Callable[[EncodedTrack, np.ndarray], EncodedTrack],
) -> dict[int, np.ndarray]:
    """Kept keys that cost fewer bytes: ``tracks`` maps a sampler to ``(its input's key
    times, its kept keys, the encoding of every key, its path)``. Samplers with the same
    input times and more than one kept key may all keep the union of their kept keys
    instead: one key-time accessor for all of them, and records a key apart, which the
    vertex codec compresses better, at the price of more records. The cheaper of the two
    layouts (:func:`layout_bytes`) is returned, per group of samplers."""
    groups: dict[bytes, list[int]] = {}
    for k, (times, kept, _, _) in tracks.items():
        if len(kept) > 1:
            groups.setdefault(np.asarray(times, dtype=np.float64).tobytes(), []).append(k)
    out = {k: kept for k, (_, kept, _, _) in tracks.items()}
    for members in groups.values():
        if len(members) < 2:
            continue
        union = np.unique(np.concatenate([tracks[k][1] for k in members]))
        shared = {k: union for k in members}
        own = {k: tracks[k][1] for k in members}
        if _layout(tracks, shared, meshopt, subset) < _layout(tracks, own, meshopt, subset):
            out.update(shared)
    return out
