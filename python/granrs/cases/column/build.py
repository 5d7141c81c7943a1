"""The 2D model of a :class:`ColumnCase` (two-phase or granular-only): grid, materials, walls,
pore pressure, rheology, options and the initial condition (the column's default objects in
``case`` give the measured reasons for its numerics)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ...boundary import BoundaryConditions, FreeSlip
from ...materials import AIR, Material
from ...model import Model, PorePressure
from ...shapes import Rectangle
from .case import ColumnCase, G


def pore_pressure(case: ColumnCase) -> PorePressure | None:
    """The case's pore pressure with the scene's air supply through the reservoir's base
    (−β φρ_s g for 0 < x < L_c with ``fluidisation.air_supply='injection'``); None when not
    fluidised."""
    f = case.fluidisation
    if not f.active:
        return None
    sign = 1.0 if f.air_supply == "literal" else -1.0
    return dataclasses.replace(
        case.pore_pressure,
        basal_gradient=sign * f.pore_pressure_ratio * case.mixture_density * G,
        basal_x_min=0.0,
        basal_x_max=case.geometry.width,
    )


def model_arguments(case: ColumnCase) -> dict:
    """The arguments of the column's ``Model`` (``Model.check`` checks them without allocating)."""
    case.validate()
    return dict(
        grid=case.grid(),
        dense=Material(case.mixture_density, case.rheology.viscosity),
        light=AIR,
        gravity=(0.0, -G),
        bc=BoundaryConditions(
            left=FreeSlip() if case.back_wall == "free-slip" else case.base,
            right=FreeSlip(),
            bottom=case.base,
            top=FreeSlip(),
        ),
        numerics=case.numerics,
        time_stepping=case.time,
        active_region=case.active_region,
        interface=case.interface,
        threads=case.threads,
        pore_pressure=pore_pressure(case),
        air="free-surface" if case.model == "granular" else "resolved",
        side_walls=case.side_walls,
        rheology=case.rheology,
    )


def build_model(case: ColumnCase) -> Model:
    """The two-phase model of the column case (or, with ``model='granular'``, the granular-only
    model: the same 2D model with the air not resolved), with its initial condition."""
    args = model_arguments(case)
    hc, lc = case.column_height, case.geometry.width
    rho = case.mixture_density
    pore = args["pore_pressure"]
    model = Model(**args)
    model.set_shape(Rectangle(-1.0, lc, -1.0, hc), balance_pressure=False)
    if pore is not None:
        beta = case.fluidisation.pore_pressure_ratio
        model.set_initial(
            pf=lambda x, y: np.where((x < lc) & (y < hc), beta * rho * G * (hc - y), 0.0), balance_pressure=False
        )
    model.set_initial(balance_pressure=True)
    return model
