"""``meshbits batch`` and :func:`meshbits.batch`: inputs, mirrored outputs, the report,
resuming, failures that never stop the batch, exit codes, Dask, and Ctrl-C."""

from __future__ import annotations

import csv
import importlib
import json
import multiprocessing
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from independent import read_gltf, read_output

import meshbits
from meshbits.batch.inputs import output_names
from meshbits.batch.report import ReportFile
from meshbits.batch.task import available_cores
from meshbits.cli import main

DATA = Path(__file__).parent / "data"
batch_module = importlib.import_module("meshbits.batch")

#: A loose relative error budget: quick to meet on the tiny meshes below.
LOOSE = ["--error", "0.01", "--relative"]


@pytest.fixture
def library(tmp_path: Path) -> Path:
    """A library: two tiny meshes (one in a sub-folder), three unusable files (a corrupt
    PLY, an empty PLY, an OBJ without triangles) and a text file."""
    root = tmp_path / "library"
    (root / "animals").mkdir(parents=True)
    shutil.copy(DATA / "bunny_res4.ply", root / "animals" / "bunny.ply")
    shutil.copy(DATA / "suzanne.ply", root / "suzanne.ply")
    (root / "animals" / "broken.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\n")
    (root / "empty.ply").write_bytes(b"")
    (root / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")  # no faces
    (root / "notes.txt").write_text("not a mesh\n")
    return root


def good_library(tmp_path: Path) -> Path:
    root = tmp_path / "good"
    (root / "sub").mkdir(parents=True)
    shutil.copy(DATA / "bunny_res4.ply", root / "sub" / "bunny.ply")
    shutil.copy(DATA / "suzanne.ply", root / "suzanne.ply")
    return root


def report_rows(out: Path) -> list[dict]:
    lines = (out / batch_module.REPORT_NAME).read_text().splitlines()
    return [json.loads(line) for line in lines if line.strip()]


def summary(out: Path) -> dict[str, str]:
    with open(out / batch_module.SUMMARY_NAME, newline="") as handle:
        return {row["metric"]: row["value"] for row in csv.DictReader(handle)}


def point_to_surface(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Distance from each point to the nearest triangle, by brute force in numpy (the
    plane projection when it falls inside the triangle, else the nearest clamped edge
    projection): an independent reference for the error of an output's vertices."""

    def segment_d2(p, x, y):
        d = y - x
        t = (((p - x) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-300)).clip(0, 1)
        return ((p - (x + t[..., None] * d)) ** 2).sum(-1)

    p = np.asarray(points, dtype=float)[:, None, :]
    v = np.asarray(vertices, dtype=float)
    a, b, c = (v[np.asarray(faces)[:, k]][None] for k in range(3))
    best = np.minimum(np.minimum(segment_d2(p, a, b), segment_d2(p, b, c)), segment_d2(p, c, a))
    n = np.cross(b - a, c - a)
    nn = np.maximum((n * n).sum(-1), 1e-300)
    h = ((p - a) * n).sum(-1) / nn
    q = p - h[..., None] * n
    inside = (n * n).sum(-1) > 0
    for x, y in ((a, b), (b, c), (c, a)):
        inside = inside & ((np.cross(y - x, q - x) * n).sum(-1) >= 0)
    return np.sqrt(np.where(inside, np.minimum(best, h * h * nn), best).min(axis=1))


def decode_output(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """An output's vertices and faces in world coordinates, read without meshbits
    (DracoPy; pygltflib and DracoPy for a Draco ``.glb``, its node transforms composed in
    float64)."""
    if path.suffix == ".glb":
        doc, _ = read_gltf(path)
        assert doc["extensionsRequired"] == ["KHR_draco_mesh_compression"]
    return read_output(path)


def run_cli_json(capsys, *argv: str) -> tuple[int, dict]:
    code = main(["batch", *argv, "--json"])
    return code, json.loads(capsys.readouterr().out)


# --- inputs and outputs ------------------------------------------------------------------


def test_folder_mirrors_subfolders_and_records_the_corrupt_file(library, tmp_path, capsys):
    out = tmp_path / "out"
    code, payload = run_cli_json(capsys, str(library), "-o", str(out), *LOOSE, "--workers", "1")
    assert code == 2  # some inputs were unusable; the others were still compressed
    assert (out / "animals" / "bunny.drc").is_file()
    assert (out / "suzanne.drc").is_file()
    assert sorted(p.name for p in out.rglob("*.drc")) == ["bunny.drc", "suzanne.drc"]
    assert payload["exit_code"] == 2
    assert (payload["inputs"], payload["met"], payload["unusable"]) == (5, 2, 3)
    assert payload["ignored"] == {".txt": 1}  # counted, never silently dropped
    rows = {r["relative"]: r for r in report_rows(out)}
    assert set(rows) == {
        "animals/bunny.ply",
        "animals/broken.ply",
        "empty.ply",
        "points.obj",
        "suzanne.ply",
    }
    for name, words in (
        ("animals/broken.ply", "broken.ply"),
        ("empty.ply", "empty"),
        ("points.obj", "triangle"),
    ):
        row = rows[name]
        assert row["status"] == "unusable" and row["output"] is None and not row["met"]
        assert words in row["message"] and "\n" not in row["message"], row["message"]
    broken = rows["animals/broken.ply"]
    bunny = rows["animals/bunny.ply"]
    assert bunny["status"] == "met" and bunny["met"] is True and bunny["message"] is None
    assert bunny["output"] == "animals/bunny.drc"
    assert bunny["output_bytes"] == (out / "animals" / "bunny.drc").stat().st_size
    assert bunny["input_bytes"] == (DATA / "bunny_res4.ply").stat().st_size
    assert 0 < bunny["error"] <= bunny["error_upper"] <= bunny["budget"]
    assert bunny["bits"] >= 1 and bunny["vertices"] > 0
    assert len(bunny["input_sha256"]) == 64
    assert bunny["options"]["error"] == 0.01 and bunny["options"]["relative"] is True
    assert bunny["peak_rss_bytes"] >= bunny["rss_before_bytes"] > 0
    assert bunny["seconds"] > 0 and bunny["cpu_seconds"] > 0
    assert set(bunny) == set(broken)  # every row has every key
    totals = summary(out)
    assert (totals["inputs"], totals["met"], totals["unusable"]) == ("5", "2", "3")
    assert totals["ignored_files"] == "1" and totals["exit_code"] == "2"
    assert int(totals["saved_bytes"]) == sum(
        r["input_bytes"] - r["output_bytes"] for r in rows.values() if r["output"]
    )
    assert (out / batch_module.PLOT_NAME).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("fmt", ["drc", "glb"])
def test_outputs_read_back_independently_within_the_budget(tmp_path, fmt):
    root = good_library(tmp_path)
    out = tmp_path / "out"
    result = meshbits.batch(root, out, error=0.005, relative=True, format=fmt, workers=1)
    assert result.exit_code == 0 and len(result.rows) == 2
    for row in result.rows:
        vertices, faces = decode_output(out / row.output)
        # V counts positions once: Draco splits some vertices into copies.
        assert (len(np.unique(vertices, axis=0)), len(faces)) == (row.vertices, row.faces)
        assert len(faces) > 0
        source_v, source_f = meshbits.load_mesh(row.path)
        size = float(np.ptp(source_v, axis=0).max())
        assert row.budget == pytest.approx(0.005 * size, rel=1e-6)
        # Every output vertex lies on the output surface, so its distance to the input is
        # a lower bound of the Hausdorff distance: never above the measured error.
        far = point_to_surface(vertices, source_v, source_f).max()
        assert far <= row.error * (1 + 1e-6) + 1e-12 * size
        assert far > 0  # quantized: the vertices did move
        assert row.error_upper is not None
        assert far <= row.error_upper * (1 + 1e-6) + 1e-12 * size
        assert row.error <= row.error_upper <= row.budget


def test_glob_input_relative_to_its_folder(tmp_path):
    root = good_library(tmp_path)
    out = tmp_path / "out"
    result = meshbits.batch(str(root / "**" / "*.ply"), out, error=0.01, relative=True, workers=1)
    assert result.exit_code == 0 and result.met == 2
    assert sorted(r.output for r in result.rows) == ["sub/bunny.drc", "suzanne.drc"]
    only = meshbits.batch(str(root / "*.ply"), tmp_path / "top", error=0.01, relative=True)
    assert [r.relative for r in only.rows] == ["suzanne.ply"]


@pytest.mark.parametrize("kind", ["csv", "jsonl"])
def test_manifest_paths_are_relative_to_it(tmp_path, kind):
    root = good_library(tmp_path)
    entries = ["sub/bunny.ply", "suzanne.ply", "", "sub/bunny.ply", "missing.ply"]
    if kind == "csv":
        manifest = root / "list.csv"
        manifest.write_text("id,path\n" + "".join(f"{i},{e}\n" for i, e in enumerate(entries)))
    else:
        manifest = root / "list.jsonl"
        manifest.write_text("".join(json.dumps({"path": e or None}) + "\n" for e in entries))
    out = tmp_path / "out"
    result = meshbits.batch(manifest, out, error=0.01, relative=True, workers=1)
    assert (result.inputs, result.duplicates, result.blank_manifest_rows) == (3, 1, 1)
    assert [r.relative for r in result.rows] == ["sub/bunny.ply", "suzanne.ply", "missing.ply"]
    missing = result.rows[2]
    assert missing.status == "unusable" and "no such file" in missing.message
    assert (out / "sub" / "bunny.drc").is_file()
    assert result.exit_code == 2


def test_manifest_without_a_path_column_is_refused(tmp_path, capsys):
    manifest = tmp_path / "m.csv"
    manifest.write_text("file\nx.ply\n")
    assert main(["batch", str(manifest), "-o", str(tmp_path / "out"), *LOOSE]) == 2
    assert "no 'path' column" in capsys.readouterr().err


def test_output_names_never_collide(tmp_path):
    root = tmp_path / "lib"
    root.mkdir()
    for name in ("a.ply", "a.obj", "b.ply.gz"):
        (root / name).write_bytes(b"")
    inputs = batch_module.find_inputs(root)
    names = dict(output_names(inputs, tmp_path / "out", "drc"))
    assert names == {"a.obj": "a.obj.drc", "a.ply": "a.ply.drc", "b.ply.gz": "b.drc"}


def test_the_output_folder_inside_the_input_is_not_searched(tmp_path):
    root = good_library(tmp_path)
    first = meshbits.batch(root, root / "out", error=0.01, relative=True, format="glb", workers=1)
    assert first.inputs == 2
    again = meshbits.batch(root, root / "out", error=0.01, relative=True, format="glb", workers=1)
    assert (again.inputs, again.resumed) == (2, 2)  # out/*.glb are not inputs


def test_scene_outputs_go_through_compress_scene(tmp_path):
    root = good_library(tmp_path)
    result = meshbits.batch(
        root, tmp_path / "out", error=0.01, relative=True, format="gltf", codec="meshopt"
    )
    assert result.exit_code == 0
    assert (tmp_path / "out" / "suzanne.gltf").is_file()
    assert (tmp_path / "out" / "suzanne.bin").is_file()
    row = next(r for r in result.rows if r.relative == "suzanne.ply")
    assert row.options["codec"] == "meshopt" and row.bits is not None


# --- resuming ----------------------------------------------------------------------------


def test_rerun_skips_what_is_done_and_force_redoes_it(tmp_path):
    root = good_library(tmp_path)
    out = tmp_path / "out"
    options = {"error": 0.01, "relative": True, "workers": 1}
    first = meshbits.batch(root, out, **options)
    assert (first.ran, first.resumed) == (2, 0)
    outputs = sorted(out.rglob("*.drc"))
    assert len(outputs) == 2
    written = {p: p.stat().st_mtime_ns for p in outputs}
    second = meshbits.batch(root, out, **options)
    assert (second.ran, second.resumed) == (0, 2)
    assert {p: p.stat().st_mtime_ns for p in outputs} == written  # not rewritten
    assert [r.finished for r in second.rows] == [r.finished for r in first.rows]
    assert second.backend == "none" and second.exit_code == 0
    assert all(r.resumed for r in second.rows)
    assert [r.output_bytes for r in second.rows] == [r.output_bytes for r in first.rows]
    assert len(report_rows(out)) == 2  # one row per input, not one per run

    # Changed bytes, a deleted output, other options: redone.
    shutil.copy(DATA / "bunny_res4.ply", root / "suzanne.ply")
    (out / "sub" / "bunny.drc").unlink()
    third = meshbits.batch(root, out, **options)
    assert (third.ran, third.resumed) == (2, 0)
    other = meshbits.batch(root, out, **{**options, "seed": 1})
    assert (other.ran, other.resumed) == (2, 0)

    before = {p: p.stat().st_mtime_ns for p in outputs}
    forced = meshbits.batch(root, out, **{**options, "seed": 1}, force=True)
    assert (forced.ran, forced.resumed) == (2, 0)
    assert all(p.stat().st_mtime_ns != before[p] for p in outputs)  # rewritten
    assert len(report_rows(out)) == 2
    again = meshbits.batch(root, out, **{**options, "seed": 1})
    assert (again.ran, again.resumed) == (0, 2)


def test_rows_of_other_inputs_and_cut_lines_are_kept_or_counted(tmp_path):
    root = good_library(tmp_path)
    out = tmp_path / "out"
    meshbits.batch(root / "sub", out, error=0.01, relative=True, workers=1)
    with open(out / batch_module.REPORT_NAME, "a") as handle:
        handle.write('{"path": "/x", "relat')  # a line cut by a crash
    result = meshbits.batch(root / "suzanne.ply", out, error=0.01, relative=True)
    assert (result.earlier_rows, result.unreadable_report_lines) == (1, 1)
    assert {r["relative"] for r in report_rows(out)} == {"bunny.ply", "suzanne.ply"}


def test_unusable_inputs_are_tried_again(tmp_path, library):
    out = tmp_path / "out"
    meshbits.batch(library, out, error=0.01, relative=True, workers=1)
    again = meshbits.batch(library, out, error=0.01, relative=True, workers=1)
    assert (again.resumed, again.ran, again.unusable) == (2, 3, 3)


# --- exit codes and failures -------------------------------------------------------------


def test_unmet_budget_exit_1(tmp_path, capsys):
    root = good_library(tmp_path)
    code = main(["batch", str(root), "-o", str(tmp_path / "out"), "--size", "20B", "--quiet"])
    text = capsys.readouterr().out
    assert code == 1
    assert "unmet: suzanne.ply: could not meet" in text
    rows = report_rows(tmp_path / "out")
    assert {r["status"] for r in rows} == {"unmet"}
    assert all(r["output"] and r["budget"] == 20 for r in rows)  # the closest is written


def test_an_internal_error_is_recorded_and_the_batch_goes_on(tmp_path, monkeypatch, capsys):
    # The task calls the compress its module imported: the bug goes there.
    compress_module = importlib.import_module("meshbits.batch.task")
    real = compress_module.compress

    def buggy(mesh, **kwargs):
        if len(mesh[1]) == len(meshbits.load_mesh(DATA / "suzanne.ply")[1]):
            raise ZeroDivisionError("a bug")
        return real(mesh, **kwargs)

    monkeypatch.setattr(compress_module, "compress", buggy)
    root = good_library(tmp_path)
    code, payload = run_cli_json(
        capsys, str(root), "-o", str(tmp_path / "out"), *LOOSE, "--workers", "1"
    )
    assert code == 3
    rows = {r["relative"]: r for r in payload["rows"]}
    assert rows["sub/bunny.ply"]["status"] == "met"
    bug = rows["suzanne.ply"]
    assert bug["status"] == "internal_error"
    assert bug["message"] == "internal error: ZeroDivisionError: a bug"
    assert "ZeroDivisionError" in bug["traceback"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--size", "10KB", "--relative"], "--relative applies to --error only"),
        (["--error", "0.01", "--workers", "2", "--dask", "local:1"], "not both"),
        (["--error", "0.01", "--dask", "local:x"], "local:N"),
        (["--error", "0.01", "--codec", "meshopt"], "glb and gltf"),
    ],
)
def test_bad_arguments_exit_2(tmp_path, capsys, argv, message):
    root = good_library(tmp_path)
    assert main(["batch", str(root), "-o", str(tmp_path / "out"), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_no_inputs_exit_2(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "a.txt").write_text("x")
    assert main(["batch", str(tmp_path / "empty"), "-o", str(tmp_path / "out"), *LOOSE]) == 2
    assert "no mesh files" in capsys.readouterr().err
    assert main(["batch", str(tmp_path / "nothing*.ply"), "-o", str(tmp_path / "o2"), *LOOSE]) == 2
    assert main(["batch", str(tmp_path / "empty"), "-o", str(tmp_path / "x" / "y"), *LOOSE]) == 2


# --- the Python API and the JSON ---------------------------------------------------------


def test_python_api_returns_frozen_results(tmp_path):
    root = good_library(tmp_path)
    result = meshbits.batch(root, tmp_path / "out", size="4KB", workers=1, seed=3)
    assert isinstance(result, meshbits.BatchResult)
    assert all(isinstance(r, meshbits.BatchRow) for r in result.rows)
    with pytest.raises(AttributeError):
        result.met = 0  # type: ignore[misc]
    assert result.options["size_bits"] == 32_000 and result.options["seed"] == 3
    assert result.rows[0].constraint == "size" and result.rows[0].budget == 4000
    data = json.loads(json.dumps(result.to_dict(), allow_nan=False))
    assert data["exit_code"] == result.exit_code and len(data["rows"]) == 2
    assert meshbits.BatchRow.from_dict(data["rows"][0]) == result.rows[0]
    with pytest.raises(meshbits.MeshbitsError, match="exactly one"):
        meshbits.batch(root, tmp_path / "out", error=0.1, size="4KB")
    with pytest.raises(meshbits.MeshbitsError, match="workers"):
        meshbits.batch(root, tmp_path / "out", error=0.1, workers=0)


def test_the_process_pool_gives_the_serial_results(tmp_path):
    root = good_library(tmp_path)
    serial = meshbits.batch(root, tmp_path / "serial", error=0.01, relative=True, workers=1)
    pooled = meshbits.batch(root, tmp_path / "pool", error=0.01, relative=True, workers=2)
    assert (serial.backend, pooled.backend) == ("serial", "processes")
    assert (pooled.workers, pooled.kernel_threads) == (2, max(1, available_cores() // 2))
    for a, b in zip(serial.rows, pooled.rows, strict=True):
        assert (a.bits, a.vertices, a.output_bytes, a.error) == (
            b.bits,
            b.vertices,
            b.output_bytes,
            b.error,
        )
    assert len({r.worker for r in pooled.rows}) >= 1
    assert not multiprocessing.active_children()


def test_progress_bar_shows_eta_and_bytes_saved(tmp_path, capsys):
    root = good_library(tmp_path)
    meshbits.batch(root, tmp_path / "out", error=0.01, relative=True, workers=1, progress=True)
    err = capsys.readouterr().err
    assert "meshbits batch" in err and "2/2" in err
    assert "<" in err  # tqdm's [elapsed<remaining]
    assert "saved" in err and "kB" in err


# distributed's HTTP server start retries a port with a socket it leaves to the garbage
# collector (a ResourceWarning, seen once under load): with warnings as errors the
# cluster then fails to start. The warning is distributed's, not a meshbits leak.
@pytest.mark.filterwarnings("ignore::ResourceWarning")
def test_dask_local_cluster(tmp_path, capsys):
    # CI installs ".[test]", which pulls dask[distributed]: this runs there.
    pytest.importorskip("distributed")
    root = good_library(tmp_path)
    (root / "bad.obj").write_text("v 0 0 0\n")  # no triangles
    code, payload = run_cli_json(
        capsys, str(root), "-o", str(tmp_path / "out"), *LOOSE, "--dask", "local:2"
    )
    assert code == 2
    assert payload["backend"] == "dask" and payload["workers"] == 2
    statuses = {r["relative"]: r["status"] for r in payload["rows"]}
    assert statuses == {"bad.obj": "unusable", "sub/bunny.ply": "met", "suzanne.ply": "met"}
    assert (tmp_path / "out" / "sub" / "bunny.drc").is_file()
    assert len(report_rows(tmp_path / "out")) == 3
    # The tasks ran in the cluster's worker processes, which are gone.
    assert all(not r["worker"].startswith(f"{os.getpid()}@") for r in payload["rows"])
    assert not multiprocessing.active_children()
    # Its outputs are the local pool's (the same seed, the same options).
    local = meshbits.batch(root, tmp_path / "local", error=0.01, relative=True, workers=1)
    dask_rows = {r["relative"]: r for r in payload["rows"]}
    for row in local.rows:
        assert (row.bits, row.vertices, row.output_bytes) == (
            dask_rows[row.relative]["bits"],
            dask_rows[row.relative]["vertices"],
            dask_rows[row.relative]["output_bytes"],
        )


# --- Ctrl-C ------------------------------------------------------------------------------


@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_keeps_the_report_of_what_finished(tmp_path, monkeypatch, capsys, workers):
    root = good_library(tmp_path)
    shutil.copy(DATA / "bunny_res4.ply", root / "sub" / "bunny2.ply")
    real = ReportFile.append

    def interrupted_after_one(self, row):
        real(self, row)
        raise KeyboardInterrupt

    monkeypatch.setattr(ReportFile, "append", interrupted_after_one)
    out = tmp_path / "out"
    code = main(["batch", str(root), "-o", str(out), *LOOSE, "--workers", str(workers)])
    captured = capsys.readouterr()
    assert code == 130
    assert "interrupted" in captured.err and "2 not reached" in captured.out
    assert len(report_rows(out)) == 1
    totals = summary(out)
    assert (totals["interrupted"], totals["ran"], totals["not_reached"]) == (
        "True",
        "1",
        "2",
    )
    assert not multiprocessing.active_children()  # the pool's workers are stopped
    with pytest.raises(meshbits.BatchInterrupted) as stop:
        meshbits.batch(root, out, error=0.01, relative=True, workers=workers)
    assert stop.value.result.interrupted and stop.value.result.resumed == 1


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_sigint_stops_the_program_with_exit_130(tmp_path):
    """Ctrl-C at a terminal: SIGINT to the whole process group (the workers too)."""
    import signal
    import subprocess
    import time

    root = good_library(tmp_path)
    for i in range(6):
        shutil.copy(DATA / "suzanne.ply", root / f"copy{i}.ply")
    out = tmp_path / "out"
    command = [sys.executable, "-m", "meshbits.cli", "batch", str(root), "-o", str(out)]
    process = subprocess.Popen(
        [*command, *LOOSE, "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    report = out / batch_module.REPORT_NAME
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and process.poll() is None:
        if report.is_file() and report.read_text().count("\n") >= 1:
            break
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    if process.returncode == 0:  # pragma: no cover - a very fast machine finished first
        pytest.skip("the batch finished before the signal")
    assert process.returncode == 130, stderr.decode()
    assert b"interrupted" in stderr and b"Traceback" not in stderr
    rows = report_rows(out)
    assert 1 <= len(rows) < 8
    totals = summary(out)
    assert totals["interrupted"] == "True"
    assert int(totals["ran"]) == len(rows)
    assert int(totals["ran"]) + int(totals["not_reached"]) == 8
    # The rerun keeps what finished and does the rest.
    rerun = meshbits.batch(root, out, error=0.01, relative=True, workers=1)
    assert (rerun.resumed, rerun.ran, rerun.exit_code) == (len(rows), 8 - len(rows), 0)
