"""
Restarting a run from its checkpoint
====================================

A run writes a checkpoint every ``output.checkpoint_every_s`` seconds of simulated time
(``checkpoint.npz`` in its output folder). A later run of the same configuration with a later
``time.t_end`` restarts from it and continues bit for bit as the uninterrupted run would. This
example runs the paper's fluidised column at ny = 16 to 0.2 s, restarts it to 0.3 s, and compares
the front with the same run made in one go. On the command line the same is
``granrs run FILE.toml --restart DIR/checkpoint.npz`` (docs/howto/restart.md).
"""

# %%
# The first part, with a checkpoint
# ---------------------------------
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from granrs.config import load_config
from granrs.runner import run_config

work = Path(tempfile.mkdtemp())
# the run file of the paper's fluidised case, found from the repository or its examples/gallery
run_file = next(
    d / "examples" / "paper_fluidised.toml"
    for d in (Path.cwd(), *Path.cwd().parents)
    if (d / "examples" / "paper_fluidised.toml").exists()
)
common = ["grid.ny=16", "output.animation=false", "output.formats=[]"]


def config(t_end, out, *more):
    return load_config(run_file, [*common, f"time.t_end={t_end}", f'output.dir="{out}"', *more])


first = run_config(config(0.2, work / "first", "output.checkpoint_every_s=0.1"), progress=False)
print(first["stop_reason"], first["steps"], sorted(p.name for p in (work / "first").iterdir()))

# %%
# The restart, and the same run in one go
# ---------------------------------------
# The restart writes its outputs into a new folder; its records start at the checkpoint's time.
restarted = run_config(config(0.3, work / "restarted"), restart=str(work / "first" / "checkpoint.npz"), progress=False)
whole = run_config(config(0.3, work / "whole"), progress=False)
print("run-out at 0.3 s, restarted:", restarted["runout_m"], " in one go:", whole["runout_m"])
assert restarted["runout_m"] == whole["runout_m"]

# %%
# The fronts of the three runs
# ----------------------------
fig, ax = plt.subplots(figsize=(6, 3.5), layout="constrained")
for name, style in (("whole", "-"), ("first", "--"), ("restarted", "o")):
    front = np.genfromtxt(work / name / "front.csv", delimiter=",", names=True)
    ax.plot(front["t_s"], front["front_m"], style, lw=2, ms=3, label=name)
ax.set_xlabel("t (s)")
ax.set_ylabel("front from the gate (m)")
ax.legend()
plt.show()
