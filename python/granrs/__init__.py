"""granrs: dense granular flows fluidised by pore gas pressure, on a MAC grid.

Reproduces and extends Aravena, Chupin, Dubois & Roche, *Fluidisation by pore pressure of dense
granular flows: numerical simulations versus experiments*. The Rust core (``granrs._granrs``)
does the numerics; this package sets up cases, runs them and plots the results.

The pipeline is grid → model → simulation → run::

    import granrs
    grid = granrs.Grid(nx=64, ny=64, lx=1.0, ly=1.0)
    model = granrs.Model(grid, dense=granrs.Material(density=1.0, viscosity=0.01),
                         bc=granrs.BoundaryConditions(top=granrs.Velocity(tangential=1.0)))
    sim = granrs.Simulation(model, stop_time=10.0)
    sim.run()
    model.u   # read-only zero-copy view of the x-velocity, shape (ny, nx + 1)
"""

from . import shapes
from ._granrs import ParameterError, SimulationError, SolverError, __version__, build_info
from .boundary import (
    BoundaryConditions,
    Coulomb,
    CoulombWall,
    FreeSlip,
    FullyDeveloped,
    NavierSlip,
    NoSlip,
    Outflow,
    Velocity,
)
from .depth_averaged import DepthAveraged, DepthAveragedModel, DepthAveragedPore
from .grid import Grid
from .materials import AIR, WATER, Material
from .model import Model, PorePressure, SideWalls
from .options import ActiveRegion, BiProjection, Interface, Numerics, TimeStepping
from .rheology import Bingham, DruckerPrager, MuI, Newtonian
from .simulation import Callback, Simulation

__all__ = [
    "AIR",
    "ActiveRegion",
    "BiProjection",
    "WATER",
    "Bingham",
    "BoundaryConditions",
    "Callback",
    "Coulomb",
    "CoulombWall",
    "DepthAveraged",
    "DepthAveragedModel",
    "DepthAveragedPore",
    "DruckerPrager",
    "FreeSlip",
    "FullyDeveloped",
    "Grid",
    "Interface",
    "Material",
    "Model",
    "MuI",
    "NavierSlip",
    "Newtonian",
    "NoSlip",
    "Numerics",
    "Outflow",
    "PorePressure",
    "SideWalls",
    "ParameterError",
    "Simulation",
    "SimulationError",
    "TimeStepping",
    "SolverError",
    "Velocity",
    "__version__",
    "build_info",
    "shapes",
]
