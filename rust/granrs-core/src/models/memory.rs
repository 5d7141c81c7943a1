//! The memory a two-phase model holds, estimated from its grid and options before anything is
//! allocated, and the check [`TwoPhaseModel::new`](super::TwoPhaseModel::new) makes with it.
//!
//! The estimate counts the f64 arrays each room allocates in its constructor (fields with their
//! halos, the solvers' level hierarchies and work vectors) and the step's snapshot of the state
//! (the last accepted state a failed step returns to). It leaves out what is O(nx + ny) (wall
//! vectors, block partial sums) and the thread pool's own bookkeeping; tests/memory.rs compares
//! it with the bytes a counting allocator sees a model take.
//!
//! A model is refused when the estimate exceeds the memory the operating system reports as
//! available (`MemAvailable` of /proc/meminfo); where that is not readable (not Linux) no check
//! is made.

use super::ModelConfig;
use crate::error::{Error, Result};
use crate::grid::{Grid, Location, Side, VelocityBc, HALO};
use crate::rheology::{SigmaLocation, YieldTreatment};
use crate::solvers::{PoissonSolver, ShiftedSystem};

const F64: u64 = 8;

/// f64 values of a field at `loc`, halos included (`Field::zeros`).
fn field(g: &Grid, loc: Location) -> u64 {
    let (nx, ny) = loc.interior_shape(g.nx, g.ny);
    ((nx + 2 * HALO) * (ny + 2 * HALO)) as u64
}

impl ModelConfig {
    /// The bytes a model of this configuration holds (see the module docs): its rooms' arrays,
    /// and with an active region as much again for the window (at most the whole grid).
    pub fn memory_estimate(&self) -> u64 {
        let one = self.memory_estimate_one();
        if self.active_region.is_some() {
            2 * one
        } else {
            one
        }
    }

    fn memory_estimate_one(&self) -> u64 {
        let g = &self.grid;
        let (c, xf, yf, nd) = (field(g, Location::Centre), field(g, Location::XFace), field(g, Location::YFace), field(g, Location::Node));
        let n = (g.nx * g.ny) as u64;
        let s = &self.pressure_solver;
        // the state (u, v, their history and convection at n − 1; p, Φ) and the work arrays
        // (convection, right-hand side, gradient, diagonal; p + p_f)
        let mut f = 3 * (xf + yf) + 2 * c;
        f += 4 * (xf + yf) + c;
        // the properties: ρ on the faces, η at centres and nodes
        f += (xf + yf) + c + nd;
        // level set: transport (2 stages) and redistancing (10 fields); the extended transport
        // velocity: its two face fields; the removal of detached pieces: two u32 per cell
        f += 12 * c;
        if self.redistance.extended_velocity {
            f += xf + yf;
        }
        if self.redistance.piece_removal_cells > 0 {
            f += n;
        }
        // the volume fraction: F and its two moments, the same after the first sweep, the nine
        // rows of the cells' reconstruction and the twelve of their segments, F and its moments
        // in the step's snapshot, and Φ as the properties read it
        if self.interface_transport == crate::levelset::InterfaceTransport::Clsvof && self.light.is_some() {
            f += 31 * c;
        }
        // the film-sparing mass correction: its weight and the rows' maxima
        if self.redistance.mass_correction_film > 0.0 {
            f += 2 * c;
        }
        // momentum solver (5 vectors of CG per component)
        f += 5 * (xf + yf);
        // projection: Poisson solver, β on faces, rhs, δp, work, divergence and δp fields
        f += PoissonSolver::memory_values(g.nx, g.ny, s) + (g.ny * (g.nx + 1) + (g.ny + 1) * g.nx) as u64 + 3 * n + 2 * c;
        if self.free_surface {
            // the free-surface projection besides: its shifted system, divergence, the
            // known-face masks (bytes)
            f += ShiftedSystem::memory_values(g.nx, g.ny, s) + c;
            f += (2 * (g.ny * (g.nx + 1) + (g.ny + 1) * g.nx)) as u64 / F64;
        }
        // the state snapshot of a step
        f += 3 * (xf + yf) + 2 * c + n;
        if self.pore.is_some() {
            f += 4 * c + ShiftedSystem::memory_values(g.nx, g.ny, s);
            f += 3 * c;
        }
        let rc = &self.rheology;
        let coulomb = rc.wall_friction_angle.is_some() && Side::ALL.iter().any(|&side| self.bc.get(side) == VelocityBc::Coulomb);
        if rc.law.has_yield_stress() || coulomb || rc.variable_viscosity() || rc.side_walls.is_some() {
            // rheology stage: strain rates, norms, p and Φ at nodes, rhs and predictor copies
            f += 4 * c + 4 * nd + 2 * (xf + yf);
            // plastic tensor Σ with its anchor, τ, r, trial, new and stress at centres and nodes
            f += 7 * (c + nd);
            if rc.sigma_location == SigmaLocation::Centres {
                f += 4 * c;
            }
            f += rc.picard_max_iterations.min(100_000) as u64;
            let projection = rc.law.has_yield_stress() && rc.treatment == YieldTreatment::Projection;
            if projection && rc.anderson_depth > 0 {
                let depth = rc.anderson_depth.clamp(1, crate::rheology::anderson::MAX_ANDERSON_DEPTH) as u64;
                f += (4 + 2 * depth) * (c + nd);
            }
            if rc.side_walls.is_some() {
                f += 6 * (xf + yf);
            }
            // snapshot: Σ (and Σ_xy at centres), the side walls' directions
            f += c + nd;
            if rc.sigma_location == SigmaLocation::Centres {
                f += c;
            }
            if rc.side_walls.is_some() {
                f += xf + yf;
            }
        }
        f * F64
    }

    /// Refuses a configuration whose model would not fit in the available memory, naming the
    /// grid, the estimate and the memory available.
    pub fn check_memory(&self) -> Result<()> {
        let need = self.memory_estimate();
        match available_memory() {
            Some(avail) if need > avail => Err(Error::param(
                "grid",
                format!("{} x {} cells", self.grid.nx, self.grid.ny),
                &format!(
                    "a grid whose model fits in the memory available: its estimate is {} against {} available (MemAvailable, /proc/meminfo)",
                    format_bytes(need),
                    format_bytes(avail)
                ),
            )),
            _ => Ok(()),
        }
    }
}

/// The memory available to a new process in bytes (`MemAvailable` of /proc/meminfo); None where
/// it cannot be read.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// `bytes` in GiB or MiB, three significant digits.
pub fn format_bytes(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= (1u64 << 30) as f64 {
        format!("{:.3} GiB", b / (1u64 << 30) as f64)
    } else {
        format!("{:.3} MiB", b / (1u64 << 20) as f64)
    }
}
