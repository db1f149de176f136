"""The README's Python examples run as written."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_blocks_run():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "README has no Python example"
    for block in blocks:
        exec(compile(block, str(README), "exec"), {})


def test_readme_names_the_two_commands_ci_runs():
    text = README.read_text()
    ci = (README.parent / ".ci" / "run").read_text()
    for command in ("pip install . && meshbits demo", 'pip install ".[test]" && python -m pytest'):
        assert command in text and command in ci


def test_readme_plan_example_predicts_what_compress_writes(tmp_path):
    """The README's `meshbits plan` and `meshbits compress` lines print what their comments
    say (both deterministic: the compress samples are seeded)."""
    import json
    import subprocess
    import sys

    text = README.read_text()
    plan_line = re.search(
        r"meshbits plan (\S+) --size (\S+) +# plan: B = (\d+), V = ([\d,]+)", text
    )
    done_line = re.search(
        r"meshbits compress \S+ --size \S+ -o \S+ *# wrote: B = (\d+), V = ([\d,]+), ([\d,]+) B",
        text,
    )
    assert plan_line and done_line, "README lost its plan/compress example"
    mesh = README.parent / plan_line.group(1)

    def run(*argv: str) -> dict:
        done = subprocess.run(
            [sys.executable, "-m", "meshbits.cli", *argv, "--json"],
            capture_output=True,
            text=True,
            check=False,
        )
        assert done.returncode == 0, done.stderr
        return json.loads(done.stdout)

    plan = run("plan", str(mesh), "--size", plan_line.group(2))
    assert plan["whole_bits"] == int(plan_line.group(3))
    assert round(plan["whole_vertices"]) == int(plan_line.group(4).replace(",", ""))
    result = run("compress", str(mesh), "--size", plan_line.group(2), "-o", str(tmp_path / "b.drc"))
    assert result["bits"] == int(done_line.group(1))
    assert result["vertices"] == int(done_line.group(2).replace(",", ""))
    assert result["size_bytes"] == int(done_line.group(3).replace(",", ""))
    assert (tmp_path / "b.drc").stat().st_size == result["size_bytes"]
