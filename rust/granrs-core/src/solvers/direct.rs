//! Sparse Cholesky factorisation (faer) of the five-point operator A = −L of one level.
//!
//! The matrix pattern (upper triangle, compressed columns) and the symbolic factorisation with
//! an AMD fill-reducing ordering are computed once when the solver is built; every call of
//! [`DirectSolver::factorize`] fills the values from the level's couplings and recomputes the
//! numeric factor L Lᵀ in place (no allocation). [`DirectSolver::solve`] does the two
//! triangular solves in a preallocated workspace.
//!
//! When every side is Neumann, A is singular (constants span its kernel). The first cell is then
//! pinned: its row and column are replaced by those of the identity. For a right-hand side with
//! zero sum this gives one solution of the singular system (the one with p_0 = 0, which the
//! caller shifts to mean zero): the deleted equation of cell 0 is implied by the others because
//! the columns of A sum to zero.
//!
//! Cost: for an n × m grid, nested-dissection-like orderings give O(N^1.5) flops and
//! O(N log N) memory (N = n m); fine for the coarse grids of the multigrid (tens to a few
//! thousand cells) and for reference solutions up to a few 10⁵ cells.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use super::level::Level;
use crate::error::{Error, Result};

const SOLVER: &str = "sparse Cholesky (faer)";

/// Where the value of one stored matrix entry comes from.
#[derive(Clone, Copy, Debug)]
enum Entry {
    /// −cy of the face below cell `k` (coupling with the cell below).
    South(usize),
    /// −cx of the face left of cell `k` (coupling with the cell on the left).
    West(usize),
    /// Diagonal of cell `k`.
    Diag(usize),
    /// 1 on the diagonal of the pinned cell.
    One,
}

/// Factorised operator of one level.
pub(crate) struct DirectSolver {
    n: usize,
    pinned: bool,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    sources: Vec<Entry>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    mem: MemBuffer,
    work: Vec<f64>,
    factorised: bool,
}

impl std::fmt::Debug for DirectSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DirectSolver")
            .field("n", &self.n)
            .field("pinned", &self.pinned)
            .field("nnz", &self.values.len())
            .field("factor_nnz", &self.l_values.len())
            .finish()
    }
}

impl DirectSolver {
    /// Pattern and symbolic factorisation for an `nx × ny` five-point operator; `pinned` pins
    /// cell 0 (singular, all-Neumann case).
    pub fn new(nx: usize, ny: usize, pinned: bool) -> Result<Self> {
        let n = nx * ny;
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::with_capacity(3 * n);
        let mut sources = Vec::with_capacity(3 * n);
        col_ptr.push(0);
        for j in 0..ny {
            for i in 0..nx {
                let k = j * nx + i;
                if pinned && k == 0 {
                    row_idx.push(0);
                    sources.push(Entry::One);
                } else {
                    // Rows in increasing order: south (k − nx), west (k − 1), diagonal.
                    if j > 0 && !(pinned && k - nx == 0) {
                        row_idx.push(k - nx);
                        sources.push(Entry::South(k));
                    }
                    if i > 0 && !(pinned && k - 1 == 0) {
                        row_idx.push(k - 1);
                        sources.push(Entry::West(k));
                    }
                    row_idx.push(k);
                    sources.push(Entry::Diag(k));
                }
                col_ptr.push(row_idx.len());
            }
        }
        let failure = |what: &str, e: &dyn std::fmt::Debug| Error::SolverFailure { solver: SOLVER.to_string(), message: format!("{what}: {e:?}") };
        let symbolic = {
            let a = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
            factorize_symbolic_cholesky(a, Side::Upper, SymmetricOrdering::Amd, CholeskySymbolicParams::default())
                .map_err(|e| failure("symbolic factorisation", &e))?
        };
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        let mem = MemBuffer::try_new(req).map_err(|e| failure("workspace allocation", &e))?;
        let l_values = vec![0.0; symbolic.len_val()];
        let values = vec![0.0; row_idx.len()];
        Ok(DirectSolver { n, pinned, col_ptr, row_idx, sources, values, symbolic, l_values, mem, work: vec![0.0; n], factorised: false })
    }

    /// Numeric factorisation of the operator of `level` (same size as at construction).
    pub fn factorize(&mut self, level: &Level) -> Result<()> {
        debug_assert_eq!(level.cells(), self.n);
        let nx = level.nx;
        for (v, s) in self.values.iter_mut().zip(&self.sources) {
            *v = match *s {
                Entry::South(k) => -level.cy[k],
                Entry::West(k) => -level.cx[(k / nx) * (nx + 1) + k % nx],
                Entry::Diag(k) => level.diag[k],
                Entry::One => 1.0,
            };
        }
        self.factorised = false;
        let a = SparseColMatRef::new(SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx), &self.values);
        self.symbolic
            .factorize_numeric_llt(&mut self.l_values, a, Side::Upper, LltRegularization::default(), Par::Seq, MemStack::new(&mut self.mem), Default::default())
            .map_err(|e| Error::SolverFailure {
                solver: SOLVER.to_string(),
                message: format!("numeric factorisation failed ({e:?}): the operator is not positive definite"),
            })?;
        self.factorised = true;
        Ok(())
    }

    /// x = A⁻¹ b (with cell 0 pinned to 0 in the singular case; the caller makes b sum to zero
    /// and shifts x). Requires a successful [`DirectSolver::factorize`].
    pub fn solve(&mut self, b: &[f64], x: &mut [f64]) {
        assert!(self.factorised, "DirectSolver::solve before a successful factorize");
        self.work.copy_from_slice(b);
        if self.pinned {
            self.work[0] = 0.0;
        }
        let llt = LltRef::<'_, usize, f64>::new(&self.symbolic, &self.l_values);
        llt.solve_in_place_with_conj(Conj::No, MatMut::from_column_major_slice_mut(&mut self.work, self.n, 1), Par::Seq, MemStack::new(&mut self.mem));
        x.copy_from_slice(&self.work);
    }
}
