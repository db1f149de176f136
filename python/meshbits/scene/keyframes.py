"""One animation track (a sampler's keys) sampled, quantized and thinned.

A track is a sampler's key times ``t_0 < ... < t_{n-1}`` (seconds) and values, ``(n, w)``
rows: a translation or scale (w = 3), a rotation quaternion ``(x, y, z, w)`` (w = 4), or
one morph weight per target (w = targets). Sampled as glTF 2.0 defines (its appendix on
interpolation): before the first key the first value, after the last the last; ``STEP``
holds a key's value until the next key; ``LINEAR`` interpolates linearly, and rotations
by spherical linear interpolation along the shorter arc (``slerp(a, b, t)`` with ``b``
negated when ``a . b < 0``); ``CUBICSPLINE`` is glTF's cubic Hermite spline (sampled
to measure, never thinned here: the caller copies such tracks).

Values are quantized by meshoptimizer's filters and read back through its own decoder
(:func:`meshbits._core.meshopt_decode`, the reference of ``EXT_meshopt_compression``):
rotations by the ``QUATERNION`` filter at K bits (4 to 16), translations, scales and
weights by the ``EXPONENTIAL`` filter at K mantissa bits (1 to 24, one exponent per
component over the track); without meshopt, rotations as normalized shorts and the rest
as float32. Keys are then removed greedily (:func:`thin_keys`): from each kept key the next
kept one is the farthest whose interpolation of the decoded values stays within the
track's tolerance of the original track at every original key and midway between keys.

Errors of a track's value (:func:`value_error`), in the track's own terms: a translation
the length of the difference (parent units); a rotation ``2 sqrt(1 - d^2)`` with ``d`` the
cosine of half the angle between the normalized quaternions (the spectral norm of the
difference of their rotation matrices: what a point at distance 1 moves); a scale the
largest component difference; weights ``sum_k |dw_k| D_k`` with ``D_k`` the largest
displacement of target ``k`` (mesh units).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _core

__all__ = [
    "EncodedTrack",
    "encode_track",
    "midpoints",
    "sample_track",
    "slerp",
    "thin_keys",
    "value_error",
]

#: Most components a row of the exponential filter takes (its records are at most 256
#: bytes).
MAX_EXPONENTIAL_WIDTH = 64

#: Quaternions closer than this (1 - |a . b|) are interpolated linearly (slerp's weights
#: are 0/0 there; the two agree to float64 rounding).
SLERP_LINEAR = 1e-9


def slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """glTF's spherical linear interpolation of rows of quaternions ``a`` and ``b``
    (``(m, 4)``) at fractions ``t`` (``(m,)``): along the shorter arc, not normalized."""
    d = np.einsum("ij,ij->i", a, b)
    sign = np.where(d < 0, -1.0, 1.0)
    d = np.minimum(np.abs(d), 1.0)
    angle = np.arccos(d)
    sin = np.sin(angle)
    near = 1.0 - d < SLERP_LINEAR
    safe = np.where(near, 1.0, sin)
    wa = np.where(near, 1.0 - t, np.sin((1.0 - t) * angle) / safe)
    wb = np.where(near, t, np.sin(t * angle) / safe) * sign
    return a * wa[:, None] + b * wb[:, None]


def _slerp_pair(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """:func:`slerp` of one pair of quaternions at many fractions."""
    d = float(a @ b)
    if d < 0:
        b, d = -b, -d
    d = min(d, 1.0)
    if 1.0 - d < SLERP_LINEAR:
        wa, wb = 1.0 - t, t
    else:
        angle = math.acos(d)
        sin = math.sin(angle)
        wa, wb = np.sin((1.0 - t) * angle) / sin, np.sin(t * angle) / sin
    return a * wa[:, None] + b * wb[:, None]


def sample_track(
    times: np.ndarray, values: np.ndarray, interpolation: str, path: str, at: np.ndarray
) -> np.ndarray:
    """A ``LINEAR`` or ``STEP`` track's values at times ``at`` (glTF's sampling: clamped
    to the first and last keys)."""
    times = np.asarray(times, dtype=np.float64)
    at = np.asarray(at, dtype=np.float64)
    if interpolation == "CUBICSPLINE":
        return _sample_cubic(times, values, path, at)
    if len(times) == 1:
        return np.repeat(values[:1], len(at), axis=0)
    k = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 2)
    if interpolation == "STEP":
        held = np.where(at >= times[-1], len(times) - 1, k)
        return values[held]
    span = times[k + 1] - times[k]
    t = np.clip((at - times[k]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    if path == "rotation":
        return slerp(values[k], values[k + 1], t)
    return values[k] * (1.0 - t)[:, None] + values[k + 1] * t[:, None]


def _sample_cubic(times: np.ndarray, values: np.ndarray, path: str, at: np.ndarray) -> np.ndarray:
    """glTF's cubic Hermite spline: ``values`` are (in-tangent, value, out-tangent) per
    key; ``p(s) = (2s^3 - 3s^2 + 1) v_k + (s^3 - 2s^2 + s) dt b_k + (-2s^3 + 3s^2) v_k+1
    + (s^3 - s^2) dt a_k+1``, a rotation normalized."""
    points = values[1::3]
    if len(times) == 1:
        return np.repeat(points[:1], len(at), axis=0)
    k = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 2)
    dt = times[k + 1] - times[k]
    s = np.clip((at - times[k]) / np.where(dt > 0, dt, 1.0), 0.0, 1.0)[:, None]
    s2, s3 = s * s, s * s * s
    out = (
        (2 * s3 - 3 * s2 + 1) * points[k]
        + (s3 - 2 * s2 + s) * dt[:, None] * values[3 * k + 2]
        + (-2 * s3 + 3 * s2) * points[k + 1]
        + (s3 - s2) * dt[:, None] * values[3 * (k + 1)]
    )
    if path == "rotation":
        out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)
    return out


def midpoints(times: np.ndarray, between: int) -> np.ndarray:
    """The key times and ``between`` evenly spaced times inside each interval, in order:
    key ``k`` at index ``k (between + 1)``."""
    times = np.asarray(times, dtype=np.float64)
    if len(times) < 2 or between < 1:
        return times.copy()
    fractions = np.arange(0, between + 1) / (between + 1)
    grid = times[:-1, None] + np.diff(times)[:, None] * fractions[None, :]
    return np.concatenate([grid.reshape(-1), times[-1:]])


def value_error(
    path: str, original: np.ndarray, other: np.ndarray, target_reach: np.ndarray | None = None
) -> np.ndarray:
    """Per row, how far ``other`` is from ``original`` in the track's terms (module
    docstring); ``target_reach`` is ``D_k`` for weights."""
    if path == "rotation":
        a = original / np.linalg.norm(original, axis=1, keepdims=True)
        b = other / np.maximum(np.linalg.norm(other, axis=1, keepdims=True), 1e-300)
        d = np.minimum(np.abs(np.einsum("ij,ij->i", a, b)), 1.0)
        return 2.0 * np.sqrt(np.maximum(1.0 - d * d, 0.0))
    if path == "translation":
        return np.linalg.norm(original - other, axis=1)
    if path == "weights":
        reach = np.ones(original.shape[1]) if target_reach is None else target_reach
        return np.abs(original - other) @ reach
    return np.abs(original - other).max(axis=1)


@dataclass(frozen=True)
class EncodedTrack:
    """A track's values as written: ``raw`` the filter's records (``stride`` bytes a
    key), ``filter`` the meshopt filter (``"NONE"`` for none), ``decoded`` what a reader
    gets back (float64, ``(n, w)``), ``bits`` the filter's K (0 without a filter), the
    accessor's ``componentType`` and ``normalized``, and ``plain`` the bytes a reader
    gets (the filter undone: the same ``decoded`` values stored without a filter)."""

    raw: bytes
    stride: int
    filter: str
    decoded: np.ndarray
    bits: int
    component_type: int
    normalized: bool
    plain: bytes


def _decode_filtered(raw: np.ndarray, stride: int, filter_name: str) -> bytes:
    """What meshoptimizer's reference decoder makes of ``raw`` records under a filter."""
    flat = np.ascontiguousarray(raw, dtype=np.uint8).reshape(-1)
    count = len(flat) // stride
    data = _core.meshopt_encode_vertices(flat, stride)
    return _core.meshopt_decode(data, count, stride, "ATTRIBUTES", filter_name)


def _quaternions(values: np.ndarray, bits: int) -> EncodedTrack:
    unit = values / np.linalg.norm(values, axis=1, keepdims=True)
    raw = _core.meshopt_encode_quaternions(np.ascontiguousarray(unit, dtype=np.float32), bits)
    shorts = np.frombuffer(_decode_filtered(raw, 8, "QUATERNION"), dtype="<i2").reshape(-1, 4)
    decoded = np.maximum(shorts.astype(np.float64) / 32767.0, -1.0)
    plain = shorts.astype("<i2").tobytes()
    return EncodedTrack(raw.tobytes(), 8, "QUATERNION", decoded, bits, 5122, True, plain)


def _exponential(values: np.ndarray, bits: int) -> EncodedTrack:
    width = values.shape[1]
    raw = _core.meshopt_encode_exponential(
        np.ascontiguousarray(values, dtype=np.float32), bits, "component"
    )
    floats = np.frombuffer(_decode_filtered(raw, 4 * width, "EXPONENTIAL"), dtype="<f4")
    decoded = floats.reshape(-1, width).astype(np.float64)
    plain = floats.astype("<f4").tobytes()
    return EncodedTrack(raw.tobytes(), 4 * width, "EXPONENTIAL", decoded, bits, 5126, False, plain)


def _plain(values: np.ndarray, path: str) -> EncodedTrack:
    """Without meshopt: rotations as normalized shorts (glTF 2.0 allows them), the rest
    as float32."""
    if path == "rotation":
        unit = values / np.linalg.norm(values, axis=1, keepdims=True)
        shorts = np.round(unit * 32767.0).astype("<i2")
        decoded = np.maximum(shorts.astype(np.float64) / 32767.0, -1.0)
        raw = shorts.tobytes()
        return EncodedTrack(raw, 8, "NONE", decoded, 16, 5122, True, raw)
    floats = values.astype("<f4")
    decoded = floats.astype(np.float64)
    raw = floats.tobytes()
    return EncodedTrack(raw, 4 * values.shape[1], "NONE", decoded, 0, 5126, False, raw)


def encode_track(
    path: str,
    values: np.ndarray,
    tolerance: float,
    meshopt: bool,
    target_reach: np.ndarray | None = None,
) -> EncodedTrack | None:
    """A track's values at the fewest filter bits whose decoded values are within
    ``tolerance`` of ``values`` (:func:`value_error`) at every key (a rotation by the
    quaternion filter, then beyond its 16 bits by the exponential one on its float
    components); without ``meshopt`` the plain encoding when within it (a rotation as
    normalized shorts, then float32). None when no encoding is."""
    if meshopt and values.shape[1] <= MAX_EXPONENTIAL_WIDTH:
        options = [(_exponential, bits) for bits in range(1, 25)]
        if path == "rotation":
            # Beyond the quaternion filter's 16 bits, float rotations through the
            # exponential filter (glTF allows float rotations) before plain float32.
            options = [(_quaternions, bits) for bits in range(4, 17)] + options[16:]
        for encode, bits in options:
            encoded = encode(values, bits)
            if value_error(path, values, encoded.decoded, target_reach).max() <= tolerance:
                return encoded
    plain = _plain(values, path)
    if value_error(path, values, plain.decoded, target_reach).max() <= tolerance:
        return plain
    if path == "rotation":
        floats = values.astype("<f4")
        decoded = floats.astype(np.float64)
        raw = floats.tobytes()
        return EncodedTrack(raw, 16, "NONE", decoded, 0, 5126, False, raw)
    return None


def _segment_ok(
    track: tuple[np.ndarray, np.ndarray, str, str],
    check: tuple[np.ndarray, np.ndarray, int],
    i: int,
    j: int,
    tolerance: float,
    target_reach: np.ndarray | None,
) -> bool:
    """Whether keys ``i`` and ``j`` alone (the decoded values) stay within ``tolerance``
    of the original at every check time from key ``i`` to key ``j`` (the check times are
    the keys and ``per - 1`` times inside each interval: key ``k`` is check ``k per``)."""
    times, decoded, interpolation, path = track
    check_times, original, per = check
    lo, hi = i * per, j * per + 1
    a, b = decoded[i], decoded[j]
    if interpolation == "STEP":
        kept = np.repeat(a[None], hi - lo, axis=0)
        kept[-1] = b
    else:
        t = (check_times[lo:hi] - times[i]) / (times[j] - times[i])
        if path == "rotation":
            kept = _slerp_pair(a, b, t)
        else:
            kept = a + (b - a) * t[:, None]
    return bool(value_error(path, original[lo:hi], kept, target_reach).max() <= tolerance)


def thin_keys(
    times: np.ndarray,
    original: np.ndarray,
    decoded: np.ndarray,
    interpolation: str,
    path: str,
    tolerance: float,
    target_reach: np.ndarray | None = None,
    between: int = 1,
) -> np.ndarray:
    """The keys to keep (indices, increasing, the first and last among them): greedily,
    from each kept key the farthest next key (searched by doubling, then halving) whose
    segment of ``decoded`` values is within ``tolerance`` of the ``original`` track at
    every original key time and ``between`` times inside each original interval. A track
    within ``tolerance`` of its first decoded value everywhere keeps that key alone."""
    n = len(times)
    check_times = midpoints(times, between)
    reference = sample_track(times, original, interpolation, path, check_times)
    first = np.repeat(decoded[:1], len(check_times), axis=0)
    if value_error(path, reference, first, target_reach).max() <= tolerance:
        return np.array([0])
    if n <= 2:
        return np.arange(n)
    track = (np.asarray(times, dtype=np.float64), decoded, interpolation, path)
    check = (check_times, reference, between + 1)
    kept, i = [0], 0
    while i < n - 1:
        good, step = i + 1, 1
        while good + step < n and _segment_ok(
            track, check, i, good + step, tolerance, target_reach
        ):
            good += step
            step *= 2
        bad = min(good + step, n)
        while bad - good > 1:
            mid = (good + bad) // 2
            if _segment_ok(track, check, i, mid, tolerance, target_reach):
                good = mid
            else:
                bad = mid
        kept.append(good)
        i = good
    return np.array(kept)
