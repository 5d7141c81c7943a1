"""The README's Python quick start runs as written: its one ```python block is extracted and
executed in a temporary directory (ny = 16, 0.3 s of simulated time: a few seconds)."""

from __future__ import annotations

import os
import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_readme_has_one_python_block_and_it_runs(tmp_path, monkeypatch):
    blocks = python_blocks(README.read_text())
    assert len(blocks) == 1
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict = {}
    exec(compile(blocks[0], str(README), "exec"), namespace)
    # the block's own outputs: a front that has left the gate and moves forward, and the plot
    times, fronts, model = namespace["times"], namespace["fronts"], namespace["model"]
    assert abs(model.time - 0.3) < 1e-9 and len(times) == len(fronts) >= 30
    # at 0.3 s the fluidised front lies between the fronts of the paper's grid (ny = 256) at 0.2 s
    # and 0.4 s, 0.302 and 0.768 m (docs/validation.md, "The channel's side walls"; ny = 16
    # measures 0.516 m); it never moves back by more than one cell while the column collapses
    assert 0.302 < fronts[-1] < 0.768, fronts[-1]
    h = model.grid.dx
    assert all(b >= a - h for a, b in zip(fronts, fronts[1:]))
    assert (tmp_path / "front.png").stat().st_size > 1000
    assert os.environ["MPLBACKEND"] == "Agg"
