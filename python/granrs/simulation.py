"""The simulation owns the time loop: stop conditions, callbacks, diagnostics history, and the
detection of a blow-up the core's own checks let through.

After every chunk of steps (at most ``Simulation.chunk_steps``) the loop checks each step's
diagnostics and raises ``SimulationError`` (with ``step``, ``time`` and ``location``, the cell
(i, j) of the largest speed) when
  * a speed, δt or CFL number is not finite;
  * the CFL number after the step, max|u|·δt/h with the velocity the step produced, exceeds the
    model's ``Numerics.cfl_abort``;
  * the time step collapsed: δt fell below ``dt_collapse`` (1e-6) times the largest step taken
    so far in this run (the clock stalls while the velocity grows);
  * the largest speed exceeds ``speed_limit`` (default 100 × the free-fall speed √(2|g|(lx + ly))
    over the domain, or 100 × the largest speed at the start or on a boundary, whichever is
    larger): an unbounded growth no flow driven by gravity or by its boundaries reaches.
The model is then put back at the state it had before that chunk (its last state known good,
restored from a copy kept when the core exports its state) and ``history`` ends with the last
step before that state.
"""

from __future__ import annotations

import contextlib
import math
import signal
import sys
import threading
import time as _time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ._granrs import ParameterError, SimulationError
from .model import Model


class Terminated(KeyboardInterrupt):
    """A SIGTERM or SIGHUP (what a batch scheduler or a closed terminal sends), raised where a
    Ctrl-C's KeyboardInterrupt would be, so that a run stops the same way: ``signum``, and the
    message "terminated by SIGTERM"."""

    def __init__(self, signum: int):
        super().__init__(f"terminated by {signal.Signals(signum).name}")
        self.signum = int(signum)


def raise_terminated(signum: int, frame=None) -> None:
    """A signal handler raising ``Terminated`` (``granrs`` on the command line installs it for
    SIGTERM and SIGHUP)."""
    raise Terminated(signum)


#: The signals ``deferred_interrupt`` holds when their handler raises (a Python function).
HELD_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))


@contextlib.contextmanager
def deferred_interrupt():
    """Holds SIGINT (KeyboardInterrupt), and SIGTERM and SIGHUP where a Python handler takes them
    (``raise_terminated``), until the block ends, then hands the first one received to its
    handler (main thread only). A signal that is ignored (SIGINT of a process started in the
    background by a shell without job control, SIGHUP under ``nohup``) or left to the system
    keeps that disposition inside the block too."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = [s for s in HELD_SIGNALS if callable(signal.getsignal(s))]
    received: list = []
    previous = {s: signal.signal(s, lambda signum, frame: received.append(signum)) for s in held}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    if received:
        handler = previous[received[0]]
        if callable(handler):  # always: only the signals with a Python handler are held
            handler(received[0], None)


@dataclass
class Callback:
    """Calls ``func(simulation)`` every ``every_time`` seconds of simulated time (landing on those
    times exactly) or every ``every_steps`` steps. ``saves_state``: ``func`` saves the model's
    state for a restart (a checkpoint); the simulation's ``flush_outputs`` (a driver's outputs
    gathered so far) is then called first, so what a restart from that state appends to on disk
    holds every record and step before it."""

    func: Callable[[Simulation], object]  # what it returns is not used
    every_time: Optional[float] = None
    every_steps: Optional[int] = None
    saves_state: bool = False

    def __post_init__(self):
        if not callable(self.func):
            raise ParameterError(
                f"invalid parameter `func` = {self.func!r}: allowed a callable func(simulation), called at each output"
            )
        if (self.every_time is None) == (self.every_steps is None):
            raise ParameterError("invalid parameter `Callback`: give exactly one of every_time, every_steps")
        if self.every_time is not None and not (math.isfinite(self.every_time) and self.every_time > 0):
            raise ParameterError(f"invalid parameter `every_time` = {self.every_time!r}: allowed a finite number > 0")
        if self.every_steps is not None and not (isinstance(self.every_steps, int) and self.every_steps >= 1):
            raise ParameterError(f"invalid parameter `every_steps` = {self.every_steps!r}: allowed an integer >= 1")
        if not isinstance(self.saves_state, bool):
            raise ParameterError(f"invalid parameter `saves_state` = {self.saves_state!r}: allowed True or False")


class Simulation:
    """Runs a model to ``stop_time`` and/or ``stop_iteration``, or until a callback sets
    ``simulation.stop = True`` (with ``stop_reason``). Per-step diagnostics accumulate in
    ``history`` (lists: time, dt, max_speed, cfl, divergence, pressure_iterations, viscous_iterations,
    pore_iterations, and those the model adds). ``speed_limit`` and ``dt_collapse``: the blow-up
    checks of the module docstring. A Ctrl-C (KeyboardInterrupt) is raised once the chunk of steps
    in progress is in ``history``, so an interrupted run keeps its last steps."""

    #: most steps per call into the core between two blow-up checks
    chunk_steps = 50

    def __init__(
        self,
        model: Model,
        stop_time: Optional[float] = None,
        stop_iteration: Optional[int] = None,
        callbacks: Optional[list] = None,
        progress: bool = False,
        wall_limit: Optional[float] = None,
        speed_limit: Optional[float] = None,
        dt_collapse: float = 1e-6,
    ):
        if not isinstance(model, Model):
            raise ParameterError(f"invalid parameter `model` = {model!r}: allowed a granrs.Model")
        if callbacks is not None and not isinstance(callbacks, (list, tuple)):
            raise ParameterError(
                f"invalid parameter `callbacks` = {callbacks!r}: allowed a list of granrs.Callback "
                "(one callback too: callbacks=[Callback(...)])"
            )
        if stop_time is None and stop_iteration is None:
            raise ParameterError("invalid parameter `stop_time/stop_iteration`: allowed at least one of them")
        if stop_time is not None and (
            isinstance(stop_time, bool)
            or not isinstance(stop_time, (int, float))
            or not (math.isfinite(stop_time) and stop_time > model.time)
        ):
            raise ParameterError(
                f"invalid parameter `stop_time` = {stop_time!r}: allowed a finite time > the model time {model.time}"
            )
        if stop_iteration is not None and (
            isinstance(stop_iteration, bool)
            or not isinstance(stop_iteration, int)
            or stop_iteration <= model.step_count
        ):
            raise ParameterError(
                f"invalid parameter `stop_iteration` = {stop_iteration!r}: allowed an integer > the model's "
                f"step count {model.step_count}"
            )
        if wall_limit is not None and (
            isinstance(wall_limit, bool)
            or not isinstance(wall_limit, (int, float))
            or not (math.isfinite(wall_limit) and wall_limit > 0)
        ):
            raise ParameterError(
                f"invalid parameter `wall_limit` = {wall_limit!r}: allowed a finite number of seconds > 0"
            )
        if callbacks is not None and not all(isinstance(cb, Callback) for cb in callbacks):
            raise ParameterError(f"invalid parameter `callbacks` = {callbacks!r}: allowed a list of granrs.Callback")
        if speed_limit is not None and (
            isinstance(speed_limit, bool)
            or not isinstance(speed_limit, (int, float))
            or not (math.isfinite(speed_limit) and speed_limit > 0)
        ):
            raise ParameterError(
                f"invalid parameter `speed_limit` = {speed_limit!r}: allowed None or a finite speed > 0 (m/s)"
            )
        if isinstance(dt_collapse, bool) or not isinstance(dt_collapse, (int, float)) or not 0 <= dt_collapse < 1:
            raise ParameterError(f"invalid parameter `dt_collapse` = {dt_collapse!r}: allowed a number in [0, 1)")
        self.speed_limit = speed_limit if speed_limit is not None else _default_speed_limit(model)
        self.dt_collapse = float(dt_collapse)
        self._dt_max = 0.0
        self.model = model
        self.stop_time = stop_time
        self.stop_iteration = stop_iteration
        self.callbacks = list(callbacks or [])
        self.progress = progress
        self.wall_limit = wall_limit
        self.history: dict[str, list] = {}
        self.stop = False
        self.stop_reason = ""
        self.wall_time = 0.0
        #: called before each ``saves_state`` callback; a driver sets it to write its outputs so far
        self.flush_outputs: Optional[Callable[[Simulation], object]] = None

    def _call(self, cb: Callback) -> None:
        """Calls a callback; an exception of its own (not granrs's SimulationError, not an
        interrupt) stops the run as a SimulationError naming the callback, chained to it."""
        if cb.saves_state and self.flush_outputs is not None:
            self.flush_outputs(self)
        try:
            cb.func(self)
        except SimulationError:
            raise
        except Exception as err:
            name = getattr(cb.func, "__qualname__", None) or type(cb.func).__name__
            self.stop_reason = f"error: the callback {name} raised {type(err).__name__}: {err}"
            raise SimulationError(
                f"the callback {name} raised {type(err).__name__}: {err} at t = {self.model.time:.6g} s (step "
                f"{self.model.step_count}); the run stops there"
            ) from err

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
        every = cb.every_steps
        assert every is not None  # Callback holds exactly one of every_time, every_steps
        return m.step_count // every > n_before // every

    def run(self) -> Simulation:
        """Runs to the stop condition. A failure (SimulationError, SolverError) propagates after
        the history gathered so far is kept in ``history``. A model runs in one thread at a time:
        a second run of the same model while one goes on is a ParameterError naming it."""
        busy = self.model.__dict__.setdefault("_run_lock", threading.Lock())
        if not busy.acquire(blocking=False):
            raise ParameterError(
                f"invalid parameter `model` = {_model_words(self.model)}: it is running in another thread; "
                "allowed one run at a time per model (a Model of its own for each thread)"
            )
        try:
            return self._run()
        finally:
            busy.release()

    def _run(self) -> Simulation:
        m = self.model
        start = _time.perf_counter()
        for cb in self.callbacks:
            self._call(cb)
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
            n_next = self.chunk_steps if n_next is None else min(n_next, self.chunk_steps)
            t_before, n_before = m.time, m.step_count
            good = _state(m)
            with deferred_interrupt():  # a Ctrl-C waits until the chunk's steps are in the history
                try:
                    log = m.advance(t_end=t_next, max_steps=n_next)
                except Exception as err:  # keep the steps done before the failure
                    if type(err) is RuntimeError and "borrowed" in str(err):
                        raise ParameterError(  # the core's state is held by a call from another thread
                            f"invalid parameter `model` = {_model_words(m)}: it is in use by another thread; "
                            "allowed one thread at a time per model (a Model of its own for each thread)"
                        ) from None
                    for k, v in getattr(err, "history", {}).items():
                        self.history.setdefault(k, []).extend(v)
                    self.wall_time = _time.perf_counter() - start
                    self.stop_reason = f"error: {err}"
                    raise
                try:
                    self._check_blow_up(log, good, t_before, n_before)
                except SimulationError as err:
                    self.wall_time = _time.perf_counter() - start
                    self.stop_reason = f"error: {err}"
                    raise
                for k, v in log.items():
                    self.history.setdefault(k, []).extend(v)
            for cb in self.callbacks:
                if self._due(cb, t_before, n_before):
                    self._call(cb)
            if self.progress:
                self._print_progress(start)
        self.wall_time = _time.perf_counter() - start
        if self.progress:
            sys.stderr.write("\n")
        return self

    def _check_blow_up(self, log: dict, good, t_before: float, n_before: int) -> None:
        """Raises SimulationError at the first step of ``log`` that blew up (module docstring),
        after putting the model back at ``good`` (its state before the chunk)."""
        m = self.model
        h = m.grid.h
        cfl_abort = m.numerics.cfl_abort
        for k, (t, dt, speed) in enumerate(zip(log.get("time", ()), log.get("dt", ()), log.get("max_speed", ()))):
            why = None
            if not (math.isfinite(t) and math.isfinite(dt) and math.isfinite(speed)):
                why = f"a non-finite step (δt = {dt!r}, max speed {speed!r} m/s)"
            elif speed * dt / h > cfl_abort:
                why = (
                    f"the CFL number after the step, max|u| δt/h = {speed * dt / h:.4g}, exceeds cfl_abort = "
                    f"{cfl_abort:g} (max speed {speed:.4g} m/s)"
                )
            elif speed > self.speed_limit:
                why = (
                    f"the largest speed {speed:.4g} m/s exceeds the limit {self.speed_limit:.4g} m/s (unbounded "
                    "growth: Simulation(speed_limit=...))"
                )
            elif self._dt_max > 0 and dt < self.dt_collapse * self._dt_max:
                why = (
                    f"the time step collapsed: δt = {dt:.3g} s is below {self.dt_collapse:g} × the largest step "
                    f"{self._dt_max:.3g} s (max speed {speed:.4g} m/s)"
                )
            if why is None:
                self._dt_max = max(self._dt_max, dt)
                continue
            location = _fastest_cell(m)
            restored = _restore(m, good)
            where = f" at cell (i={location[0]}, j={location[1]})" if location is not None else ""
            back = (
                f"; the model is back at t = {t_before:.6g} s, step {n_before}"
                if restored
                else "; the model holds the state after the blow-up"
            )
            err = SimulationError(f"blow-up at step {n_before + k + 1}, t = {t:.6g} s{where}: {why}{back}")
            err.step, err.time, err.location = n_before + k + 1, t, location
            err.history = {}
            raise err

    def _print_progress(self, start: float) -> None:
        m = self.model
        wall = _time.perf_counter() - start
        if self.stop_time:
            frac = min(1.0, m.time / self.stop_time)
            left = wall / frac * (1 - frac) if frac > 0 else math.nan
            bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
            sys.stderr.write(
                f"\r[{bar}] t = {m.time:.4g}/{self.stop_time:g} s  wall {wall:.1f} s  left ~{left:.0f} s  "
                f"step {m.step_count}  "
            )
        else:
            sys.stderr.write(f"\rstep {m.step_count}/{self.stop_iteration}  t = {m.time:.4g} s  wall {wall:.1f} s ")
        sys.stderr.flush()

    def history_arrays(self) -> dict:
        return {k: np.asarray(v) for k, v in self.history.items()}


def _model_words(model: Model) -> str:
    """The model named for an error: its class, grid and identity."""
    g = model.grid
    return f"<{type(model).__name__} {g.nx} x {g.ny} cells at {id(model):#x}>"


def _default_speed_limit(model: Model) -> float:
    """100 × the largest of the free-fall speed over the domain, the largest initial speed and the
    largest boundary speed (m/s)."""
    g = math.hypot(*model.gravity)
    scale = math.sqrt(2.0 * g * (model.grid.lx + model.grid.ly))
    try:
        scale = max(scale, float(np.max(np.abs(model.u))), float(np.max(np.abs(model.v))))
    except ValueError:
        pass
    for side in ("left", "right", "bottom", "top"):
        spec = getattr(model.bc, side, None)
        for name in ("tangential", "normal", "velocity"):
            v = getattr(spec, name, None)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                scale = max(scale, abs(float(v)))
    return 100.0 * max(scale, 1e-3)


def _state(model: Model):
    """A copy of the model's state (None when the core cannot export it)."""
    rust = model._rust
    if not hasattr(rust, "checkpoint_state"):
        return None
    return rust.checkpoint_state()  # fresh arrays: the core copies its state out


def _restore(model: Model, state) -> bool:
    if state is None:
        return False
    try:
        model._rust.restore_state(state)
    except Exception:  # noqa: BLE001 - the blow-up is reported either way
        return False
    return True


def _fastest_cell(model: Model):
    """(i, j) of the cell with the largest (or a non-finite) centre speed."""
    try:
        uc, vc = model.centre_velocity()
        speed = np.hypot(uc, vc)
        speed = np.where(np.isfinite(speed), speed, np.inf)
        j, i = np.unravel_index(int(np.argmax(speed)), speed.shape)
        return int(i), int(j)
    except Exception:  # noqa: BLE001
        return None
