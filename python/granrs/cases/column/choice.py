"""Model choice for ``model='auto'``: the measured interval where the depth-averaged run-out agrees
with the two-phase one, and :func:`choose_model`."""

from __future__ import annotations

from .case import ColumnCase

# Largest aspect ratio a = H_c/L_c at which the depth-averaged run-out was measured within 5 % of
# the two-phase one at ny = 32 (examples/model_ladder.py → docs/img/model_ladder.csv,
# docs/models.md), per fluidisation state; None: at no measured aspect ratio. Measured points:
# a = 0.5, 1, 2, 4. auto takes the depth-averaged model only at or below the largest aspect
# ratio of an unbroken run of measured agreements starting from the smallest one.
# Measured (k: Savage–Hutter active) against the two-phase model with r_neighbourhood = 0
# fluidised −9.0, −15.3, −15.0, −7.3 %; non-fluidised −11.3, −9.7, +2.5, +16.8 % at
# a = 0.5, 1, 2, 4. No unbroken run of agreement starts at a = 0.5, so auto never takes the
# depth-averaged model. (With the option r_neighbourhood = 2 the non-fluidised a = 0.5 agrees to
# +0.1 %; docs/models.md.)
DEPTH_AVERAGED_MAX_ASPECT = {True: None, False: None}
RUNOUT_TOLERANCE = 0.05


def choose_model(case: ColumnCase) -> tuple[str, str]:
    """(model, reason): the requested model, or for ``auto`` the cheapest one whose documented
    criterion the scene meets (depth-averaged: a ≤ DEPTH_AVERAGED_MAX_ASPECT[fluidised]; otherwise
    the two-phase model)."""
    if case.model != "auto":
        return case.model, "requested"
    fluidised = bool(case.fluidised and case.pore_pressure_ratio > 0)
    state = "fluidised" if fluidised else "non-fluidised"
    a_max = DEPTH_AVERAGED_MAX_ASPECT[fluidised]
    if a_max is not None and case.aspect_ratio <= a_max + 1e-12:
        return "depth-averaged", (f"auto: {state} column with aspect ratio {case.aspect_ratio:g} <= {a_max:g}, where the "
                                  f"depth-averaged run-out was measured within {RUNOUT_TOLERANCE:.0%} of the two-phase "
                                  "model (docs/models.md)")
    limit = "at no measured aspect ratio" if a_max is None else f"only up to aspect ratio {a_max:g}"
    return "two-phase", (f"auto: {state} column with aspect ratio {case.aspect_ratio:g}: the depth-averaged run-out "
                         f"is within {RUNOUT_TOLERANCE:.0%} of the two-phase model {limit} (docs/models.md); "
                         "two-phase model used")
