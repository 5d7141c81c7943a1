"""The 2D model of a :class:`ColumnCase` (two-phase or granular-only): grid, materials, walls,
numerics, pore pressure, rheology and the initial condition (convection by WENO5, a free-slip
lid: the package's docstring gives the measured reasons)."""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ...boundary import BoundaryConditions, Coulomb, FreeSlip
from ...materials import AIR, Material
from ...model import Model, Numerics, PorePressure, SideWalls
from ...shapes import Rectangle
from .case import COLUMN_NUMERICS, OPTION_FIELD_KEYS, ColumnCase, G


def side_walls(case: ColumnCase) -> Optional[SideWalls]:
    """The channel's side walls of ``case`` (None without a channel_width)."""
    if case.channel_width is None:
        return None
    angle = case.wall_friction_angle if case.side_wall_friction_angle is None else case.side_wall_friction_angle
    return SideWalls(case.channel_width, angle)


def build_model(case: ColumnCase) -> Model:
    """The two-phase model of the column case (or, with ``model='granular'``, the granular-only
    model: the same 2D model with the air not resolved), with its initial condition."""
    case.validate()
    grid = case.grid()
    hc, lc = case.column_height, case.width
    rho = case.mixture_density
    pore = None
    if case.fluidised and case.pore_pressure_ratio > 0:
        sign = 1.0 if case.air_supply == "literal" else -1.0
        pore = PorePressure(
            diffusivity=case.diffusivity,
            basal_gradient=sign * case.pore_pressure_ratio * rho * G,
            formulation=case.pore_formulation,
            kappa_air=case.kappa_air,
            basal_x_min=0.0,
            basal_x_max=lc,
        )
    model = Model(
        grid,
        Material(rho, case.granular_viscosity),
        light=AIR,
        gravity=(0.0, -G),
        bc=BoundaryConditions(
            left=FreeSlip() if case.back_wall == "free-slip" else Coulomb(case.wall_friction_angle),
            right=FreeSlip(),
            bottom=Coulomb(case.wall_friction_angle),
            top=FreeSlip(),
        ),
        numerics=column_numerics(case),
        threads=case.threads,
        pore_pressure=pore,
        air="free-surface" if case.model == "granular" else "resolved",
        side_walls=side_walls(case),
        **_rheology_kwargs(case),
    )
    model.set_shape(Rectangle(-1.0, lc, -1.0, hc), balance_pressure=False)
    if pore is not None:
        beta = case.pore_pressure_ratio
        model.set_initial(
            pf=lambda x, y: np.where((x < lc) & (y < hc), beta * rho * G * (hc - y), 0.0), balance_pressure=False
        )
    model.set_initial(balance_pressure=True)
    return model


def column_numerics(case: ColumnCase) -> Numerics:
    """The model's numerics of ``case``: the column's (COLUMN_NUMERICS), its option fields
    (OPTION_FIELDS) and its ``numerics`` dict, in that order of precedence (last wins)."""
    fields = {key: getattr(case, name) for key, name in OPTION_FIELD_KEYS.items() if key != "threads"}
    return Numerics(**{**COLUMN_NUMERICS, **fields, **case.numerics})


def _rheology_kwargs(case: ColumnCase) -> dict:
    """The granular rheology of the case: the paper's D-P model (constant η_s, yield stress
    tan α p⁺) or μ(I). The paper gives no μ(I) constants for its beads; we take μ_s = tan α and
    the Δμ = μ₂ − μ_s = 0.26, I₀ = 0.279 of Jop, Forterre & Pouliquen (2006, Nature 441) for glass
    beads (an assumption, stated in the summary)."""
    from ...rheology import DruckerPrager, MuI

    if case.rheology == "drucker-prager":
        return {"rheology": DruckerPrager(friction_angle=case.friction_angle)}
    mu_s = math.tan(math.radians(case.friction_angle))
    return {
        "rheology": MuI(
            mu_s=mu_s, mu_2=mu_s + 0.26, i0=0.279, grain_diameter=case.grain_diameter, grain_density=case.grain_density
        )
    }
