"""The paper's experiment: collapse of a (fluidised) column of glass beads in a channel.

Aravena, Chupin, Dubois & Roche, §4 (docs/reference-data.md, "The paper"): a column L_c = 0.20 m wide and
H_c = 0.40 m high (aspect ratio a = H_c/L_c = 2) of glass beads (φ = 0.58, ρ_s = 2500 kg m⁻³,
d_s = 75 µm) with internal friction angle α = 27° and wall friction α_b = 15° on the base and the
back wall, released at t = 0 from a reservoir whose gate is at x = L_c. Fluidised: the pore
pressure starts at p_f = β φ ρ_s g (H_c − y) (β = 0.9) and air is supplied through the reservoir
base, ∂p_f/∂y = −β φ ρ_s g for 0 < x < L_c; κ_f = 0.035 m² s⁻¹. D-P rheology with η_s = 0.1 Pa s.
The paper's run-out from the gate: 1.6874 m (simulation), 1.8443 m (experiment).

Numerics chosen for this case (measured reasons in docs/validation.md, "Column collapse"): the
column's default objects (``column_rheology``: θ = 0.8, Picard tolerance 1e-3;
``column_numerics``: WENO5 convection; ``column_interface``: mass correction;
``column_pore_pressure``: κ_∞ = 1e8)
state theirs; a free-slip lid at the top of the domain (with an open top the inner viscous
solves stall near 1e-3 relative and floor the Picard increment above its tolerance).

Rest criterion (``ColumnCase.rest``, a :class:`RestCriterion`; the run file's [rest] section):
the run stops when the largest velocity in the granular phase (cells with Φ > 0; the air side of
the smoothed interface band, Φ ≤ 0, where H_ε still gives a cell some grains, is explicitly not
looked at) stays below ``rest.speed`` (default 5e-3 m/s, 0.18 % of √(2 g H_c)) for
``rest.duration`` (default 0.05 s) after ``rest.after`` (default 0.1 s), or at ``t_end``.
summary.json says when (:func:`arrest_summary`): ``stop_reason`` is ``"rest"`` and
``arrest_time_s`` the start of that quiet window (None for a run that did not come to rest),
with the largest front, when it was reached and how far the front then moved back
(docs/validation.md, "Arrest of the deposit"). With the default numerics the deposit does not
come to rest before ``t_end``; docs/howto/deposit-at-rest.md gives the options that bring it to
rest and keep it there, and what they change.

Models (``ColumnCase.model``, ``granrs run column --model``): ``two-phase`` (the paper's model,
the default), ``granular`` (the same 2D model with the air not resolved: the granular phase has a
free surface at p = 0, ``Model(air='free-surface')``), ``depth-averaged`` (Savage–Hutter shallow
layer with a depth-averaged pore pressure, ``granrs.depth_averaged``; seconds instead of
minutes). All models write the same outputs. There is no automatic choice: the depth-averaged
run-out was measured within 5 % of the two-phase one at no aspect ratio (docs/models.md).

Observables (granrs.observables; docs/validation.md, "Observables"): every record (0.01 s) adds to
front.csv the fronts of the volume profile h = Σ_j f Δy at 1, 2, 5, 10 and 20 mm and at ½, 1 and
2 cells, the 50/90/95/99 % deposit quantiles, the centre of mass and the heights at the back wall
and the gate; summary.json["observables"] holds those of the final deposit with the centre of
mass's travel, and profiles.csv the final volume profile (``hvol_final``).

The package, one file a task: ``case`` (:class:`ColumnCase`, its validation, domain and grid),
``build`` (the 2D model from a case), ``run`` (:func:`run_column`: records, rest criterion,
outputs; :func:`run_columns`: several cases, one after the other or side by side;
:func:`run_finished`: whether a folder holds a run that ended),
``measures`` (front, deposit quantile, surface profile, basal pore-pressure ratio),
``summaries`` (summary.json's derived entries, :class:`RestWatch`, the stop reasons), ``outputs`` (the output files), ``plots``,
and ``depth_averaged`` (the depth-averaged variant).
"""

from .build import build_model, pore_pressure
from .case import (
    MODELS,
    PAPER_RUNOUT_EXP,
    PAPER_RUNOUT_SIM,
    ColumnCase,
    ColumnGeometry,
    Fluidisation,
    G,
    Grains,
    RestCriterion,
    column_interface,
    column_numerics,
    column_pore_pressure,
    column_rheology,
    jop_mu_i,
)
from .depth_averaged import build_depth_averaged, depth_averaged_front_depth, run_column_depth_averaged
from .measures import (
    DEPOSIT_QUANTILE,
    basal_pore_pressure_ratio,
    deposit_quantile,
    farthest_material,
    front_cell,
    front_position,
    granular_speed,
    surface_profile,
)
from .outputs import FRONT_NAMES, _progress as _progress, front_columns, write_energy, write_outputs
from .plots import (
    _front_band as _front_band,
    _front_label as _front_label,
    _label as _label,
    _read_front as _read_front,
    plot_energy,
    plot_fluidisation,
    plot_front,
    plot_profiles,
)
from .run import FLUSH_RECORDS, run_column, run_columns, run_finished
from .summaries import (
    ENERGY_COLUMNS,
    UNFINISHED_REASONS,
    RestWatch,
    _energy_row as _energy_row,
    _observables_summary as _observables_summary,
    _record_observables as _record_observables,
    arrest_summary,
    energy_summary,
    fluidisation_summary,
)

__all__ = [
    "DEPOSIT_QUANTILE",
    "ENERGY_COLUMNS",
    "FLUSH_RECORDS",
    "FRONT_NAMES",
    "G",
    "MODELS",
    "PAPER_RUNOUT_EXP",
    "PAPER_RUNOUT_SIM",
    "ColumnCase",
    "ColumnGeometry",
    "Fluidisation",
    "Grains",
    "arrest_summary",
    "basal_pore_pressure_ratio",
    "build_depth_averaged",
    "build_model",
    "column_interface",
    "column_numerics",
    "column_pore_pressure",
    "column_rheology",
    "jop_mu_i",
    "pore_pressure",
    "deposit_quantile",
    "depth_averaged_front_depth",
    "energy_summary",
    "farthest_material",
    "fluidisation_summary",
    "front_cell",
    "front_columns",
    "front_position",
    "granular_speed",
    "plot_energy",
    "plot_fluidisation",
    "plot_front",
    "plot_profiles",
    "run_column",
    "run_column_depth_averaged",
    "run_columns",
    "run_finished",
    "RestCriterion",
    "RestWatch",
    "UNFINISHED_REASONS",
    "surface_profile",
    "write_energy",
    "write_outputs",
]
