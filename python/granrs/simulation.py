"""The simulation owns the time loop: stop conditions, callbacks, diagnostics history."""

from __future__ import annotations

import math
import sys
import time as _time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ._granrs import ParameterError
from .model import Model


@dataclass
class Callback:
    """Calls ``func(simulation)`` every ``every_time`` seconds of simulated time (landing on those
    times exactly) or every ``every_steps`` steps."""

    func: Callable[["Simulation"], None]
    every_time: Optional[float] = None
    every_steps: Optional[int] = None

    def __post_init__(self):
        if (self.every_time is None) == (self.every_steps is None):
            raise ParameterError("invalid parameter `Callback`: give exactly one of every_time, every_steps")
        if self.every_time is not None and not (math.isfinite(self.every_time) and self.every_time > 0):
            raise ParameterError(f"invalid parameter `every_time` = {self.every_time!r}: allowed a finite number > 0")
        if self.every_steps is not None and not (isinstance(self.every_steps, int) and self.every_steps >= 1):
            raise ParameterError(f"invalid parameter `every_steps` = {self.every_steps!r}: allowed an integer >= 1")


class Simulation:
    """Runs a model to ``stop_time`` and/or ``stop_iteration``, or until a callback sets
    ``simulation.stop = True`` (with ``stop_reason``). Per-step diagnostics accumulate in
    ``history`` (arrays: time, dt, max_speed, cfl, divergence, pressure_iterations, viscous_iterations,
    picard_iterations, picard_increment)."""

    def __init__(self, model: Model, stop_time: Optional[float] = None, stop_iteration: Optional[int] = None,
                 callbacks: Optional[list] = None, progress: bool = False, wall_limit: Optional[float] = None):
        if stop_time is None and stop_iteration is None:
            raise ParameterError("invalid parameter `stop_time/stop_iteration`: allowed at least one of them")
        if stop_time is not None and not (math.isfinite(stop_time) and stop_time > model.time):
            raise ParameterError(f"invalid parameter `stop_time` = {stop_time!r}: allowed a finite time > the model time {model.time}")
        self.model = model
        self.stop_time = stop_time
        self.stop_iteration = stop_iteration
        self.callbacks = list(callbacks or [])
        self.progress = progress
        self.wall_limit = wall_limit
        self.history: dict[str, list] = {k: [] for k in ("time", "dt", "max_speed", "cfl", "divergence",
                                                          "pressure_iterations", "viscous_iterations",
                                                          "picard_iterations", "picard_increment")}
        self.stop = False
        self.stop_reason = ""
        self.wall_time = 0.0

    def _next_stop(self):
        m = self.model
        t_next = self.stop_time if self.stop_time is not None else math.inf
        n_next = self.stop_iteration - m.step_count if self.stop_iteration is not None else None
        for cb in self.callbacks:
            if cb.every_time is not None:
                k = math.floor(m.time / cb.every_time * (1 + 1e-12)) + 1
                t_next = min(t_next, k * cb.every_time)
            else:
                left = cb.every_steps - m.step_count % cb.every_steps
                n_next = left if n_next is None else min(n_next, left)
        return (None if math.isinf(t_next) else t_next), n_next

    def _due(self, cb: Callback, t_before: float, n_before: int) -> bool:
        m = self.model
        if cb.every_time is not None:
            return math.floor(m.time / cb.every_time * (1 + 1e-12)) > math.floor(t_before / cb.every_time * (1 + 1e-12))
        return m.step_count // cb.every_steps > n_before // cb.every_steps

    def run(self) -> "Simulation":
        """Runs to the stop condition. A failure (SimulationError, SolverError) propagates after
        the history gathered so far is kept in ``history``."""
        m = self.model
        start = _time.perf_counter()
        for cb in self.callbacks:
            cb.func(self)
        while not self.stop:
            if self.stop_time is not None and m.time >= self.stop_time * (1 - 1e-12):
                self.stop_reason = "stop_time"
                break
            if self.stop_iteration is not None and m.step_count >= self.stop_iteration:
                self.stop_reason = "stop_iteration"
                break
            if self.wall_limit is not None and _time.perf_counter() - start > self.wall_limit:
                self.stop_reason = "wall_limit"
                break
            t_next, n_next = self._next_stop()
            t_before, n_before = m.time, m.step_count
            try:
                log = m.advance(t_end=t_next, max_steps=n_next)
            except Exception as err:  # keep the steps done before the failure
                for k, v in getattr(err, "history", {}).items():
                    self.history[k].extend(v)
                self.wall_time = _time.perf_counter() - start
                self.stop_reason = f"error: {err}"
                raise
            for k, v in log.items():
                self.history[k].extend(v)
            for cb in self.callbacks:
                if self._due(cb, t_before, n_before):
                    cb.func(self)
            if self.progress:
                self._print_progress(start)
        self.wall_time = _time.perf_counter() - start
        if self.progress:
            sys.stderr.write("\n")
        return self

    def _print_progress(self, start: float) -> None:
        m = self.model
        wall = _time.perf_counter() - start
        if self.stop_time:
            frac = min(1.0, m.time / self.stop_time)
            left = wall / frac * (1 - frac) if frac > 0 else math.nan
            bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
            sys.stderr.write(f"\r[{bar}] t = {m.time:.4g}/{self.stop_time:g} s  wall {wall:.1f} s  left ~{left:.0f} s  "
                             f"step {m.step_count}  ")
        else:
            sys.stderr.write(f"\rstep {m.step_count}/{self.stop_iteration}  t = {m.time:.4g} s  wall {wall:.1f} s ")
        sys.stderr.flush()

    def history_arrays(self) -> dict:
        return {k: np.asarray(v) for k, v in self.history.items()}
