"""The column's output files: summary.json, front.csv, profiles.csv and energy.csv, each written
atomically (``granrs.io.outputs``), and the files rewritten during the run."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ...io.outputs import RunOutputs
from .summaries import ENERGY_COLUMNS, INCOMPLETE, _energy_row


def write_energy(out: Path, times: list, budgets: list) -> None:
    """energy.csv: the energy budget at the recorded times (J per metre of width)."""
    with open(out / "energy.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s"] + [c + "_J_m" for c in ENERGY_COLUMNS])
        for t, b in zip(times, budgets):
            row = _energy_row(b)
            w.writerow([f"{t:.6g}"] + [f"{row[c]:.6g}" for c in ENERGY_COLUMNS])


#: front.csv's name of a per-record series (with its unit); any other series of numbers the
#: records hold is written under its own name
FRONT_NAMES = {"t": "t_s", "front": "front_m", "area": "area_m2", "max_granular_speed": "max_granular_speed_m_s"}


def front_columns(rec: dict) -> dict:
    """front.csv's columns from the per-record series: every series of numbers in ``rec``."""
    cols = {FRONT_NAMES[k]: rec[k] for k in FRONT_NAMES if k in rec}
    n = len(rec.get("t", ()))
    for k, v in rec.items():
        if k not in FRONT_NAMES and len(v) == n and all(isinstance(x, (int, float)) for x in v):
            cols[k] = v
    return cols


def write_outputs(out: Path, summary: dict, rec: dict, profiles: dict, xs: np.ndarray, outputs=None) -> None:
    """summary.json, front.csv (t, front from the gate, area, largest speed; with pore pressure
    also the basal pore-pressure ratios under the reservoir and in the channel) and profiles.csv
    (surface height at the recorded times against x − L_c): the same files for every model. Each
    file is written atomically (``granrs.io.outputs``); ``outputs``: the run's ``RunOutputs``
    (a restart's earlier rows)."""
    outputs = outputs if outputs is not None else RunOutputs(out)
    outputs.write_json("summary.json", summary)
    outputs.write_columns("front.csv", front_columns(rec))
    keys = list(profiles)
    cols = {"x_from_gate_m": xs} | {
        (("h_final" if k == "final" else k) if isinstance(k, str) else f"h_{k}"): profiles[k] for k in keys
    }
    outputs.write_columns("profiles.csv", cols)


def _progress(outputs, summary: dict, rec: dict, hist: dict, t: float, steps: int) -> None:
    """The outputs written during the run: front.csv and history.npz so far, and a summary whose
    ``stop_reason`` says the run had not finished when it was written. The summary is written
    first: a run killed between the writes keeps a summary for every record front.csv holds."""
    outputs.write_json(
        "summary.json",
        summary
        | {
            "stop_reason": f"{INCOMPLETE}: written during the run at t = {t:.6g} s (step {steps}); a run that ends writes "
            "its final stop_reason here, so this one was killed or its disk filled"
        },
    )
    outputs.write_columns("front.csv", front_columns(rec))
    outputs.write_history(hist)
