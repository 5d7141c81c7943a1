//! Free-surface projection of the granular-only model (the air is not resolved; the
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
//! coefficient, right-hand-side and correction loops are row-parallel and elementwise, so is
//! each layer of the extension (a face's new value is the mean of faces known when the layer
//! starts, summed in a fixed order), and the solve is the project's deterministic MGCG, so one
//! thread and many give bit-identical results.

use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, Side, HALO};
use crate::levelset::{interface_diagonal, interface_fraction};
use crate::operators::{divergence, for_each_interior_row, unknown_face_range};
use crate::projection::{fill_increment_ghosts, fill_pressure_ghosts};
use crate::solvers::{par::SharedMut, ShiftedSystem, SolveInfo, SolverSettings};
use rayon::prelude::*;

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
    /// The shifted system; its solution `x` is the pressure increment δp (the next solve's
    /// warm start).
    sys: ShiftedSystem,
    div: Field,
    /// Known-face flags of the extension (current and next layer), for u and v.
    known_u: [Vec<u8>; 2],
    known_v: [Vec<u8>; 2],
}

impl FreeSurfaceProjection {
    /// Work arrays and solver for `grid` with the pressure conditions implied by `bc`.
    pub fn new(grid: &Grid, bc: &BoundaryConditions, settings: SolverSettings) -> Result<Self> {
        let (nx, ny) = (grid.nx, grid.ny);
        Ok(FreeSurfaceProjection {
            sys: ShiftedSystem::new(nx, ny, grid.dx, grid.dy, bc.pressure_all(), settings)?,
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
        &mut self,
        u: &mut Field,
        v: &mut Field,
        p: &mut Field,
        phi: &Field,
        rho: f64,
        dt_over_a0: f64,
        grid: &Grid,
        bc: &BoundaryConditions,
        exec: Exec,
    ) -> Result<SolveInfo> {
        let (nx, ny) = (grid.nx, grid.ny);
        let beta = 1.0 / rho;
        // row by row on the raw slices (elementwise: serial == parallel)
        let (ps, sp) = (phi.slice(), phi.stride());
        let c = |i: usize, j: usize| (j + HALO) * sp + i + HALO;
        // faces: β between two granular cells, 0 on faces that touch the air; on a domain side β
        // of the cell beside it (used by the solver on Dirichlet sides only)
        exec.for_each_row(&mut self.sys.beta_x, nx + 1, |j, row| {
            for i in 0..=nx {
                let a = i == 0 || inside(ps[c(i - 1, j)]);
                let b = i == nx || inside(ps[c(i, j)]);
                row[i] = if a && b { beta } else { 0.0 };
            }
        });
        exec.for_each_row(&mut self.sys.beta_y, nx, |j, row| {
            for i in 0..nx {
                let a = j == 0 || inside(ps[c(i, j - 1)]);
                let b = j == ny || inside(ps[c(i, j)]);
                row[i] = if a && b { beta } else { 0.0 };
            }
        });
        divergence(u, v, grid, &mut self.div, exec);
        let scale = 1.0 / dt_over_a0;
        let any_inside = (0..ny).any(|j| (0..nx).any(|i| inside(ps[c(i, j)])));
        if !any_inside {
            p.fill(0.0);
            return Ok(SolveInfo::default());
        }
        let (dx, dy) = (grid.dx, grid.dy);
        exec.for_each_row(&mut self.sys.shift, nx, |j, row| {
            for i in 0..nx {
                // ghost-fluid Dirichlet δp = 0 where a face crosses the surface; 1 in the air
                row[i] = if inside(ps[c(i, j)]) { interface_diagonal(phi, i, j, dx, dy, beta, 0.0) } else { 1.0 };
            }
        });
        let ds = self.div.slice();
        exec.for_each_row(&mut self.sys.rhs, nx, |j, row| {
            for i in 0..nx {
                row[i] = if inside(ps[c(i, j)]) { scale * ds[c(i, j)] } else { 0.0 };
            }
        });
        exec.for_each_row(&mut self.sys.x, nx, |j, row| {
            for i in 0..nx {
                if !inside(ps[c(i, j)]) {
                    row[i] = 0.0;
                }
            }
        });
        let info = self.sys.solve(exec)?;
        // δp into `div` (a work field with ghosts); p ← p + δp in the granular phase, 0 in the air
        let xs = &self.sys.x;
        crate::operators::for_each_interior_row2(exec, &mut self.div, p, |j, drow, prow| {
            if j >= ny {
                return;
            }
            for i in 0..nx {
                let d = xs[j * nx + i];
                drow[HALO + i] = d;
                prow[HALO + i] = if inside(ps[c(i, j)]) { prow[HALO + i] + d } else { 0.0 };
            }
        });
        let dp = &mut self.div;
        fill_increment_ghosts(dp, bc);
        fill_pressure_ghosts(p, bc);
        let dps = self.div.slice();
        // velocity correction: u ← ũ − (δt/a₀)(1/ρ_s) ∂p, with the ghost value on surface faces
        let k = dt_over_a0 * beta;
        let ru = unknown_face_range(bc.get(Side::Left), bc.get(Side::Right), nx);
        for_each_interior_row(exec, u, |j, row| {
            for i in ru.clone() {
                if let Some(g) = surface_gradient(dps[c(i, j) - 1], dps[c(i, j)], ps[c(i, j) - 1], ps[c(i, j)], dx) {
                    row[HALO + i] -= k * g;
                }
            }
        });
        let rv = unknown_face_range(bc.get(Side::Bottom), bc.get(Side::Top), ny);
        for_each_interior_row(exec, v, |j, row| {
            if !rv.contains(&j) {
                return;
            }
            for i in 0..nx {
                if let Some(g) = surface_gradient(dps[c(i, j) - sp], dps[c(i, j)], ps[c(i, j) - sp], ps[c(i, j)], dy) {
                    row[HALO + i] -= k * g;
                }
            }
        });
        self.extend(u, v, phi, grid, bc, exec);
        Ok(info)
    }

    /// Adds ∇p (p with its ghosts filled) to `gx`, `gy` on the interior faces, with p = 0 on the
    /// surface Φ = 0 (ghost values, module header); nothing on faces between two air cells.
    pub fn add_pressure_gradient(p: &Field, phi: &Field, gx: &mut Field, gy: &mut Field, grid: &Grid, exec: Exec) {
        let (nx, ny) = (grid.nx, grid.ny);
        let (pp, ps, sp) = (p.slice(), phi.slice(), phi.stride());
        debug_assert!(p.stride() == sp);
        let c = |i: usize, j: usize| (j + HALO) * sp + i + HALO;
        for_each_interior_row(exec, gx, |j, row| {
            if j >= ny {
                return;
            }
            for i in 0..=nx {
                if let Some(g) = surface_gradient(pp[c(i, j) - 1], pp[c(i, j)], ps[c(i, j) - 1], ps[c(i, j)], grid.dx) {
                    row[HALO + i] += g;
                }
            }
        });
        for_each_interior_row(exec, gy, |j, row| {
            if j > ny {
                return;
            }
            for i in 0..nx {
                if let Some(g) = surface_gradient(pp[c(i, j) - sp], pp[c(i, j)], ps[c(i, j) - sp], ps[c(i, j)], grid.dy) {
                    row[HALO + i] += g;
                }
            }
        });
    }

    /// The last pressure increment δp (row-major, the next solve's warm start), for checkpoints.
    pub fn increment_mut(&mut self) -> &mut [f64] {
        &mut self.sys.x
    }

    pub fn increment(&self) -> &[f64] {
        &self.sys.x
    }

    /// Extends the velocity from the faces beside a granular cell into the air (module header).
    pub fn extend(&mut self, u: &mut Field, v: &mut Field, phi: &Field, grid: &Grid, bc: &BoundaryConditions, exec: Exec) {
        let (nx, ny) = (grid.nx, grid.ny);
        let ru = unknown_face_range(bc.get(Side::Left), bc.get(Side::Right), nx);
        let rv = unknown_face_range(bc.get(Side::Bottom), bc.get(Side::Top), ny);
        let (ps, sp) = (phi.slice(), phi.stride());
        let c = |i: usize, j: usize| (j + HALO) * sp + i + HALO;
        // u faces: (nx + 1) × ny, beside cells i − 1 and i
        extend_faces(u, &mut self.known_u, nx + 1, ny, ru, 0..ny, exec, |i, j| (i > 0 && inside(ps[c(i - 1, j)])) || (i < nx && inside(ps[c(i, j)])));
        extend_faces(v, &mut self.known_v, nx, ny + 1, 0..nx, rv, exec, |i, j| (j > 0 && inside(ps[c(i, j - 1)])) || (j < ny && inside(ps[c(i, j)])));
    }
}

/// Layered extension on one staggered grid of `mx × my` faces: faces with `fluid(i, j)` are the
/// sources; the unknown faces in `ri × rj` (the others are boundary faces with prescribed
/// values) are filled layer by layer, the rest set to 0. Each layer is row-parallel under
/// `exec`: a row writes only its own unknown faces and reads only faces known when the layer
/// starts, which no row writes during the layer.
#[allow(clippy::too_many_arguments)]
fn extend_faces(
    f: &mut Field,
    known: &mut [Vec<u8>; 2],
    mx: usize,
    my: usize,
    ri: std::ops::Range<usize>,
    rj: std::ops::Range<usize>,
    exec: Exec,
    fluid: impl Fn(usize, usize) -> bool + Sync,
) {
    let [cur, next] = known;
    let parallel = exec.use_parallel(mx * my);
    let mark = |j: usize, row: &mut [u8]| {
        for (i, k) in row.iter_mut().enumerate() {
            *k = fluid(i, j) as u8;
        }
    };
    if parallel {
        cur.par_chunks_mut(mx).enumerate().for_each(|(j, row)| mark(j, row));
    } else {
        cur.chunks_mut(mx).enumerate().for_each(|(j, row)| mark(j, row));
    }
    let st = f.stride();
    let fs = SharedMut(f.slice_mut().as_mut_ptr());
    let at = move |i: usize, j: usize| (j + HALO) * st + i + HALO;
    for _ in 0..EXTENSION_LAYERS {
        next.copy_from_slice(cur);
        let known_now: &[u8] = cur;
        // one row of the layer: new values of its unknown faces; whether any face was filled
        let layer_row = |j: usize, next_row: &mut [u8]| -> bool {
            if !rj.contains(&j) {
                return false;
            }
            let mut grew = false;
            for i in ri.clone() {
                let k = j * mx + i;
                if known_now[k] != 0 {
                    continue;
                }
                // SAFETY: `at` indexes inside the field's buffer (HALO ≥ 1 surrounds the
                // mx × my faces). Reads are of faces known at the layer's start, which no row
                // writes in this layer; the write is to face (i, j), unknown at the start, which
                // only this row touches.
                unsafe {
                    let base = fs.get();
                    // neighbours in the order left, right, below, above (the sum's order)
                    let (mut sum, mut n) = (0.0, 0u32);
                    if i > 0 && known_now[k - 1] != 0 {
                        sum += *base.add(at(i - 1, j));
                        n += 1;
                    }
                    if i + 1 < mx && known_now[k + 1] != 0 {
                        sum += *base.add(at(i + 1, j));
                        n += 1;
                    }
                    if j > 0 && known_now[k - mx] != 0 {
                        sum += *base.add(at(i, j - 1));
                        n += 1;
                    }
                    if j + 1 < my && known_now[k + mx] != 0 {
                        sum += *base.add(at(i, j + 1));
                        n += 1;
                    }
                    if n > 0 {
                        *base.add(at(i, j)) = sum / n as f64;
                        next_row[i] = 1;
                        grew = true;
                    }
                }
            }
            grew
        };
        let grew = if parallel {
            next.par_chunks_mut(mx).enumerate().map(|(j, row)| layer_row(j, row)).reduce(|| false, |a, b| a || b)
        } else {
            // `|`, not `||`: every row is visited (the rows write)
            next.chunks_mut(mx).enumerate().map(|(j, row)| layer_row(j, row)).fold(false, |a, b| a | b)
        };
        std::mem::swap(cur, next);
        if !grew {
            break;
        }
    }
    let fs = f.slice_mut();
    for j in rj {
        let row = &mut fs[at(0, j)..at(0, j) + mx];
        for i in ri.clone() {
            if cur[j * mx + i] == 0 {
                row[i] = 0.0;
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
