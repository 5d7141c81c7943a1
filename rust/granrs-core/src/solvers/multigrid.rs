//! Cell-centred geometric multigrid cycle, used as the preconditioner of CG.
//!
//! Hierarchy: level 0 is the fine grid; a level is coarsened by 2 in both directions while both
//! of its dimensions are even and the coarse dimensions stay ≥ `SolverSettings::min_coarse_size`
//! (see [`level_sizes`]); 1280 × 256 goes down to 10 × 2. Coarse face coefficients are the
//! arithmetic mean of the two fine faces that make up the coarse face, rediscretised with
//! h_c = 2h (Trottenberg et al. 2001, §5.7; Wesseling's rediscretisation for cell-centred grids).
//! With piecewise-constant transfers this coarse operator is exactly half the Galerkin operator
//! R A P (R = Pᵀ/4), boundary terms included: it has the Galerkin operator's robustness to
//! coefficient jumps (the coupling across a coarse face is proportional to the sum of the fine
//! couplings across it, whatever lies on either side) together with the over-correction by 2
//! that repairs piecewise-constant interpolation for smooth errors.
//!
//! Transfers: piecewise-constant prolongation (a fine cell adds its parent's correction) and
//! restriction R = Pᵀ/4 (the average of the 4 children), so that the cycle is symmetric. The
//! residual is restricted on the fly (never stored on the fine grid).
//!
//! Why piecewise constant: bilinear prolongation (9, 3, 3, 1)/16 with its transpose as restriction
//! was implemented and measured (tests/solvers.rs, 1280 × 256, 1450:1 density jump, top Dirichlet,
//! CG to 1e-8): V(2,2) took 62 iterations (7 with β = 1) and W(1,1) diverged — interpolating a
//! correction across the jump, with a coarse operator that is not its Galerkin operator, makes
//! the preconditioner indefinite. With piecewise-constant transfers: V(2,2) 11 iterations (8 with
//! β = 1), W(2,2) 7 (6), W(3,3) 6 (5); W(2,2), the default, is also the fastest per solve.
//! Scaling the coarse operators by 0.9 or 1.1–1.5 (a different over-correction) gave equal or
//! more iterations: plain rediscretisation is the best of these.
//!
//! Cycle (zero initial guess): ν red–black Gauss–Seidel sweeps (red, then black), residual,
//! restriction, γ cycles on the coarse level (γ = 1: V-cycle, γ = 2: W-cycle; the second starts
//! from the first's result), prolongation, ν black–red sweeps (black, then red). The
//! post-smoother is the adjoint of the pre-smoother and γ repetitions of a symmetric iteration
//! from zero are symmetric, so the cycle is a symmetric positive definite preconditioner
//! (Tatebe 1993). The coarsest level is solved exactly with a sparse Cholesky factorisation
//! ([`DirectSolver`]); in the singular (all-Neumann) case its right-hand side is first projected
//! onto zero mean and its solution is returned with zero mean, which keeps the cycle symmetric.
//!
//! **Spans.** A free surface (the granular-only model's projection) and the pore pressure
//! outside the grains give every cell beyond the grains a trivial row σ x = b with no coupling,
//! and b = 0 there. Each level keeps, per row, the span of columns outside which every cell is
//! such an isolated cell and (on a coarse level) has no child in a span of the finer level
//! ([`Level::set_spans`], at every `set_coefficients`). When b and the initial guess are zero
//! outside the fine spans (checked per solve), the cycle's sweeps, restriction and prolongation
//! and the CG vector updates and dot products work on the spans only and leave zeros outside:
//! the same iterates bit for bit, up to the sign of a zero (each row's dot product is a
//! left-to-right sum, which zeros do not change), with the work of the grains' cells (a fifth
//! of the granular-only column's window at t = 1.5 s on the paper's grid).

use super::direct::DirectSolver;
use super::level::Level;
use super::par;
use super::{Cycle, SolverSettings};
use crate::error::Result;
use crate::exec::Exec;
use crate::grid::PressureBc;

/// Sizes of the levels of the hierarchy for an `nx × ny` fine grid.
pub(crate) fn level_sizes(nx: usize, ny: usize, min_coarse_size: usize) -> Vec<(usize, usize)> {
    let mut sizes = vec![(nx, ny)];
    let (mut cx, mut cy) = (nx, ny);
    while cx % 2 == 0 && cy % 2 == 0 && cx / 2 >= min_coarse_size && cy / 2 >= min_coarse_size {
        cx /= 2;
        cy /= 2;
        sizes.push((cx, cy));
    }
    sizes
}

/// The multigrid hierarchy with its work arrays (allocated once).
#[derive(Debug)]
pub(crate) struct Multigrid {
    /// Levels, fine first.
    pub levels: Vec<Level>,
    /// Corrections of levels 1.. (index 0 unused: the caller provides the fine one).
    xs: Vec<Vec<f64>>,
    /// Right-hand sides of levels 1.. (index 0 unused).
    bs: Vec<Vec<f64>>,
    /// Copy of the coarsest level's right-hand side (shifted to zero mean in the singular case).
    coarse_rhs: Vec<f64>,
    /// Exact solver of the coarsest level.
    coarse: DirectSolver,
    /// Partial sums for the means of the coarsest level.
    partials: Vec<[f64; 1]>,
    singular: bool,
    /// Whether the cycle may work on the levels' spans ([`Multigrid::spans_admit`]); true
    /// unless switched off to measure or test the cycle on whole rows.
    pub spans_enabled: bool,
    pre_smooth: usize,
    post_smooth: usize,
    /// Coarse-grid cycles per level: 1 (V-cycle) or 2 (W-cycle).
    gamma: usize,
}

impl Multigrid {
    /// Builds the hierarchy (unit coefficients until [`Multigrid::set_coefficients`]), the work
    /// arrays and the symbolic factorisation of the coarsest level. With `max_levels == 1` the
    /// "cycle" is an exact solve of the fine level.
    #[allow(clippy::too_many_arguments)]
    pub fn new(nx: usize, ny: usize, dx: f64, dy: f64, bc: [PressureBc; 4], settings: &SolverSettings, max_levels: usize, singular: bool) -> Result<Self> {
        let sizes: Vec<(usize, usize)> = level_sizes(nx, ny, settings.min_coarse_size).into_iter().take(max_levels.max(1)).collect();
        let levels: Vec<Level> = sizes
            .iter()
            .enumerate()
            .map(|(l, &(lx, ly))| {
                let f = (1usize << l) as f64;
                Level::new(lx, ly, dx * f, dy * f, bc)
            })
            .collect();
        let nl = levels.len();
        let xs = levels.iter().enumerate().map(|(l, lv)| vec![0.0; if l == 0 { 0 } else { lv.cells() }]).collect();
        let bs = levels.iter().enumerate().map(|(l, lv)| vec![0.0; if l == 0 { 0 } else { lv.cells() }]).collect();
        let last = &levels[nl - 1];
        let coarse = DirectSolver::new(last.nx, last.ny, singular)?;
        let partials = vec![[0.0]; par::partials_len(last.ny)];
        let coarse_rhs = vec![0.0; last.cells()];
        Ok(Multigrid {
            levels,
            xs,
            bs,
            coarse_rhs,
            coarse,
            partials,
            singular,
            spans_enabled: true,
            pre_smooth: settings.pre_smooth,
            post_smooth: settings.post_smooth,
            gamma: match settings.cycle {
                Cycle::V => 1,
                Cycle::W => 2,
            },
        })
    }

    /// Fills the shift of the fine level (coarse levels follow at the next `set_coefficients`).
    pub fn levels_mut_shift_fill(&mut self, v: f64) {
        self.levels[0].shift.fill(v);
    }

    /// Sets the fine coefficients (already validated), coarsens them down the hierarchy and
    /// refactorises the coarsest level.
    pub fn set_coefficients(&mut self, beta_x: &[f64], beta_y: &[f64], exec: Exec) -> Result<()> {
        self.set_coefficients_with_shift(beta_x, beta_y, None, exec)
    }

    /// Same, with a diagonal shift σ on the fine level (None: keep the current one).
    pub fn set_coefficients_with_shift(&mut self, beta_x: &[f64], beta_y: &[f64], shift: Option<&[f64]>, exec: Exec) -> Result<()> {
        let l0 = &mut self.levels[0];
        if let Some(s) = shift {
            exec.copy(&mut l0.shift, s);
        }
        exec.copy(&mut l0.beta_x, beta_x);
        exec.copy(&mut l0.beta_y, beta_y);
        self.levels[0].update_stencil(exec);
        self.levels[0].set_spans(None, exec);
        for l in 1..self.levels.len() {
            let (fine, coarse) = self.levels.split_at_mut(l);
            coarse[0].coarsen_coefficients(&fine[l - 1], exec);
            coarse[0].update_stencil(exec);
            coarse[0].set_spans(Some(&fine[l - 1]), exec);
        }
        let last = self.levels.len() - 1;
        self.coarse.factorize(&self.levels[last])
    }

    /// Exact solve on the coarsest level: x = A⁻¹ b (zero-mean b and x in the singular case).
    fn coarse_solve(&mut self, b: &mut [f64], x: &mut [f64]) {
        let n = b.len() as f64;
        if self.singular {
            let nx = self.levels[self.levels.len() - 1].nx;
            let ny = b.len() / nx;
            let [s] = Exec::SERIAL.sum_rows_into(ny, b.len(), &mut self.partials, |j| [b[j * nx..(j + 1) * nx].iter().sum()]);
            let m = s / n;
            b.iter_mut().for_each(|v| *v -= m);
            self.coarse.solve(b, x);
            let [s] = Exec::SERIAL.sum_rows_into(ny, x.len(), &mut self.partials, |j| [x[j * nx..(j + 1) * nx].iter().sum()]);
            let m = s / n;
            x.iter_mut().for_each(|v| *v -= m);
        } else {
            self.coarse.solve(b, x);
        }
    }

    /// One multigrid cycle (V or W) from a zero initial guess: x = M b on the fine level.
    ///
    /// Where b is zero outside the fine level's spans (and the problem is not singular), the
    /// cycle works on the spans of every level only ([`Level::set_spans`]) and sets x to zero
    /// outside them: the same values bit for bit, up to the sign of a zero, with the work of
    /// the cells that are not isolated.
    pub fn precondition(&mut self, b: &[f64], x: &mut [f64], exec: Exec) {
        let spans = self.spans_admit(&[b], exec);
        self.precondition_on_spans(b, x, spans, exec);
    }

    /// Whether the cycle may work on the spans for a right-hand side that is zero where each of
    /// `vectors` is (not in the singular case, whose coarse solve shifts every cell).
    pub fn spans_admit(&self, vectors: &[&[f64]], exec: Exec) -> bool {
        self.spans_enabled && !self.singular && self.levels.len() > 1 && vectors.iter().all(|v| self.levels[0].zero_outside_spans(v, exec))
    }

    /// [`Multigrid::precondition`] with the choice of the spans made by the caller (`spans`
    /// only where b is zero outside the fine level's spans: [`Multigrid::spans_admit`]).
    pub fn precondition_on_spans(&mut self, b: &[f64], x: &mut [f64], spans: bool, exec: Exec) {
        self.cycle(0, b, x, true, spans, exec);
    }

    /// One cycle on level `l` for A_l x = b: from x = 0 when `from_zero` (x need not be
    /// initialised), else from the current x; on the levels' spans only when `spans`.
    fn cycle(&mut self, l: usize, b: &[f64], x: &mut [f64], from_zero: bool, spans: bool, exec: Exec) {
        let nl = self.levels.len();
        let exec = self.levels[l].exec_for(exec, spans);
        if spans && from_zero && l + 1 < nl {
            self.levels[l].fill_outside_spans(x, exec);
        }
        if l + 1 == nl {
            // Coarsest level (or the only one): exact solve.
            let mut bc = std::mem::take(&mut self.coarse_rhs);
            bc.copy_from_slice(b);
            self.coarse_solve(&mut bc, x);
            self.coarse_rhs = bc;
            return;
        }
        let level = &self.levels[l];
        for s in 0..self.pre_smooth {
            level.smooth(x, b, 0, from_zero && s == 0, spans, exec);
        }
        let mut bc = std::mem::take(&mut self.bs[l + 1]);
        let mut xc = std::mem::take(&mut self.xs[l + 1]);
        level.restrict_residual(x, b, &mut bc, spans.then_some(&self.levels[l + 1]), exec);
        let gamma = if l + 2 == nl { 1 } else { self.gamma };
        for k in 0..gamma {
            self.cycle(l + 1, &bc, &mut xc, k == 0, spans, exec);
        }
        let level = &self.levels[l];
        prolong_add(self.levels[l + 1].nx, &xc, level, x, spans, exec);
        self.bs[l + 1] = bc;
        self.xs[l + 1] = xc;
        for _ in 0..self.post_smooth {
            level.smooth(x, b, 1, false, spans, exec);
        }
    }
}

/// x_f += P x_c for piecewise-constant P: every fine cell adds its parent's value (only the
/// cells of the fine level's spans when `spans`).
fn prolong_add(ncx: usize, xc: &[f64], fine: &Level, xf: &mut [f64], spans: bool, exec: Exec) {
    exec.for_each_row(xf, fine.nx, |jf, row| {
        let c = &xc[(jf / 2) * ncx..(jf / 2 + 1) * ncx];
        let (lo, hi) = fine.span(jf, spans);
        add_parents(&mut row[lo..hi], c, lo);
    });
}

crate::multiversion! {
    /// out[k] += c[(first + k) / 2]: the fine cells first.. of a row add their parents' values
    /// (the pairs of children of one parent in one loop).
    fn add_parents / add_parents_base(out: &mut [f64], c: &[f64], first: usize) {
        let mut out = out;
        let mut parent = first / 2;
        if first % 2 == 1 && !out.is_empty() {
            out[0] += c[parent];
            out = &mut out[1..];
            parent += 1;
        }
        let pairs = out.len() / 2;
        let cs = &c[parent..parent + pairs];
        for (o, &v) in out.chunks_exact_mut(2).zip(cs) {
            o[0] += v;
            o[1] += v;
        }
        if out.len() % 2 == 1 {
            let last = out.len() - 1;
            out[last] += c[parent + pairs];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_children_add_their_parents_whatever_the_cut_of_the_row() {
        let c: Vec<f64> = (0..20).map(|k| 0.1 + (k as f64).sin()).collect();
        for first in 0..7 {
            for len in 0..(40 - 2 * first).min(13) {
                let base: Vec<f64> = (0..len).map(|k| (0.37 * k as f64).cos()).collect();
                let want: Vec<u64> = base.iter().enumerate().map(|(k, v)| (v + c[(first + k) / 2]).to_bits()).collect();
                for f in [add_parents, add_parents_base] {
                    let mut out = base.clone();
                    f(&mut out, &c, first);
                    assert_eq!(out.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), want, "first {first}, len {len}");
                }
            }
        }
    }
}
