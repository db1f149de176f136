"""Pictures of the model and of measured errors (optional: needs matplotlib).

:func:`error_surface` draws the paper's Fig. 1 for one shape complexity K: iso-error and
iso-size contours over the (V, B) plane, with the ridge ``B(V)`` of optimal allocations.
:func:`error_map` writes a mesh whose per-vertex colours show distances (for instance
each vertex's distance to another mesh), with a colour-bar image.

matplotlib is imported inside the functions, so ``import meshbits`` never needs it.
Figures are drawn on the Agg canvas (no display, no pyplot global state). Install with
``pip install meshbits[plot]``.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import model
from .constants import DRACO_ALPHA, DRACO_CONNECTIVITY_BITS, MODEL_MIN_VERTICES
from .errors import MeshbitsError
from .files import write_atomic
from .mesh import MeshLike, as_mesh
from .results import ArrayResult

__all__ = ["ErrorMap", "colorbar", "error_map", "error_surface", "figure", "vertex_colors"]


def _matplotlib() -> Any:
    try:
        import matplotlib
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError("meshbits.plot needs matplotlib: pip install 'meshbits[plot]'") from err
    return matplotlib


def figure(size_px: tuple[int, int], dpi: int) -> Any:
    """A matplotlib Figure on its own Agg canvas, ``size_px`` = (width, height) pixels."""
    _matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    width, height = (int(n) for n in size_px)
    if width <= 0 or height <= 0 or dpi <= 0:
        raise MeshbitsError(f"size_px and dpi must be positive, got {size_px} and {dpi}")
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _range(name: str, value: Sequence[float], low: float) -> tuple[float, float]:
    try:
        lo, hi = (float(x) for x in value)
    except (TypeError, ValueError) as err:
        raise MeshbitsError(f"{name} must be a (low, high) pair of numbers, got {value!r}") from err
    if not (np.isfinite(lo) and np.isfinite(hi) and low <= lo < hi):
        raise MeshbitsError(f"{name} must satisfy {low:g} <= low < high (finite), got {value!r}")
    return lo, hi


def error_surface(
    k: float,
    *,
    grid_size: float = 1.0,
    alpha: float = DRACO_ALPHA,
    connectivity_bits: float = DRACO_CONNECTIVITY_BITS,
    vertices: Sequence[float] = (1e2, 1e6),
    bits: Sequence[float] = (2.0, 20.0),
    points: Sequence[tuple[float, float, str]] = (),
    title: str | None = None,
    path: str | Path | None = None,
    size_px: tuple[int, int] = (900, 650),
    dpi: int = 100,
    resolution: int = 240,
) -> Any:
    """The paper's Fig. 1 for shape complexity ``k``: iso-error and iso-size contours over
    (V, B), and the optimal ridge ``B(V)``.

    The error is the model's ``E(B, V) = E_Q(B) + E_T(V)`` (paper Eq. 2, 10, 7;
    :func:`meshbits.model.error`) in the length unit of ``grid_size`` (relative to S when
    ``grid_size`` is 1); the size is ``F = (3 alpha B + T) V`` bits (Eq. 1). Contour levels
    are powers of ten (and their halves for the error, when the range is narrow). The ridge
    is :func:`meshbits.model.optimal_bits` (Eq. 12): where it crosses an iso-size curve,
    that curve touches the lowest iso-error curve it can reach.

    Parameters
    ----------
    k : float
        ``K``, grid-normalised shape complexity (dimensionless, > 0).
    grid_size, alpha, connectivity_bits : float
        ``S`` (length; the default 1 draws errors as fractions of ``S``), ``alpha`` in
        (0, 1], ``T`` (bits per vertex), as in :mod:`meshbits.model` (default Draco's
        fitted 0.595 and 0, as ``compress``; the paper's are 1 and 4).
    vertices : (float, float)
        Range of ``V`` (log axis), ``4 <= low < high``.
    bits : (float, float)
        Range of ``B`` (bits per coordinate), ``0 <= low < high``.
    points : sequence of (V, B, label)
        Points to mark (for instance a mesh's own V and its planned B).
    title : str, optional
        Figure title (default: names K, alpha and T).
    path : str or Path, optional
        Save a PNG of exactly ``size_px`` pixels there.
    size_px : (int, int)
        Width and height in pixels.
    dpi : int
        Dots per inch of the saved image (fonts scale with it).
    resolution : int
        Grid points per axis of the contoured surface.

    Returns
    -------
    matplotlib.figure.Figure
    """
    k = float(k)
    if not (np.isfinite(k) and k > 0):
        raise MeshbitsError(f"k must be positive and finite, got {k}")
    v_lo, v_hi = _range("vertices", vertices, MODEL_MIN_VERTICES)
    b_lo, b_hi = _range("bits", bits, 0.0)
    resolution = int(resolution)
    if resolution < 8:
        raise MeshbitsError(f"resolution must be at least 8, got {resolution}")
    v = np.geomspace(v_lo, v_hi, resolution)
    b = np.linspace(b_lo, b_hi, resolution)
    vv, bb = np.meshgrid(v, b)
    err = np.asarray(model.error(bb, vv, k, grid_size))
    size = np.asarray(model.file_size(bb, vv, alpha=alpha, connectivity_bits=connectivity_bits))
    ridge = np.asarray(model.optimal_bits(v, k, alpha=alpha, connectivity_bits=connectivity_bits))

    fig = figure(size_px, dpi)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_xscale("log")
    filled = ax.contourf(vv, bb, np.log10(err), levels=64, cmap="viridis_r")
    grid = _Grid(v=v, b=b, vv=vv, bb=bb, v_range=(v_lo, v_hi), b_range=(b_lo, b_hi))
    _iso_error_contours(ax, grid, err, k=k, grid_size=grid_size)
    _iso_size_contours(ax, grid, size, alpha=alpha, connectivity_bits=connectivity_bits)
    inside = (ridge >= b_lo) & (ridge <= b_hi)
    ax.plot(v[inside], ridge[inside], color="red", linewidth=2.0, label="optimal B(V) (Eq. 12)")
    _mark_points(ax, points)
    colorbar_ = fig.colorbar(filled, ax=ax)
    unit = "E / S" if grid_size == 1.0 else "E (length)"
    colorbar_.set_label(f"log10 {unit}")
    ax.set_xlim(v_lo, v_hi)
    ax.set_ylim(b_lo, b_hi)
    ax.set_xlabel("V, vertices (log)")
    ax.set_ylabel("B, bits per coordinate")
    ax.set_title(
        title
        if title is not None
        else f"Error and size over (V, B): K = {k:.4g}, alpha = {alpha:g}, "
        f"T = {connectivity_bits:g} bits/vertex"
    )
    ax.legend(loc="upper left", fontsize=8)
    if path is not None:
        _save_png(fig, path, dpi)
    return fig


@dataclass(frozen=True)
class _Grid:
    """The (V, B) grid of :func:`error_surface`: the axes ``v`` (log-spaced) and ``b``,
    their mesh ``vv, bb``, and the plotted ranges."""

    v: np.ndarray
    b: np.ndarray
    vv: np.ndarray
    bb: np.ndarray
    v_range: tuple[float, float]
    b_range: tuple[float, float]


def _iso_error_contours(
    ax: Any, grid: _Grid, err: np.ndarray, *, k: float, grid_size: float
) -> None:
    """Black iso-error contours at the decades (and 3 x 10^n) inside ``err``, labelled near
    the right edge, where those curves run flat, or along the top edge where a curve turns
    below it before reaching that column."""
    v, b, vv, bb = grid.v, grid.b, grid.vv, grid.bb
    (v_lo, v_hi), (b_lo, b_hi) = grid.v_range, grid.b_range
    e_levels = _decades(err, halves=True)
    lines = ax.contour(vv, bb, err, levels=e_levels, colors="black", linewidths=0.8)
    v_error_labels = v_lo * (v_hi / v_lo) ** 0.88
    error_column = np.asarray(model.error(b, v_error_labels, k, grid_size))
    b_top_labels = b_hi - 0.06 * (b_hi - b_lo)
    error_row = np.asarray(model.error(b_top_labels, v, k, grid_size))
    error_label_at = []
    for level in lines.levels:
        b_at = float(np.interp(-np.log(level), -np.log(error_column), b))
        if b_at < b_top_labels:
            error_label_at.append((v_error_labels, b_at))
        else:  # the curve turns below the top edge left of the column: label it there
            log_v = np.interp(-np.log(level), -np.log(error_row), np.log(v))
            error_label_at.append((float(np.exp(log_v)), b_top_labels))
    error_name = "E/S" if grid_size == 1.0 else "E"
    ax.clabel(lines, fmt=lambda x: f"{error_name}={x:.0e}", fontsize=7, manual=error_label_at)


def _iso_size_contours(
    ax: Any, grid: _Grid, size: np.ndarray, *, alpha: float, connectivity_bits: float
) -> None:
    """Dashed white iso-size contours at the powers of ten inside ``size`` (bits), labelled
    low in the plot, where those curves run steep (apart from the iso-error labels)."""
    (v_lo, v_hi), (b_lo, b_hi) = grid.v_range, grid.b_range
    f_levels = _decades(size, halves=False)
    size_lines = ax.contour(
        grid.vv, grid.bb, size, levels=f_levels, colors="white", linewidths=0.9, linestyles="dashed"
    )
    b_size_labels = b_lo + 0.12 * (b_hi - b_lo)
    bits_per_vertex = float(
        model.file_size(b_size_labels, 1.0, alpha=alpha, connectivity_bits=connectivity_bits)
    )
    size_label_at = [(level / bits_per_vertex, b_size_labels) for level in size_lines.levels]
    ax.clabel(
        size_lines,
        fmt=lambda x: f"F={x:.0e} bits",
        fontsize=7,
        colors="white",
        manual=[(x, y) for x, y in size_label_at if v_lo < x < v_hi],
    )


def _mark_points(ax: Any, points: Sequence[tuple[float, float, str]]) -> None:
    """A red dot and a white label at each ``(V, B, label)``."""
    for pv, pb, label in points:
        ax.plot([pv], [pb], marker="o", color="red", markeredgecolor="white")
        ax.annotate(
            str(label),
            (pv, pb),
            textcoords="offset points",
            xytext=(6, 6),
            color="white",
            fontsize=8,
        )


def _save_png(fig: Any, path: str | Path, dpi: int) -> Path:
    """Render ``fig`` as PNG and write it atomically."""
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=dpi, format="png")
    return write_atomic(Path(path), buffer.getvalue())


def _decades(values: np.ndarray, *, halves: bool) -> list[float]:
    """Powers of ten strictly inside the range of ``values`` (with 3 x 10^n when
    ``halves`` and the range spans fewer than four decades)."""
    finite = values[np.isfinite(values) & (values > 0)]
    lo, hi = float(finite.min()), float(finite.max())
    exps = np.arange(np.floor(np.log10(lo)), np.ceil(np.log10(hi)) + 1)
    levels = [10.0**e for e in exps]
    if halves and len(exps) < 6:
        levels += [3.0 * 10.0**e for e in exps]
    return sorted(x for x in levels if lo < x < hi)


@dataclass(frozen=True, eq=False)
class ErrorMap(ArrayResult):
    """What :func:`error_map` wrote.

    Attributes
    ----------
    path : Path
        The coloured PLY.
    colorbar_path : Path or None
        The colour-bar PNG.
    colors : ndarray, shape (n, 4), uint8
        Per-vertex RGBA written to the PLY.
    vmin, vmax : float
        Distances (length) mapped to the two ends of the colour map.
    """

    path: Path
    colorbar_path: Path | None
    colors: np.ndarray
    vmin: float
    vmax: float

    _arrays = ("colors",)


def vertex_colors(
    distances: Any, *, cmap: str = "viridis", vmin: float = 0.0, vmax: float | None = None
) -> tuple[np.ndarray, float, float]:
    """RGBA ``uint8`` colours of ``cmap`` applied to ``(d - vmin) / (vmax - vmin)`` clipped to
    [0, 1]; ``vmax`` defaults to the largest distance (1 above ``vmin`` when all are equal).

    Returns ``(colors (n, 4) uint8, vmin, vmax)``.
    """
    matplotlib = _matplotlib()
    d = np.asarray(distances, dtype=np.float64)
    if d.ndim != 1:
        raise MeshbitsError(f"distances must be one-dimensional, got shape {d.shape}")
    if not np.all(np.isfinite(d)):
        raise MeshbitsError("distances contain NaN or infinite values")
    vmin = float(vmin)
    if vmax is None:
        vmax = float(d.max()) if len(d) else vmin
    vmax = float(vmax)
    if not np.isfinite(vmin) or not np.isfinite(vmax):
        raise MeshbitsError(f"vmin and vmax must be finite, got {vmin} and {vmax}")
    if vmax < vmin:
        raise MeshbitsError(f"vmax ({vmax}) must not be below vmin ({vmin})")
    if vmax == vmin:  # all distances equal: show them with the bottom colour
        vmax = vmin + 1.0
    try:
        colormap = matplotlib.colormaps[cmap]
    except KeyError as err:
        raise MeshbitsError(f"unknown colour map {cmap!r}") from err
    unit = np.clip((d - vmin) / (vmax - vmin), 0.0, 1.0)
    rgba = colormap(unit)
    return np.rint(np.asarray(rgba) * 255.0).astype(np.uint8), vmin, vmax


def colorbar(
    path: str | Path,
    *,
    cmap: str = "viridis",
    vmin: float = 0.0,
    vmax: float = 1.0,
    label: str = "distance",
    size_px: tuple[int, int] = (160, 600),
    dpi: int = 100,
) -> Path:
    """Write a vertical colour-bar PNG of exactly ``size_px`` pixels for ``cmap`` over
    ``[vmin, vmax]``; returns the path."""
    _matplotlib()
    from matplotlib import colors
    from matplotlib.colorbar import ColorbarBase

    fig = figure(size_px, dpi)
    ax = fig.add_axes((0.15, 0.05, 0.25, 0.9))
    bar = ColorbarBase(
        ax, cmap=cmap, norm=colors.Normalize(vmin=vmin, vmax=vmax), orientation="vertical"
    )
    bar.set_label(label)
    return _save_png(fig, path, dpi)


def error_map(
    mesh: MeshLike,
    distances: Any,
    path: str | Path,
    *,
    colorbar_path: str | Path | None = None,
    cmap: str = "viridis",
    vmax: float | None = None,
    label: str = "distance",
) -> ErrorMap:
    """Write ``mesh`` as a PLY whose per-vertex colours show ``distances``.

    Vertex ``i`` gets ``cmap(clip(distances[i] / vmax, 0, 1))`` as RGBA bytes (PLY
    properties ``red green blue alpha``; MeshLab and most viewers show them). Vertex order
    and faces are kept as given.

    Parameters
    ----------
    mesh
        A ``trimesh.Trimesh`` or ``(vertices, faces)`` pair.
    distances : array_like, shape (n_vertices,)
        Non-negative per-vertex values (length), for instance
        ``meshbits.ClosestPoints(other).query(vertices).distances``.
    path : str or Path
        The PLY to write.
    colorbar_path : str or Path, optional
        Also write a colour-bar PNG there.
    cmap : str
        A matplotlib colour map name.
    vmax : float, optional
        Distance shown with the top colour (default: the largest distance of a vertex
        some face uses).
    label : str
        Colour-bar label.

    Returns
    -------
    ErrorMap
    """
    import trimesh

    vertices, faces = as_mesh(mesh)
    d = np.asarray(distances, dtype=np.float64)
    if d.shape != (len(vertices),):
        raise MeshbitsError(
            f"distances must have one value per vertex ({len(vertices)}), got shape {d.shape}"
        )
    if np.any(d < 0):
        raise MeshbitsError("distances must be non-negative")
    if vmax is None:  # the surface's largest: an unreferenced vertex is not on it
        vmax = float(d[np.unique(faces)].max())
    colors, vmin, vmax_used = vertex_colors(d, cmap=cmap, vmin=0.0, vmax=vmax)
    out = trimesh.Trimesh(vertices, faces, vertex_colors=colors, process=False)
    path = write_atomic(Path(path), out.export(file_type="ply"))
    bar = None
    if colorbar_path is not None:
        bar = colorbar(colorbar_path, cmap=cmap, vmin=vmin, vmax=vmax_used, label=label)
    return ErrorMap(path, bar, colors, vmin, vmax_used)
