//! Free-surface projection of the granular-only model (issue 8: the air is not resolved; the
//! granular phase Φ > 0 is bounded by a free surface at the ambient pressure):
//!
//!   a₀ ρ_s (u^{n+1} − ũ^{n+1}) / δt + ∇p^{n+1} = 0,   div u^{n+1} = 0   in Ω_s = {Φ > 0},
//!   p^{n+1} = 0 on the surface Φ = 0,
//!
//! hence div((1/ρ_s) ∇p) = (a₀/δt) div ũ in Ω_s, with the Dirichlet condition imposed at the
//! surface's sub-cell position by the ghost-fluid method of Gibou, Fedkiw, Cheng & Kang (2002,
//! *J. Comput. Phys.* 176, 205–227): a face between a granular cell c and an air cell a, crossed
//! by Φ = 0 at the fraction θ = Φ_c/(Φ_c − Φ_a) of the centre distance h (`levelset/subcell.rs`,
//! shared with the pore-pressure room), sees the ghost value p_g = p_c(1 − 1/θ), i.e. the flux −β p_c/(θh); the
//! face leaves the operator and the diagonal gains β/(θh²). Air cells carry the trivial row
//! p = 0. The same ghost value corrects the surface faces' velocity.
//!
//! **Incremental form.** As in the two-phase projection, the predictor carries ∇pⁿ and the
//! projection solves for the increment δp (p^{n+1} = pⁿ + δp), here with δp = 0 on the surface
//! Φ^{n+1} = 0. The predictor's ∇pⁿ takes the same ghost values on the faces that cross the new
//! surface ([`FreeSurfaceProjection::add_pressure_gradient`]), so that pⁿ is read as 0 there; a
//! cell that has just joined the granular phase carries pⁿ = 0 (its air value) until δp corrects
//! it. The increment matters for the plastic stress: without ∇pⁿ (the non-incremental form)
//! the predicted velocity of a granular body at rest falls freely by g δt, and the
//! bi-projection then yields the grains near the surface, where p is small (measured: a
//! deposit that kept flowing at 0.6 m/s).
//!
//! **Velocity extension.** The faces with no granular cell beside them are not solved. After the
//! projection they get the granular velocity by layered extrapolation: layer k = 1..K gives each
//! such face that touches faces known after layer k − 1 (its 4 neighbours on its own staggered
//! grid) the mean of those; faces farther than K layers are set to 0. The extension is constant
//! along the normal to first order, the usual approximation of the stress-free surface
//! ∂u/∂n = 0 (Foster & Fedkiw 2001, *SIGGRAPH*; Enright et al. 2002), and it is what transports
//! the level set. K = [`EXTENSION_LAYERS`] covers the WENO5 stencil (3 cells) plus the
//! interface's motion in one step (< 1 cell at CFL < 1) and the redistancing band.
//!
//! Work arrays are allocated in [`FreeSurfaceProjection::new`]; a step allocates nothing. The
//! extension and the coefficient loops are serial and the solve is the project's deterministic
//! MGCG, so one thread and many give bit-identical results.

use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, Side};
use crate::levelset::{interface_faces, interface_fraction};
use crate::operators::{divergence, unknown_face_range};
use crate::projection::fill_pressure_ghosts;
use crate::solvers::{PoissonSolver, SolveInfo, SolverSettings};

/// Layers of faces the velocity is extended into the air (see the module header).
pub const EXTENSION_LAYERS: usize = 6;

fn inside(phi: f64) -> bool {
    phi > 0.0
}

/// ∂p/∂n on the face between centres L and R (distance h) with p = 0 on the surface: the
/// ghost value p(1 − 1/θ) on the air side; None between two air cells.
fn surface_gradient(pl: f64, pr: f64, fl: f64, fr: f64, h: f64) -> Option<f64> {
    match (inside(fl), inside(fr)) {
        (true, true) => Some((pr - pl) / h),
        (true, false) => Some(-pl / (interface_fraction(fl, fr) * h)),
        (false, true) => Some(pr / (interface_fraction(fr, fl) * h)),
        (false, false) => None,
    }
}

/// The free-surface projection: owns its shifted Poisson solver and work arrays.
pub struct FreeSurfaceProjection {
    solver: PoissonSolver,
    beta_x: Vec<f64>,
    beta_y: Vec<f64>,
    shift: Vec<f64>,
    rhs: Vec<f64>,
    /// The pressure increment δp (the next solve's warm start).
    x: Vec<f64>,
    div: Field,
    /// Known-face flags of the extension (current and next layer), for u and v.
    known_u: [Vec<u8>; 2],
    known_v: [Vec<u8>; 2],
}

impl FreeSurfaceProjection {
    /// Work arrays and solver for `grid` with the pressure conditions implied by `bc`.
    pub fn new(grid: &Grid, bc: &BoundaryConditions, settings: SolverSettings) -> Result<Self> {
        let (nx, ny) = (grid.nx, grid.ny);
        let n = grid.cells();
        Ok(FreeSurfaceProjection {
            solver: PoissonSolver::new_shifted(nx, ny, grid.dx, grid.dy, bc.pressure_all(), settings)?,
            beta_x: vec![0.0; ny * (nx + 1)],
            beta_y: vec![0.0; (ny + 1) * nx],
            shift: vec![1.0; n],
            rhs: vec![0.0; n],
            x: vec![0.0; n],
            div: Field::zeros(grid, crate::Location::Centre),
            known_u: [vec![0; ny * (nx + 1)], vec![0; ny * (nx + 1)]],
            known_v: [vec![0; (ny + 1) * nx], vec![0; (ny + 1) * nx]],
        })
    }

    /// Projects ũ (in `u`, `v`, boundary values set) onto fields that are discretely
    /// divergence-free in every granular cell, with δp = 0 on the surface, adds δp to `p` (set
    /// to 0 in the air) and extends the velocity into the air. `rho` is the granular density
    /// ρ_s, `phi` the level set with ghosts filled, `dt_over_a0` δt/a₀.
    #[allow(clippy::too_many_arguments)]
    pub fn project(
        &mut self, u: &mut Field, v: &mut Field, p: &mut Field, phi: &Field, rho: f64, dt_over_a0: f64, grid: &Grid, bc: &BoundaryConditions, exec: Exec,
    ) -> Result<SolveInfo> {
        let (nx, ny) = (grid.nx, grid.ny);
        let beta = 1.0 / rho;
        let ph = |i: usize, j: usize| phi.at(i as isize, j as isize);
        // faces: β between two granular cells, 0 on faces that touch the air; on a domain side β
        // of the cell beside it (used by the solver on Dirichlet sides only)
        for j in 0..ny {
            for i in 0..=nx {
                let a = i == 0 || inside(ph(i - 1, j));
                let b = i == nx || inside(ph(i, j));
                self.beta_x[j * (nx + 1) + i] = if a && b { beta } else { 0.0 };
            }
        }
        for j in 0..=ny {
            for i in 0..nx {
                let a = j == 0 || inside(ph(i, j - 1));
                let b = j == ny || inside(ph(i, j));
                self.beta_y[j * nx + i] = if a && b { beta } else { 0.0 };
            }
        }
        divergence(u, v, grid, &mut self.div, exec);
        let scale = 1.0 / dt_over_a0;
        let mut any_inside = false;
        for j in 0..ny {
            for i in 0..nx {
                let k = j * nx + i;
                let pc = ph(i, j);
                if !inside(pc) {
                    self.shift[k] = 1.0;
                    self.rhs[k] = 0.0;
                    self.x[k] = 0.0;
                    continue;
                }
                any_inside = true;
                // ghost-fluid Dirichlet δp = 0 where a face crosses the surface
                let sigma: f64 = interface_faces(phi, i, j, grid.dx, grid.dy).into_iter().flatten().map(|(theta, h)| beta / (theta * h * h)).sum();
                self.shift[k] = sigma;
                self.rhs[k] = scale * self.div.at(i as isize, j as isize);
            }
        }
        if !any_inside {
            p.fill(0.0);
            return Ok(SolveInfo::default());
        }
        self.solver.set_coefficients_with_shift(&self.beta_x, &self.beta_y, &self.shift, exec)?;
        let info = self.solver.solve(&self.rhs, &mut self.x, exec)?;
        // δp into `div` (a work field with ghosts); p ← p + δp in the granular phase, 0 in the air
        let dp = &mut self.div;
        for j in 0..ny {
            for i in 0..nx {
                let d = self.x[j * nx + i];
                dp.set(i, j, d);
                let inside_c = inside(ph(i, j));
                p.set(i, j, if inside_c { p.at(i as isize, j as isize) + d } else { 0.0 });
            }
        }
        fill_pressure_ghosts(dp, bc);
        fill_pressure_ghosts(p, bc);
        let dp = &self.div;
        // velocity correction: u ← ũ − (δt/a₀)(1/ρ_s) ∂p, with the ghost value on surface faces
        let k = dt_over_a0 * beta;
        let ru = unknown_face_range(bc.get(Side::Left), bc.get(Side::Right), nx);
        for j in 0..ny as isize {
            for i in ru.clone() {
                let i = i as isize;
                if let Some(g) = surface_gradient(dp.at(i - 1, j), dp.at(i, j), phi.at(i - 1, j), phi.at(i, j), grid.dx) {
                    let val = u.at(i, j) - k * g;
                    u.set(i as usize, j as usize, val);
                }
            }
        }
        let rv = unknown_face_range(bc.get(Side::Bottom), bc.get(Side::Top), ny);
        for j in rv {
            let j = j as isize;
            for i in 0..nx as isize {
                if let Some(g) = surface_gradient(dp.at(i, j - 1), dp.at(i, j), phi.at(i, j - 1), phi.at(i, j), grid.dy) {
                    let val = v.at(i, j) - k * g;
                    v.set(i as usize, j as usize, val);
                }
            }
        }
        self.extend(u, v, phi, grid, bc);
        Ok(info)
    }

    /// Adds ∇p (p with its ghosts filled) to `gx`, `gy` on the interior faces, with p = 0 on the
    /// surface Φ = 0 (ghost values, module header); nothing on faces between two air cells.
    pub fn add_pressure_gradient(p: &Field, phi: &Field, gx: &mut Field, gy: &mut Field, grid: &Grid) {
        let (nx, ny) = (grid.nx as isize, grid.ny as isize);
        for j in 0..ny {
            for i in 0..=nx {
                if let Some(g) = surface_gradient(p.at(i - 1, j), p.at(i, j), phi.at(i - 1, j), phi.at(i, j), grid.dx) {
                    let val = gx.at(i, j) + g;
                    gx.set(i as usize, j as usize, val);
                }
            }
        }
        for j in 0..=ny {
            for i in 0..nx {
                if let Some(g) = surface_gradient(p.at(i, j - 1), p.at(i, j), phi.at(i, j - 1), phi.at(i, j), grid.dy) {
                    let val = gy.at(i, j) + g;
                    gy.set(i as usize, j as usize, val);
                }
            }
        }
    }

    /// The last pressure increment δp (row-major, the next solve's warm start), for checkpoints.
    pub fn increment_mut(&mut self) -> &mut [f64] {
        &mut self.x
    }

    pub fn increment(&self) -> &[f64] {
        &self.x
    }

    /// Extends the velocity from the faces beside a granular cell into the air (module header).
    pub fn extend(&mut self, u: &mut Field, v: &mut Field, phi: &Field, grid: &Grid, bc: &BoundaryConditions) {
        let (nx, ny) = (grid.nx, grid.ny);
        let ru = unknown_face_range(bc.get(Side::Left), bc.get(Side::Right), nx);
        let rv = unknown_face_range(bc.get(Side::Bottom), bc.get(Side::Top), ny);
        // u faces: (nx + 1) × ny, beside cells i − 1 and i
        extend_faces(u, &mut self.known_u, nx + 1, ny, ru, 0..ny, |i, j| {
            (i > 0 && inside(phi.at(i as isize - 1, j as isize))) || (i < nx && inside(phi.at(i as isize, j as isize)))
        });
        extend_faces(v, &mut self.known_v, nx, ny + 1, 0..nx, rv, |i, j| {
            (j > 0 && inside(phi.at(i as isize, j as isize - 1))) || (j < ny && inside(phi.at(i as isize, j as isize)))
        });
    }
}

/// Layered extension on one staggered grid of `mx × my` faces: faces with `fluid(i, j)` are the
/// sources; the unknown faces in `ri × rj` (the others are boundary faces with prescribed
/// values) are filled layer by layer, the rest set to 0.
fn extend_faces(
    f: &mut Field, known: &mut [Vec<u8>; 2], mx: usize, my: usize, ri: std::ops::Range<usize>, rj: std::ops::Range<usize>,
    fluid: impl Fn(usize, usize) -> bool,
) {
    let [cur, next] = known;
    for j in 0..my {
        for i in 0..mx {
            cur[j * mx + i] = fluid(i, j) as u8;
        }
    }
    for _ in 0..EXTENSION_LAYERS {
        next.copy_from_slice(cur);
        let mut grew = false;
        for j in rj.clone() {
            for i in ri.clone() {
                if cur[j * mx + i] != 0 {
                    continue;
                }
                let (mut sum, mut n) = (0.0, 0u32);
                for (di, dj) in [(-1isize, 0isize), (1, 0), (0, -1), (0, 1)] {
                    let (a, b) = (i as isize + di, j as isize + dj);
                    if a < 0 || b < 0 || a >= mx as isize || b >= my as isize {
                        continue;
                    }
                    if cur[b as usize * mx + a as usize] != 0 {
                        sum += f.at(a, b);
                        n += 1;
                    }
                }
                if n > 0 {
                    f.set(i, j, sum / n as f64);
                    next[j * mx + i] = 1;
                    grew = true;
                }
            }
        }
        std::mem::swap(cur, next);
        if !grew {
            break;
        }
    }
    for j in rj {
        for i in ri.clone() {
            if cur[j * mx + i] == 0 {
                f.set(i, j, 0.0);
            }
        }
    }
}

/// max |div u| over the granular cells (Φ > 0): the free-surface projection leaves the extended
/// air velocity divergent, so the whole-domain maximum says nothing there.
pub fn divergence_max_abs_granular(u: &Field, v: &Field, phi: &Field, grid: &Grid) -> f64 {
    let (idx, idy) = (1.0 / grid.dx, 1.0 / grid.dy);
    let mut m = 0.0f64;
    for j in 0..grid.ny as isize {
        for i in 0..grid.nx as isize {
            if inside(phi.at(i, j)) {
                let d = (u.at(i + 1, j) - u.at(i, j)) * idx + (v.at(i, j + 1) - v.at(i, j)) * idy;
                m = if d.is_nan() { f64::NAN } else { m.max(d.abs()) };
            }
        }
    }
    m
}
