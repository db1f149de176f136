"""An animation's samplers read and checked for compression: each one's key times and
values with the channels that play it, or the reason it is copied as it is (a cubic
spline, a pointer channel, no channel, bad keys). Bad data never raises here: the
sampler (or, when its keys are bad, its whole animation) is copied and counted."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import MeshFileError
from ..formats.gltf.document import Document
from ..formats.gltf.spec import TYPE_WIDTHS

__all__ = ["SamplerInput", "accessor_bytes", "read_samplers"]

#: Bytes of each glTF component type.
COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}

#: Interpolations a sampler may name (glTF 2.0).
INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")

#: Paths whose samplers are thinned and quantized.
NODE_PATHS = ("translation", "rotation", "scale", "weights")


@dataclass
class SamplerInput:
    """One sampler of an animation: its index, key ``times`` (float64, ``(n,)``),
    ``values`` (float64, ``(n, w)``; ``(3n, w)`` for a cubic spline), ``interpolation``,
    the channel ``path`` and the ``nodes`` its channels drive, and ``copied``: why it is
    written as it is (None: it is compressed)."""

    index: int
    times: np.ndarray = field(repr=False)
    values: np.ndarray = field(repr=False)
    interpolation: str
    path: str | None
    nodes: list[int]
    copied: str | None = None


def accessor_bytes(document: Document, index: int) -> int:
    """Bytes an accessor's elements take, tightly packed (its count times element size)."""
    spec = document.json["accessors"][index]
    code = spec.get("componentType")
    itemsize = COMPONENT_BYTES.get(code, 4)
    width = TYPE_WIDTHS.get(spec.get("type"), 1)
    return int(spec.get("count", 0)) * width * itemsize


def _channels(animation: dict) -> dict[int, list[tuple[int | None, str | None]]]:
    """Each sampler's channels as ``(node, path)``."""
    out: dict[int, list[tuple[int | None, str | None]]] = {}
    for channel in animation.get("channels", []):
        target = channel.get("target") or {}
        out.setdefault(int(channel["sampler"]), []).append((target.get("node"), target.get("path")))
    return out


def _keys(document: Document, sampler: dict, where: str) -> tuple[np.ndarray, np.ndarray]:
    """A sampler's times and values, checked: finite, times increasing, as many values as
    the interpolation needs per key. Raises MeshFileError with what is wrong."""
    times = document.accessor(sampler["input"]).reshape(-1)
    values = document.accessor(sampler["output"])
    if len(times) == 0:
        raise MeshFileError(f"{where} has no keys")
    if not np.isfinite(times).all():
        raise MeshFileError(f"{where}: a key time is not finite")
    if len(times) > 1 and not (np.diff(times) > 0).all():
        bad = int(np.flatnonzero(np.diff(times) <= 0)[0])
        raise MeshFileError(
            f"{where}: key times are not increasing (key {bad + 1} at {times[bad + 1]:.9g} "
            f"after {times[bad]:.9g})"
        )
    if not np.isfinite(values).all():
        raise MeshFileError(f"{where}: a key value is not finite")
    return times.astype(np.float64), values.astype(np.float64)


def _shape(values: np.ndarray, keys: int, interpolation: str, path: str, where: str) -> np.ndarray:
    """Values as ``(keys * per_key, w)``: weights are one scalar a target."""
    per_key = 3 * keys if interpolation == "CUBICSPLINE" else keys
    if path == "weights":
        flat = values.reshape(-1)
        if len(flat) % per_key:
            raise MeshFileError(f"{where}: {len(flat)} weights are not {per_key} keys' worth")
        return flat.reshape(per_key, -1)
    width = 4 if path == "rotation" else 3
    if values.shape != (per_key, width):
        raise MeshFileError(f"{where}: {values.shape[0]} values of {values.shape[1]} for {per_key}")
    if path == "rotation" and (np.linalg.norm(values, axis=1) < 0.5).any():
        raise MeshFileError(f"{where}: a rotation is not a unit quaternion")
    return values


def read_samplers(document: Document, index: int) -> tuple[list[SamplerInput], str | None]:
    """Animation ``index``'s samplers, each with what it drives or why it is copied, and
    why the whole animation is copied (bad keys in one of its samplers, a pointer channel
    that may drive a node), or None."""
    animation = document.json["animations"][index]
    channels = _channels(animation)
    out: list[SamplerInput] = []
    for k, sampler in enumerate(animation.get("samplers", [])):
        where = f"animations[{index}].samplers[{k}]"
        interpolation = sampler.get("interpolation", "LINEAR")
        targets = channels.get(k, [])
        paths = {path for _, path in targets}
        path = next(iter(paths)) if len(paths) == 1 else None
        if "pointer" in paths:
            return out, "a KHR_animation_pointer channel (it may drive a node)"
        try:
            times, values = _keys(document, sampler, where)
            if interpolation not in INTERPOLATIONS:
                raise MeshFileError(f"{where}: unknown interpolation {interpolation!r}")
            if path in NODE_PATHS:
                values = _shape(values, len(times), interpolation, path, where)
        except MeshFileError as error:
            return out, f"bad keys ({error})"
        copied = None
        if not targets:
            copied = "used by no channel"
        elif path not in NODE_PATHS or any(node is None for node, _ in targets):
            copied = "a channel without a node, or channels of different paths"
        elif interpolation == "CUBICSPLINE":
            copied = "cubic spline (kept as it is)"
        nodes = [int(node) for node, _ in targets if node is not None]
        out.append(SamplerInput(k, times, values, interpolation, path, nodes, copied))
    return out, None
