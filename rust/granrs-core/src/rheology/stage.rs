//! The state of the rheology room (Σ, the walls' friction, their work arrays), allocated once;
//! its two pieces of a time step, the rheology stage and the momentum solve with the Picard loop
//! of eq. (12), run on the model in `models/rheology_stage.rs`.

use super::anderson::Anderson;
use super::plastic::PlasticState;
use super::{RheologyConfig, YieldTreatment};
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, Location, Side, VelocityBc, HALO};
use crate::solvers::par::{n_blocks, sum_rows};
use crate::walls::side::SideWallFriction;
use crate::walls::CoulombWalls;

/// Stall safeguard of the Picard loop: every `PICARD_STALL_WINDOW` iterations, if the increment
/// has not fallen below 95 % of its value at the start of the window (a cycle, not the slow
/// geometric decay of Uzawa-like settings, θ → 0), r and r_b are halved. The
/// contraction bounds behind the default r, r_b hold for each projection alone; with Coulomb
/// walls and the plastic tensor on the same faces, and at steps of a few ms, the iteration was
/// seen to lock into a cycle (increment 1.7e-2 for 300 iterations, fluidised column at ny = 64,
/// t = 0.013 s) that a smaller r_b breaks (geometric again at once).
pub const PICARD_STALL_WINDOW: usize = 40;

/// At most this many halvings per step (r/64): beyond, a stall is not a cycle that a smaller r
/// breaks (θ = 0 Uzawa iterations near their tolerance were driven to r = 1e-152 without it).
/// Uzawa (θ = 0) is left alone: its slow geometric decay is not a cycle.
pub const PICARD_MAX_HALVINGS: usize = 6;

/// Iteration cap of each viscous solve inside the Picard loop.
pub const PICARD_SOLVE_MAX_ITERATIONS: usize = 500;

/// State and work arrays of the rheology (allocated once, only for non-Newtonian laws or
/// friction walls).
pub struct RheologyState {
    pub plastic: PlasticState,
    pub walls: CoulombWalls,
    /// Friction of the channel's side walls (`RheologyConfig::side_walls`).
    pub side_walls: Option<SideWallFriction>,
    pub(crate) dxx: Field,
    pub(crate) dyy: Field,
    pub(crate) dxy: Field,
    pub(crate) dnorm_c: Field,
    pub(crate) dnorm_n: Field,
    pub(crate) p_n: Field,
    pub(crate) phi_n: Field,
    pub(crate) rhs_u: Field,
    pub(crate) rhs_v: Field,
    pub(crate) ustar_u: Field,
    pub(crate) ustar_v: Field,
    /// |Σ + r D_dev + θ(Σ^n − Σ)| at centres after the last step (≤ 1: rigid).
    pub trial_norm: Field,
    /// Whether the Picard loop runs (projection of a yield stress, or friction walls).
    pub(crate) picard: bool,
    /// Whether Σ is iterated (a yield stress treated by projection).
    pub(crate) projection: bool,
    /// Increments of the Picard iterations of the last step (capacity reserved once).
    pub history: Vec<f64>,
    /// r of the current step (a user's constant r, or the smallest local r), and r_b.
    pub r: f64,
    pub r_wall: f64,
    /// p_s of `YieldPressure::SurfaceAir` at the current step (0 with `Absolute`) [Pa].
    pub p_surface: f64,
    /// Block partial sums of `surface_air_pressure` (allocated once).
    pub(crate) surface_partials: Vec<[f64; 2]>,
    /// Anderson mixing of Σ (`RheologyConfig::anderson_depth` > 0 with a projected yield stress).
    pub(crate) anderson: Option<Anderson>,
}

impl RheologyState {
    /// `None` for a Newtonian law without friction walls.
    pub fn new(grid: &Grid, bc: &BoundaryConditions, cfg: &RheologyConfig) -> Option<Self> {
        let coulomb = Side::ALL.iter().any(|&s| bc.get(s) == VelocityBc::Coulomb);
        let walls = CoulombWalls::new(grid, bc, cfg.wall_friction_angle.is_some());
        if !cfg.law.has_yield_stress() && !walls.is_active() && !cfg.variable_viscosity() && cfg.side_walls.is_none() {
            return None;
        }
        let c = || Field::zeros(grid, Location::Centre);
        let n = || Field::zeros(grid, Location::Node);
        let plastic = PlasticState::new(grid, bc, cfg.sigma_location);
        let projection = cfg.law.has_yield_stress() && cfg.treatment == YieldTreatment::Projection;
        let anderson = (projection && cfg.anderson_depth > 0).then(|| Anderson::new(cfg.anderson_depth, &plastic));
        Some(RheologyState {
            plastic,
            walls,
            side_walls: cfg.side_walls.map(|_| SideWallFriction::new(grid)),
            dxx: c(),
            dyy: c(),
            dxy: n(),
            dnorm_c: c(),
            dnorm_n: n(),
            p_n: n(),
            phi_n: n(),
            rhs_u: Field::zeros(grid, Location::XFace),
            rhs_v: Field::zeros(grid, Location::YFace),
            ustar_u: Field::zeros(grid, Location::XFace),
            ustar_v: Field::zeros(grid, Location::YFace),
            trial_norm: c(),
            history: Vec::with_capacity(cfg.picard_max_iterations.min(100_000)),
            picard: cfg.needs_picard(coulomb),
            projection,
            r: 0.0,
            r_wall: 0.0,
            p_surface: 0.0,
            surface_partials: vec![[0.0; 2]; n_blocks(grid.ny)],
            anderson,
        })
    }
}

impl RheologyState {
    /// Whether Σ is iterated (a yield stress treated by projection).
    pub fn has_plastic_tensor(&self) -> bool {
        self.projection
    }
}

/// Mean pressure of the air on the granular surface (`YieldPressure::SurfaceAir`): the average of
/// p over the cells with −ε − h ≤ Φ < −ε (one layer of air cells just outside the smoothed band,
/// Φ a distance), equal weights; 0 when there is none. A fixed-order row-block reduction
/// ([`crate::solvers::par::sum_rows`], `partials` ≥ its number of blocks), so serial and parallel
/// runs agree bit for bit.
pub(crate) fn surface_air_pressure(p: &Field, phi: &Field, eps: f64, h: f64, partials: &mut [[f64; 2]], exec: Exec) -> f64 {
    let (nx, ny) = (p.nx, p.ny);
    let (ps, fs) = (p.slice(), phi.slice());
    let [sum, count] = sum_rows::<2, _>(exec, ny, nx * ny, partials, |j| {
        let b = (j + HALO) * p.stride() + HALO;
        let mut out = [0.0; 2];
        for i in 0..nx {
            let f = fs[b + i];
            if f < -eps && f >= -eps - h {
                out[0] += ps[b + i];
                out[1] += 1.0;
            }
        }
        out
    });
    if count > 0.0 {
        sum / count
    } else {
        0.0
    }
}

impl crate::grid::StateArrays for RheologyState {
    /// Σ (and Σ_xy at centres), the side walls' directions, the Coulomb walls' directions.
    fn visit_state(&self, f: &mut dyn FnMut(&str, &[f64])) {
        f("sigma_xx", self.plastic.sigma_xx.slice());
        f("sigma_xy", self.plastic.sigma_xy.slice());
        if let Some(cs) = &self.plastic.centred {
            f("sigma_xy_centre", cs.sigma.slice());
        }
        if let Some(sw) = &self.side_walls {
            f("side_wall_s_u", sw.s_u.slice());
            f("side_wall_s_v", sw.s_v.slice());
        }
        for (k, s) in self.walls.directions().iter().enumerate() {
            f(&format!("wall_direction_{k}"), s);
        }
    }

    fn visit_state_mut(&mut self, f: &mut dyn FnMut(&str, &mut [f64])) {
        f("sigma_xx", self.plastic.sigma_xx.slice_mut());
        f("sigma_xy", self.plastic.sigma_xy.slice_mut());
        if let Some(cs) = &mut self.plastic.centred {
            f("sigma_xy_centre", cs.sigma.slice_mut());
        }
        if let Some(sw) = &mut self.side_walls {
            f("side_wall_s_u", sw.s_u.slice_mut());
            f("side_wall_s_v", sw.s_v.slice_mut());
        }
        for (k, s) in self.walls.directions_mut().into_iter().enumerate() {
            f(&format!("wall_direction_{k}"), s);
        }
    }
}
