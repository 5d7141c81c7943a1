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
    /// Per row of faces, the span of its source faces (the extension's layers visit these
    /// spans widened by the layer's depth), for u and v.
    spans_u: Vec<(usize, usize)>,
    spans_v: Vec<(usize, usize)>,
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
            spans_u: vec![(0, 0); ny],
            spans_v: vec![(0, 0); ny + 1],
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
        extend_faces(u, &mut self.known_u, &mut self.spans_u, nx + 1, ny, ru, 0..ny, exec, |i, j| {
            (i > 0 && inside(ps[c(i - 1, j)])) || (i < nx && inside(ps[c(i, j)]))
        });
        extend_faces(v, &mut self.known_v, &mut self.spans_v, nx, ny + 1, 0..nx, rv, exec, |i, j| {
            (j > 0 && inside(ps[c(i, j - 1)])) || (j < ny && inside(ps[c(i, j)]))
        });
    }
}

/// Layered extension on one staggered grid of `mx × my` faces: faces with `fluid(i, j)` are the
/// sources; the unknown faces in `ri × rj` (the others are boundary faces with prescribed
/// values) are filled layer by layer, the rest set to 0. Each layer is row-parallel under
/// `exec`: a row writes only its own unknown faces and reads only faces known when the layer
/// starts, which no row writes during the layer. A face that layer L fills has a known
/// neighbour, so it lies within L faces (|Δi| + |Δj| ≤ L) of a source face: layer L visits, in
/// row j, the hull of the source spans of rows j − L ..= j + L widened by L on each side
/// (`spans`, one per row, filled here); the faces it skips have no known neighbour.
#[allow(clippy::too_many_arguments)]
fn extend_faces(
    f: &mut Field,
    known: &mut [Vec<u8>; 2],
    spans: &mut [(usize, usize)],
    mx: usize,
    my: usize,
    ri: std::ops::Range<usize>,
    rj: std::ops::Range<usize>,
    exec: Exec,
    fluid: impl Fn(usize, usize) -> bool + Sync,
) {
    let [cur, next] = known;
    let parallel = exec.use_parallel(mx * my);
    // the source faces, and each row's span of them ((mx, 0) for none)
    let mark = |j: usize, row: &mut [u8], span: &mut (usize, usize)| {
        let (mut lo, mut hi) = (mx, 0);
        for (i, k) in row.iter_mut().enumerate() {
            let s = fluid(i, j);
            *k = s as u8;
            if s {
                lo = lo.min(i);
                hi = i + 1;
            }
        }
        *span = (lo, hi);
    };
    if parallel {
        cur.par_chunks_mut(mx).zip(spans.par_iter_mut()).enumerate().for_each(|(j, (row, span))| mark(j, row, span));
    } else {
        cur.chunks_mut(mx).zip(spans.iter_mut()).enumerate().for_each(|(j, (row, span))| mark(j, row, span));
    }
    let spans: &[(usize, usize)] = spans;
    let st = f.stride();
    let fs = SharedMut(f.slice_mut().as_mut_ptr());
    let at = move |i: usize, j: usize| (j + HALO) * st + i + HALO;
    for layer in 1..=EXTENSION_LAYERS {
        next.copy_from_slice(cur);
        let known_now: &[u8] = cur;
        // one row of the layer: new values of its unknown faces; whether any face was filled
        let layer_row = |j: usize, next_row: &mut [u8]| -> bool {
            if !rj.contains(&j) {
                return false;
            }
            // the faces within `layer` of a source face (the doc comment above)
            let rows = &spans[j.saturating_sub(layer)..(j + layer + 1).min(my)];
            let (lo, hi) = rows.iter().fold((mx, 0), |(a, b), &(l, h)| if l < h { (a.min(l), b.max(h)) } else { (a, b) });
            if lo >= hi {
                return false;
            }
            let visit = lo.saturating_sub(layer).max(ri.start)..(hi + layer).min(ri.end);
            let mut grew = false;
            for i in visit {
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
    // the unknown faces the layers did not reach: 0 (rows in parallel, each writes its own)
    let known_now: &[u8] = cur;
    exec.for_each_row(f.slice_mut(), st, |r, row| {
        let Some(j) = r.checked_sub(HALO).filter(|j| rj.contains(j)) else {
            return;
        };
        for i in ri.clone() {
            if known_now[j * mx + i] == 0 {
                row[HALO + i] = 0.0;
            }
        }
    });
}

/// max |div u| over the granular cells (Φ > 0), NaN when one is NaN (0 without granular cells):
/// the free-surface projection leaves the extended air velocity divergent, so the whole-domain
/// maximum says nothing there. Rows on the threads of `exec` (a maximum: the same value).
pub fn divergence_max_abs_granular(u: &Field, v: &Field, phi: &Field, grid: &Grid, exec: Exec) -> f64 {
    let (idx, idy) = (1.0 / grid.dx, 1.0 / grid.dy);
    let (us, vs, ps) = (u.slice(), v.slice(), phi.slice());
    let (su, sv, sp) = (u.stride(), v.stride(), phi.stride());
    let m = exec.max_rows(grid.ny, grid.cells(), |j| {
        let (bu, bv0, bv1, bp) = ((j + HALO) * su + HALO, (j + HALO) * sv + HALO, (j + 1 + HALO) * sv + HALO, (j + HALO) * sp + HALO);
        let mut m = 0.0f64;
        for i in 0..grid.nx {
            if inside(ps[bp + i]) {
                let d = (us[bu + i + 1] - us[bu + i]) * idx + (vs[bv1 + i] - vs[bv0 + i]) * idy;
                m = if d.is_nan() || m.is_nan() { f64::NAN } else { m.max(d.abs()) };
            }
        }
        m
    });
    if m.is_nan() {
        m
    } else {
        m.max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Grid, Location};

    /// The layered extension visiting every face of `ri × rj` in each layer, one thread.
    fn extend_every_face(f: &mut Field, mx: usize, my: usize, ri: std::ops::Range<usize>, rj: std::ops::Range<usize>, fluid: impl Fn(usize, usize) -> bool) {
        let mut known: Vec<u8> = (0..mx * my).map(|k| fluid(k % mx, k / mx) as u8).collect();
        for _ in 0..EXTENSION_LAYERS {
            let now = known.clone();
            let mut grew = false;
            for j in rj.clone() {
                for i in ri.clone() {
                    let k = j * mx + i;
                    if now[k] != 0 {
                        continue;
                    }
                    let (mut sum, mut n) = (0.0, 0u32);
                    for (ok, (a, b)) in [(i > 0, (i.wrapping_sub(1), j)), (i + 1 < mx, (i + 1, j)), (j > 0, (i, j.wrapping_sub(1))), (j + 1 < my, (i, j + 1))] {
                        if ok && now[b * mx + a] != 0 {
                            sum += f.at(a as isize, b as isize);
                            n += 1;
                        }
                    }
                    if n > 0 {
                        f.set(i, j, sum / n as f64);
                        known[k] = 1;
                        grew = true;
                    }
                }
            }
            if !grew {
                break;
            }
        }
        for j in rj {
            for i in ri.clone() {
                if known[j * mx + i] == 0 {
                    f.set(i, j, 0.0);
                }
            }
        }
    }

    /// The extension that visits, in layer L, the source spans of the rows within L widened by
    /// L gives the values of the one that visits every face, bit for bit, serially and on two
    /// threads: on a wedge with a thin tail, an island and a hole (rows with several source
    /// runs, rows without any), with boundary faces left out of the unknowns; and it does fill
    /// faces and zero others.
    #[test]
    fn the_extension_on_the_sources_spans_is_the_extension_on_every_face() {
        // 121 × 60 faces: above the size from which sweeps run in parallel
        let grid = Grid::new(120, 60, 1.5, 0.75).unwrap();
        let (mx, my) = (121, 60);
        let fluid = |i: usize, j: usize| {
            let (x, y) = (i as f64 / 120.0, j as f64 / 60.0);
            let wedge = y < 0.5 - 0.45 * x;
            let hole = (x - 0.2).powi(2) + (y - 0.2).powi(2) < 0.004;
            let island = (x - 0.8).powi(2) + (y - 0.7).powi(2) < 0.003;
            (wedge && !hole) || island
        };
        let mut rnd = crate::operators::random_rows(11);
        let mut start = Field::zeros(&grid, Location::XFace);
        for j in 0..my {
            for (i, v) in rnd(mx).into_iter().enumerate() {
                start.set(i, j, v);
            }
        }
        let (ri, rj) = (1..mx - 1, 0..my);
        let mut want = start.clone();
        extend_every_face(&mut want, mx, my, ri.clone(), rj.clone(), fluid);
        let (mut filled, mut zeroed) = (0, 0);
        for j in 0..my {
            for i in 0..mx {
                filled += (!fluid(i, j) && want.at(i as isize, j as isize) != 0.0 && ri.contains(&i)) as usize;
                zeroed += (want.at(i as isize, j as isize) == 0.0) as usize;
            }
        }
        assert!(filled > 400 && zeroed > 400, "filled {filled}, zeroed {zeroed}");
        for threads in [1, 2] {
            let pool = crate::exec::build_pool(threads).unwrap();
            let mut got = start.clone();
            let (mut known, mut spans) = ([vec![0u8; mx * my], vec![0u8; mx * my]], vec![(0, 0); my]);
            pool.install(|| extend_faces(&mut got, &mut known, &mut spans, mx, my, ri.clone(), rj.clone(), Exec::with_threads(threads), fluid));
            for j in 0..my as isize {
                for i in 0..mx as isize {
                    assert_eq!(got.at(i, j).to_bits(), want.at(i, j).to_bits(), "{threads} threads, face ({i}, {j})");
                }
            }
        }
    }
}
