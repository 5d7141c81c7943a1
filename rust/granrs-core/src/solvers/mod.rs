//! Solvers of the variable-coefficient pressure equation of the projection.
//!
//! # Equation
//!
//! ∇·(β ∇p) = f on the rectangle, β = 1/ρ > 0, with on each side either ∂p/∂n = 0 (Neumann) or
//! p = 0 (Dirichlet). Density ratios up to 2500:1 occur (ρ = 1 in air, ≈ 1450 in the granular
//! mixture), so β jumps by three orders of magnitude across the interface.
//!
//! # Discrete form
//!
//! On the MAC grid of nx × ny cells (pressure at cell centres, β^x on vertical faces with shape
//! (ny, nx+1), β^y on horizontal faces with shape (ny+1, nx), all arrays row-major with index
//! j·nx + i):
//!
//! (L p)_ij = [β^x_{i+1,j}(p_{i+1,j} − p_ij) − β^x_{i,j}(p_ij − p_{i−1,j})]/dx²
//!          + [β^y_{i,j+1}(p_{i,j+1} − p_ij) − β^y_{i,j}(p_ij − p_{i,j−1})]/dy²
//!
//! Boundary faces: Neumann → zero flux; Dirichlet → p = 0 on the face (ghost value −p_ij), i.e.
//! the flux β_face (0 − p_ij) · 2/h². The solvers work with A = −L, which is symmetric positive
//! definite, or positive semi-definite with the constants as kernel when every side is Neumann.
//! This is the standard second-order cell-centred finite-volume discretisation.
//!
//! # Methods
//!
//! - [`PressureSolverKind::MultigridCg`] (production): conjugate gradients preconditioned by one
//!   cell-centred geometric multigrid cycle per iteration (MGCG). Coarse levels rediscretise the
//!   operator with arithmetic means of fine face coefficients; piecewise-constant transfers;
//!   red–black Gauss–Seidel smoothing in a symmetric W-cycle (V-cycle as an option); the
//!   coarsest level is solved exactly by sparse Cholesky. The choices are explained, with
//!   measured iteration counts, in the header of `multigrid.rs`. Measured to 1e-8: 5–7
//!   iterations from 128² to 1024² with β = 1; 7 on the 1280 × 256 column-collapse grid with a
//!   1450:1 (or 2500:1) density jump; 7–8 with a diagonal interface or 60 dense droplets.
//!   Point smoothing assumes cells that are not strongly anisotropic (dx ≈ dy, as in the
//!   paper); dx/dy far from 1 would call for line smoothing or semi-coarsening.
//! - [`PressureSolverKind::Direct`] (reference): faer sparse Cholesky of the full fine operator,
//!   symbolic factorisation once in [`PoissonSolver::new`], numeric per
//!   [`PoissonSolver::set_coefficients`]. Cost grows like N^1.5: meant for tests and grids up
//!   to a few 10⁵ cells.
//!
//! Singular case (every side Neumann): f is projected onto zero mean (the removed mean is
//! reported in [`SolveInfo::rhs_mean_removed`]), iterates are kept at zero mean, the coarsest
//! factorisation pins one cell, and the returned p has zero mean.
//!
//! All work arrays are allocated in [`PoissonSolver::new`]; `solve` and `apply` allocate nothing.
//! Sweeps run by fixed blocks of rows on the rayon pool the caller installed (when
//! [`Exec::parallel`] is set); reductions add per-block partial sums in block order, and the
//! red–black smoother updates the cells of one colour independently, so one thread and many
//! threads give bit-identical results.
//!
//! When the fine dimensions are odd (or have few factors of 2), the coarsest level is large and
//! its Cholesky factor dominates time and memory (beyond ≈ 20 000 unknowns it becomes the main
//! cost of `set_coefficients` and of each cycle); choose grid sizes with several factors of 2
//! (1280 × 256 coarsens down to 10 × 2).
//!
//! # References
//!
//! - U. Trottenberg, C. W. Oosterlee, A. Schüller, *Multigrid*, Academic Press, 2001
//!   (cell-centred multigrid, transfers, red–black smoothing; §2.9, §5.7, App. A).
//! - Y. Saad, *Iterative Methods for Sparse Linear Systems*, 2nd ed., SIAM, 2003
//!   (preconditioned CG, Algorithm 9.1).
//! - O. Tatebe, "The multigrid preconditioned conjugate gradient method", *Sixth Copper Mountain
//!   Conference on Multigrid Methods*, NASA CP 3224, 1993, pp. 621–634 (symmetric multigrid cycle as a
//!   CG preconditioner).

mod cg;
mod direct;
mod level;
mod multigrid;
pub(crate) mod par;

use std::fmt;

use crate::error::{check_positive, Error, Result};
use crate::exec::Exec;
use crate::grid::PressureBc;
use crate::options::{self, Configurable, OptionSpec, Value};

use cg::CgWork;
use multigrid::Multigrid;

/// What a solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveInfo {
    /// CG iterations (multigrid cycles) used; 1 for the direct solver; 0 when the initial guess already
    /// satisfied the tolerance or f = 0.
    pub iterations: usize,
    /// Final relative residual ‖f − L p‖₂ / ‖f‖₂ (true residual, recomputed at the end; f after
    /// mean removal in the singular case).
    pub residual: f64,
    /// Relative residual of the initial guess.
    pub initial_residual: f64,
    /// Mean of f removed to make the singular (all-Neumann) problem solvable; 0 otherwise.
    pub rhs_mean_removed: f64,
}

/// Which method solves the pressure equation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PressureSolverKind {
    /// Multigrid-preconditioned conjugate gradients (production path).
    MultigridCg,
    /// Sparse Cholesky factorisation of the whole fine operator (reference).
    Direct,
}

/// Multigrid cycle type used as the preconditioner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cycle {
    /// One coarse-grid correction per level.
    V,
    /// Two coarse-grid corrections per level (the second starts from the first); still a
    /// symmetric preconditioner. About 1.5× the work of a V-cycle in 2D.
    W,
}

/// Parameters of [`PoissonSolver`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverSettings {
    /// Method.
    pub kind: PressureSolverKind,
    /// Relative residual tolerance ‖f − L p‖₂ / ‖f‖₂ (default 1e-8), in [1e-15, 1).
    pub rtol: f64,
    /// Maximum number of CG iterations (default 200), ≥ 1.
    pub max_iterations: usize,
    /// Red–black Gauss–Seidel sweeps before the coarse correction, in [1, 10] (default 2).
    pub pre_smooth: usize,
    /// Black–red Gauss–Seidel sweeps after the coarse correction; must equal `pre_smooth` (a
    /// symmetric cycle is what makes it a valid CG preconditioner).
    pub post_smooth: usize,
    /// Multigrid cycle (default `W`: robust for density jumps at the cost of ≈ 1.5 V-cycles).
    pub cycle: Cycle,
    /// Coarsening stops before a dimension would drop below this (≥ 1; default 2).
    pub min_coarse_size: usize,
}

/// The options of the pressure solve's [`SolverSettings`] (`ModelConfig::pressure_solver`; the
/// pore pressure's solve uses the same settings).
pub const PRESSURE_SOLVER_OPTIONS: &[OptionSpec] = &[
    options::choice(
        "pressure_solver",
        "pressure_solver",
        "multigrid-cg",
        &["multigrid-cg", "direct"],
        "method of the pressure solve: multigrid-preconditioned CG, or the sparse Cholesky reference",
    ),
    options::float("pressure_solver", "pressure_rtol", 1e-8, 1e-15, 1.0, "1", "relative residual ‖f − L p‖₂/‖f‖₂ at which the pressure solve stops")
        .open(false, true),
    options::int(
        "pressure_solver",
        "pressure_max_iterations",
        200,
        1,
        100_000_000,
        "1",
        "iteration cap of the pressure CG (reaching it stops the run with a SolverError)",
    ),
];

impl Default for SolverSettings {
    fn default() -> Self {
        let o = |k| options::spec(PRESSURE_SOLVER_OPTIONS, k);
        SolverSettings {
            kind: PressureSolverKind::from_name(o("pressure_solver").name()).expect("a solver name"),
            rtol: o("pressure_rtol").float(),
            max_iterations: o("pressure_max_iterations").usize(),
            pre_smooth: 2,
            post_smooth: 2,
            cycle: Cycle::W,
            min_coarse_size: 2,
        }
    }
}

impl PressureSolverKind {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            PressureSolverKind::MultigridCg => "multigrid-cg",
            PressureSolverKind::Direct => "direct",
        }
    }

    /// The kind called `name`, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        [PressureSolverKind::MultigridCg, PressureSolverKind::Direct].into_iter().find(|k| k.name() == name)
    }
}

impl Configurable for SolverSettings {
    fn options() -> &'static [OptionSpec] {
        PRESSURE_SOLVER_OPTIONS
    }

    fn get(&self, key: &str) -> Value {
        match key {
            "pressure_solver" => Value::str(self.kind.name()),
            "pressure_rtol" => Value::Float(self.rtol),
            "pressure_max_iterations" => Value::Int(self.max_iterations as i64),
            _ => Value::None,
        }
    }

    fn set(&mut self, key: &str, v: &Value) -> Result<()> {
        match key {
            "pressure_solver" => self.kind = PressureSolverKind::from_name(options::as_name(v)).unwrap_or(self.kind),
            "pressure_rtol" => self.rtol = v.as_f64().unwrap_or(self.rtol),
            "pressure_max_iterations" => self.max_iterations = options::as_usize(v),
            _ => {}
        }
        Ok(())
    }
}

impl SolverSettings {
    /// Checks every parameter; errors name the offending field (`rtol`, `max_iterations`: the
    /// ranges of [`PRESSURE_SOLVER_OPTIONS`]).
    pub fn validate(&self) -> Result<()> {
        let o = |k| options::spec(PRESSURE_SOLVER_OPTIONS, k);
        o("pressure_rtol").check_named("rtol", &Value::Float(self.rtol))?;
        o("pressure_max_iterations").check_named("max_iterations", &Value::Int(self.max_iterations.min(i64::MAX as usize) as i64))?;
        if !(1..=10).contains(&self.pre_smooth) {
            return Err(Error::param("pre_smooth", self.pre_smooth, "an integer in [1, 10]"));
        }
        if self.post_smooth != self.pre_smooth {
            return Err(Error::param(
                "post_smooth",
                self.post_smooth,
                &format!("the value of pre_smooth ({}) (the multigrid cycle must be symmetric)", self.pre_smooth),
            ));
        }
        if self.min_coarse_size == 0 {
            return Err(Error::param("min_coarse_size", self.min_coarse_size, "an integer >= 1"));
        }
        Ok(())
    }
}

/// Solver of L p = f on a fixed grid with fixed boundary conditions; the coefficients β change
/// through [`PoissonSolver::set_coefficients`] (typically every time step).
#[derive(Debug)]
pub struct PoissonSolver {
    nx: usize,
    ny: usize,
    dx: f64,
    dy: f64,
    bc: [PressureBc; 4],
    settings: SolverSettings,
    singular: bool,
    mg: Multigrid,
    work: CgWork,
    ready: bool,
}

impl PoissonSolver {
    /// Builds the solver for `nx × ny` cells of size `dx × dy` with pressure conditions `bc`
    /// (left, right, bottom, top): level hierarchy, work arrays, symbolic factorisation. The
    /// coefficients start at β = 1 everywhere (already factorised).
    pub fn new(nx: usize, ny: usize, dx: f64, dy: f64, bc: [PressureBc; 4], settings: SolverSettings) -> Result<Self> {
        Self::build(nx, ny, dx, dy, bc, settings, false)
    }

    /// A solver for the shifted (Helmholtz-type) operator (L − σ) p = f, σ ≥ 0 per cell, set with
    /// [`PoissonSolver::set_coefficients_with_shift`]; σ must be positive somewhere when every
    /// side is Neumann, so the problem is never singular (implicit diffusion, pore pressure).
    pub fn new_shifted(nx: usize, ny: usize, dx: f64, dy: f64, bc: [PressureBc; 4], settings: SolverSettings) -> Result<Self> {
        Self::build(nx, ny, dx, dy, bc, settings, true)
    }

    /// Shared constructor: a Poisson operator is singular when every side is Neumann; a shifted
    /// one never is (its shift starts at σ = 1).
    fn build(nx: usize, ny: usize, dx: f64, dy: f64, bc: [PressureBc; 4], settings: SolverSettings, shifted: bool) -> Result<Self> {
        if nx == 0 {
            return Err(Error::param("nx", nx, "an integer >= 1"));
        }
        if ny == 0 {
            return Err(Error::param("ny", ny, "an integer >= 1"));
        }
        check_positive("dx", dx)?;
        check_positive("dy", dy)?;
        settings.validate()?;
        let singular = !shifted && bc.iter().all(|&b| b == PressureBc::Neumann);
        let max_levels = match settings.kind {
            PressureSolverKind::MultigridCg => usize::MAX,
            PressureSolverKind::Direct => 1,
        };
        let mut mg = Multigrid::new(nx, ny, dx, dy, bc, &settings, max_levels, singular)?;
        if shifted {
            // a shifted solver starts with σ = 1 so that the initial factorisation is regular
            mg.levels_mut_shift_fill(1.0);
        }
        let ones_x = vec![1.0; ny * (nx + 1)];
        let ones_y = vec![1.0; (ny + 1) * nx];
        mg.set_coefficients(&ones_x, &ones_y, Exec::SERIAL)?;
        Ok(PoissonSolver { nx, ny, dx, dy, bc, settings, singular, mg, work: CgWork::new(nx, ny), ready: true })
    }

    /// Sets β on the faces (β^x shape (ny, nx+1), β^y shape (ny+1, nx), row-major), rebuilds the
    /// coarse levels and refactorises (coarsest level for MGCG, whole operator for Direct).
    /// Every β must be finite and > 0.
    pub fn set_coefficients(&mut self, beta_x: &[f64], beta_y: &[f64], exec: Exec) -> Result<()> {
        let (nx, ny) = (self.nx, self.ny);
        check_len("beta_x", beta_x.len(), &[ny, nx + 1])?;
        check_len("beta_y", beta_y.len(), &[ny + 1, nx])?;
        check_coefficients("beta_x", beta_x, nx + 1, exec)?;
        check_coefficients("beta_y", beta_y, nx, exec)?;
        self.ready = false;
        self.mg.set_coefficients(beta_x, beta_y, exec)?;
        self.ready = true;
        Ok(())
    }

    /// Sets β and the diagonal shift σ (shape (ny, nx), finite, ≥ 0; positive somewhere when
    /// every side is Neumann) of a solver built with [`PoissonSolver::new_shifted`]: solves
    /// (L − σ) p = f afterwards.
    pub fn set_coefficients_with_shift(&mut self, beta_x: &[f64], beta_y: &[f64], shift: &[f64], exec: Exec) -> Result<()> {
        let (nx, ny) = (self.nx, self.ny);
        if self.singular {
            return Err(Error::param("shift", "given", "only for a solver built with PoissonSolver::new_shifted"));
        }
        check_len("beta_x", beta_x.len(), &[ny, nx + 1])?;
        check_len("beta_y", beta_y.len(), &[ny + 1, nx])?;
        check_len("shift", shift.len(), &[ny, nx])?;
        check_non_negative_array("beta_x", beta_x, nx + 1, exec)?;
        check_non_negative_array("beta_y", beta_y, nx, exec)?;
        check_non_negative_array("shift", shift, nx, exec)?;
        if self.bc.iter().all(|&b| b == PressureBc::Neumann) && shift.iter().all(|&s| s == 0.0) {
            return Err(Error::param("shift", "0 everywhere", "positive somewhere when every side is Neumann (else singular)"));
        }
        self.ready = false;
        self.mg.set_coefficients_with_shift(beta_x, beta_y, Some(shift), exec)?;
        self.ready = true;
        Ok(())
    }

    /// Solves L p = f. `p` holds the initial guess on entry (warm start; zeros are fine) and the
    /// solution on exit. Errors: shapes ([`Error::Shape`]), non-finite f or p
    /// ([`Error::InvalidParameter`] naming the array and cell), no convergence within
    /// `max_iterations` ([`Error::NotConverged`], p then holds the last iterate).
    pub fn solve(&mut self, f: &[f64], p: &mut [f64], exec: Exec) -> Result<SolveInfo> {
        let (nx, ny) = (self.nx, self.ny);
        check_len("f", f.len(), &[ny, nx])?;
        check_len("p", p.len(), &[ny, nx])?;
        if !self.ready {
            return Err(Error::SolverFailure {
                solver: self.solver_name().to_string(),
                message: "the last set_coefficients failed; set valid coefficients before solving".to_string(),
            });
        }
        check_finite_array("f", f, nx, exec)?;
        check_finite_array("p", p, nx, exec)?;
        // b = −f (A = −L), projected onto zero mean in the singular case.
        let rhs = &mut self.work.rhs;
        exec.for_each_row(rhs, nx, |j, row| {
            for (v, fv) in row.iter_mut().zip(&f[j * nx..(j + 1) * nx]) {
                *v = -fv;
            }
        });
        let rhs_mean_removed = if self.singular { -cg::remove_mean(exec, rhs, nx, &mut self.work.partials1) } else { 0.0 };
        let bnorm = cg::dot(exec, rhs, rhs, nx, &mut self.work.partials1).sqrt();
        if bnorm == 0.0 {
            p.iter_mut().for_each(|v| *v = 0.0);
            return Ok(SolveInfo { iterations: 0, residual: 0.0, initial_residual: 0.0, rhs_mean_removed });
        }
        let mut info = match self.settings.kind {
            PressureSolverKind::MultigridCg => cg::pcg(&mut self.mg, &mut self.work, p, bnorm, &self.settings, self.singular, exec)?,
            PressureSolverKind::Direct => self.solve_direct(p, bnorm, exec),
        };
        info.rhs_mean_removed = rhs_mean_removed;
        Ok(info)
    }

    /// Direct solve of A p = rhs (exact up to rounding).
    fn solve_direct(&mut self, p: &mut [f64], bnorm: f64, exec: Exec) -> SolveInfo {
        let nx = self.nx;
        let w = &mut self.work;
        self.mg.levels[0].residual(p, &w.rhs, &mut w.r, exec);
        let initial_residual = cg::dot(exec, &w.r, &w.r, nx, &mut w.partials1).sqrt() / bnorm;
        self.mg.precondition(&w.rhs, p, exec);
        if self.singular {
            cg::remove_mean(exec, p, nx, &mut w.partials1);
        }
        self.mg.levels[0].residual(p, &w.rhs, &mut w.r, exec);
        let residual = cg::dot(exec, &w.r, &w.r, nx, &mut w.partials1).sqrt() / bnorm;
        SolveInfo { iterations: 1, residual, initial_residual, rhs_mean_removed: 0.0 }
    }

    /// out = L p (the operator with the current coefficients and boundary conditions).
    ///
    /// # Panics
    /// If `p` or `out` does not have nx·ny elements.
    pub fn apply(&self, p: &[f64], out: &mut [f64], exec: Exec) {
        let n = self.nx * self.ny;
        assert!(p.len() == n && out.len() == n, "PoissonSolver::apply: p and out must have nx*ny = {n} elements");
        let level = &self.mg.levels[0];
        exec.for_each_row(out, self.nx, |j, row| level.stencil_row(j, p, |i, v| row[i] = -v));
    }

    /// Applies the preconditioner once: one multigrid cycle (V or W, per the settings) from a
    /// zero initial guess, z ≈ L⁻¹ r (exact for the direct kind). Exposed for benchmarks and
    /// diagnostics; `solve` is the entry point for users.
    pub fn precondition(&mut self, r: &[f64], z: &mut [f64], exec: Exec) -> Result<()> {
        let (nx, ny) = (self.nx, self.ny);
        check_len("r", r.len(), &[ny, nx])?;
        check_len("z", z.len(), &[ny, nx])?;
        let rhs = &mut self.work.rhs;
        exec.for_each_row(rhs, nx, |j, row| {
            for (v, rv) in row.iter_mut().zip(&r[j * nx..(j + 1) * nx]) {
                *v = -rv;
            }
        });
        self.mg.precondition(&self.work.rhs, z, exec);
        Ok(())
    }

    /// Lets the multigrid cycle skip the isolated cells outside the rows' spans (`true`, the
    /// default: the same iterates, up to the sign of a zero) or not (`false`: every cell; for
    /// benchmarks and tests of that equality).
    pub fn set_cycle_spans(&mut self, on: bool) {
        self.mg.spans_enabled = on;
    }

    /// Whether every side is Neumann (p defined up to a constant; solutions have zero mean).
    pub fn is_singular(&self) -> bool {
        self.singular
    }

    /// Sizes (nx, ny) of the multigrid levels, fine first (one level for the direct kind).
    pub fn level_sizes(&self) -> Vec<(usize, usize)> {
        self.mg.levels.iter().map(|l| (l.nx, l.ny)).collect()
    }

    /// The settings the solver was built with.
    pub fn settings(&self) -> &SolverSettings {
        &self.settings
    }

    fn solver_name(&self) -> &'static str {
        match self.settings.kind {
            PressureSolverKind::MultigridCg => cg::SOLVER,
            PressureSolverKind::Direct => "sparse Cholesky (faer)",
        }
    }
}

impl fmt::Display for PoissonSolver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let bc: Vec<&str> = self.bc.iter().map(|b| if *b == PressureBc::Neumann { "Neumann" } else { "Dirichlet" }).collect();
        writeln!(f, "PoissonSolver ({})", self.solver_name())?;
        writeln!(f, "├── grid: {} × {} cells, dx = {:e}, dy = {:e}", self.nx, self.ny, self.dx, self.dy)?;
        writeln!(f, "├── bc (left, right, bottom, top): {}{}", bc.join(", "), if self.singular { " (singular)" } else { "" })?;
        let levels: Vec<String> = self.mg.levels.iter().map(|l| format!("{}×{}", l.nx, l.ny)).collect();
        writeln!(f, "├── levels: {} (coarsest solved by sparse Cholesky)", levels.join(" → "))?;
        write!(
            f,
            "└── rtol = {:e}, max_iterations = {}, {:?}({}, {})-cycle, piecewise-constant transfers",
            self.settings.rtol, self.settings.max_iterations, self.settings.cycle, self.settings.pre_smooth, self.settings.post_smooth
        )
    }
}

/// Checks that a flattened array of shape `shape` has the right length.
fn check_len(name: &str, len: usize, shape: &[usize]) -> Result<()> {
    if len == shape.iter().product::<usize>() {
        Ok(())
    } else {
        Err(Error::Shape { name: name.to_string(), got: vec![len], expected: shape.to_vec() })
    }
}

/// The lower bound of the values a solver accepts in an array; every value must also be below +∞
/// (NaN fails every bound).
#[derive(Clone, Copy)]
enum Lower {
    /// x > 0
    Positive,
    /// x ≥ 0
    NonNegative,
    /// x > −∞
    Finite,
}

impl Lower {
    #[inline(always)]
    fn admits(self, x: f64) -> bool {
        let above = match self {
            Lower::Positive => x > 0.0,
            Lower::NonNegative => x >= 0.0,
            Lower::Finite => x > f64::NEG_INFINITY,
        };
        above & (x < f64::INFINITY)
    }
}

crate::multiversion! {
    /// Whether every value of `v` satisfies `lower` and is below +∞, from two running values
    /// per lane (vertical arithmetic only, which vectorises; these checks run on every solve):
    /// Σ 0·x, which stays 0 while every x is finite and becomes NaN at the first NaN or ±∞,
    /// and the smallest value, compared with the bound at the end.
    fn all_admitted / all_admitted_base(v: &[f64], lower: Lower) -> bool {
        let (mut zero, mut lo) = ([0.0f64; 4], [f64::INFINITY; 4]);
        let chunks = v.chunks_exact(4);
        let rest = chunks.remainder();
        for c in chunks {
            for k in 0..4 {
                let x = c[k];
                zero[k] += 0.0 * x;
                lo[k] = if x < lo[k] { x } else { lo[k] };
            }
        }
        for &x in rest {
            zero[0] += 0.0 * x;
            lo[0] = if x < lo[0] { x } else { lo[0] };
        }
        let finite = (zero[0] == 0.0) & (zero[1] == 0.0) & (zero[2] == 0.0) & (zero[3] == 0.0);
        let min = lo[0].min(lo[1]).min(lo[2]).min(lo[3]);
        finite && (v.is_empty() || lower.admits(min))
    }
}

/// Whether every value of `v` is finite (the vectorised pass of the solvers' own checks).
pub(crate) fn all_finite(v: &[f64]) -> bool {
    all_admitted(v, Lower::Finite)
}

/// Checks every value of a row-major array with rows of `stride` against `lower` (and +∞); the
/// error names the array, the row and column of the first failure, and `allowed`. A branch-free
/// pass runs first ([`all_admitted`]), the search for the position only on failure. Large
/// arrays are checked by blocks on the threads of `exec`.
fn check_array(name: &str, v: &[f64], stride: usize, lower: Lower, allowed: &str, exec: Exec) -> Result<()> {
    use rayon::prelude::*;
    let all_ok = if exec.use_parallel(v.len()) { v.par_chunks(crate::exec::TASK_CELLS).all(|c| all_admitted(c, lower)) } else { all_admitted(v, lower) };
    if all_ok {
        return Ok(());
    }
    match v.iter().position(|&x| !lower.admits(x)) {
        None => Ok(()),
        Some(k) => Err(Error::param(&format!("{name}[j={}, i={}]", k / stride, k % stride), v[k], allowed)),
    }
}

/// Checks that every coefficient is finite and > 0; the error names the array and the face.
fn check_coefficients(name: &str, beta: &[f64], stride: usize, exec: Exec) -> Result<()> {
    check_array(name, beta, stride, Lower::Positive, "a finite number > 0 (β = 1/ρ on every face)", exec)
}

/// A shifted system (L_β − σ) x = rhs on `nx × ny` cells with its coefficient and work arrays
/// (row-major: β_x on the (nx + 1) × ny x-faces, β_y on the nx × (ny + 1) y-faces, σ, rhs and x
/// per cell). The pore pressure and the free-surface projection fill the arrays and call
/// [`ShiftedSystem::solve`]; `x` holds the warm start on entry and the solution after.
#[derive(Debug)]
pub struct ShiftedSystem {
    solver: PoissonSolver,
    pub beta_x: Vec<f64>,
    pub beta_y: Vec<f64>,
    pub shift: Vec<f64>,
    pub rhs: Vec<f64>,
    pub x: Vec<f64>,
}

impl ShiftedSystem {
    /// The solver ([`PoissonSolver::new_shifted`]) and zeroed arrays.
    pub fn new(nx: usize, ny: usize, dx: f64, dy: f64, bc: [PressureBc; 4], settings: SolverSettings) -> Result<Self> {
        let n = nx * ny;
        Ok(ShiftedSystem {
            solver: PoissonSolver::new_shifted(nx, ny, dx, dy, bc, settings)?,
            beta_x: vec![0.0; ny * (nx + 1)],
            beta_y: vec![0.0; (ny + 1) * nx],
            shift: vec![0.0; n],
            rhs: vec![0.0; n],
            x: vec![0.0; n],
        })
    }

    /// Sets the coefficients from the arrays and solves into `x`.
    pub fn solve(&mut self, exec: Exec) -> Result<SolveInfo> {
        self.solver.set_coefficients_with_shift(&self.beta_x, &self.beta_y, &self.shift, exec)?;
        self.solver.solve(&self.rhs, &mut self.x, exec)
    }
}

/// Checks that every coefficient is finite and ≥ 0 (a shifted operator may decouple cells).
fn check_non_negative_array(name: &str, beta: &[f64], stride: usize, exec: Exec) -> Result<()> {
    check_array(name, beta, stride, Lower::NonNegative, "a finite number >= 0", exec)
}

/// Checks that every value is finite; the error names the array and the cell.
fn check_finite_array(name: &str, v: &[f64], stride: usize, exec: Exec) -> Result<()> {
    check_array(name, v, stride, Lower::Finite, "a finite number", exec)
}

impl PoissonSolver {
    /// The f64 values a solver on nx × ny cells holds ([`PoissonSolver::new`]): per level the
    /// face coefficients β and c, the shift, the diagonal and its inverse, the coarse levels'
    /// solution and right-hand side; the conjugate-gradient vectors; the direct factorisation of
    /// the coarsest level (with [`PressureSolverKind::Direct`] the whole grid), bounded by the
    /// band Cholesky factor n · min(nx, ny) with its row indices (the fill-reducing ordering
    /// keeps below it). For the memory estimate of a model (models/memory.rs).
    pub fn memory_values(nx: usize, ny: usize, s: &SolverSettings) -> u64 {
        let mut sizes = multigrid::level_sizes(nx, ny, s.min_coarse_size);
        if s.kind == PressureSolverKind::Direct {
            sizes.truncate(1);
        }
        let mut total = 0u64;
        for (l, &(lx, ly)) in sizes.iter().enumerate() {
            let n = (lx * ly) as u64;
            let faces = (ly * (lx + 1) + (ly + 1) * lx) as u64;
            total += 2 * faces + 3 * n + lx as u64;
            if l > 0 {
                total += 2 * n;
            }
        }
        let &(cx, cy) = sizes.last().expect("at least the fine level");
        let nc = (cx * cy) as u64;
        total += 2 * nc * cx.min(cy) as u64 + nc;
        total + 5 * (nx * ny) as u64
    }
}

impl ShiftedSystem {
    /// The f64 values [`ShiftedSystem::new`] allocates (its solver, β on faces, shift, rhs, x).
    pub fn memory_values(nx: usize, ny: usize, s: &SolverSettings) -> u64 {
        PoissonSolver::memory_values(nx, ny, s) + (ny * (nx + 1) + (ny + 1) * nx) as u64 + 3 * (nx * ny) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vectorised pass accepts an array exactly when every value satisfies its bound, in both
    /// copies of the kernel, wherever the offending value lies (lanes, remainder) and whatever
    /// the length.
    #[test]
    fn the_checks_accept_exactly_the_admitted_values() {
        let specials = [0.0, -0.0, 1e-300, -1e-300, 5.0, -5.0, f64::INFINITY, f64::NEG_INFINITY, f64::NAN, f64::MAX, f64::MIN_POSITIVE];
        for lower in [Lower::Positive, Lower::NonNegative, Lower::Finite] {
            let definition = |x: f64| match lower {
                Lower::Positive => x.is_finite() && x > 0.0,
                Lower::NonNegative => x.is_finite() && x >= 0.0,
                Lower::Finite => x.is_finite(),
            };
            for len in 1..11 {
                for at in 0..len {
                    for &x in &specials {
                        let mut v = vec![2.5; len];
                        v[at] = x;
                        let want = definition(x);
                        assert_eq!(all_admitted(&v, lower), want, "len {len}, at {at}, x {x}");
                        assert_eq!(all_admitted_base(&v, lower), want, "len {len}, at {at}, x {x}");
                        let err = check_array("a", &v, 3, lower, "allowed", Exec::SERIAL);
                        match err {
                            Ok(()) => assert!(want),
                            Err(e) => {
                                assert!(!want);
                                let msg = e.to_string();
                                assert!(msg.contains(&format!("a[j={}, i={}]", at / 3, at % 3)), "{msg}");
                            }
                        }
                    }
                }
            }
        }
    }
}
