//! The cone program of the exact step (`exact.rs`, `interior_point.rs`): its terms and the
//! sparse factorisation its two solvers share. The step of eq. (11) of Aravena et al. minimises
//!
//!   J(u) = ½ uᵀA u − bᵀu + Σ_k w_k |B_k u + β_k|,
//!
//! one term per plastic location (B_k its deviatoric rate, w_k its yield stress share) and per
//! Coulomb wall face (B_k the face's velocity, w_k = τ_b/h): a second-order cone program
//! (Muravleva & Olshanskii 2008, *Russ. J. Numer. Anal. Math. Model.* 23; Bleyer 2018,
//! *Comput. Methods Appl. Mech. Eng.* 330).

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, Lu, SymbolicLlt, SymbolicLu};
use faer::sparse::{SparseColMat, Triplet};
use std::ops::Range;

use crate::error::{Error, Result};
use crate::grid::Side;

/// The symbolic factorisation of the last matrix with its pattern (column pointers, row
/// indices), reused while the pattern holds.
pub(crate) type SymbolicCache = std::sync::Mutex<Option<(Vec<usize>, Vec<usize>, Symbolic)>>;

/// A symbolic factorisation: Cholesky for a symmetric matrix, LU otherwise.
#[derive(Clone)]
pub(crate) enum Symbolic {
    Llt(SymbolicLlt<usize>),
    Lu(SymbolicLu<usize>),
}

/// A numeric factorisation (`factor`).
pub(crate) enum Factor {
    Llt(Llt<usize, f64>),
    Lu(Box<Lu<usize, f64>>),
}

impl Factor {
    /// x ← M⁻¹x.
    pub(crate) fn solve_in_place(&self, x: &mut [f64]) {
        let n = x.len();
        let rhs = faer::MatMut::from_column_major_slice_mut(x, n, 1);
        match self {
            Factor::Llt(f) => f.solve_in_place(rhs),
            Factor::Lu(f) => f.solve_in_place(rhs),
        }
    }
}

/// out ← A x (serial, the same bits on every thread setting).
pub(crate) fn apply(a: &SparseColMat<usize, f64>, x: &[f64], out: &mut [f64]) {
    let n = x.len();
    faer::sparse::linalg::matmul::sparse_dense_matmul(
        faer::MatMut::from_column_major_slice_mut(out, a.nrows(), 1),
        faer::Accum::Replace,
        a.as_ref(),
        faer::MatRef::from_column_major_slice(x, n, 1),
        1.0,
        faer::Par::Seq,
    );
}

/// Whether `a` is symmetric to 1e-14 of its largest entry (the predictor's operator with walls
/// on every side is, to the last bit; periodic or open sides need not be).
pub(crate) fn is_symmetric(a: &SparseColMat<usize, f64>) -> bool {
    let (cp, ri, v) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let scale = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for j in 0..a.ncols() {
        for e in cp[j]..cp[j + 1] {
            let i = ri[e];
            let mirror = ri[cp[i]..cp[i + 1]].binary_search(&j).map(|p| v[cp[i] + p]).unwrap_or(0.0);
            if (mirror - v[e]).abs() > 1e-14 * scale {
                return false;
            }
        }
    }
    true
}

/// Where a term's multiplier is kept between steps.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Slot {
    Centre(usize, usize),
    Node(usize, usize),
    Wall(Side, usize),
}

/// One term w|B u + β| of J.
#[derive(Clone, Debug)]
pub(crate) struct Term {
    pub(crate) w: f64,
    pub(crate) dim: usize,
    /// The rows of B: `rows[c]` indexes `cols`/`vals`.
    pub(crate) rows: [Range<usize>; 2],
    pub(crate) beta: [f64; 2],
    pub(crate) r: f64,
    pub(crate) sigma: [f64; 2],
    pub(crate) slot: Slot,
}

/// The factorisation of the matrix of `trip` (duplicates summed): sparse Cholesky where
/// `symmetric` (the matrices of both solvers are then symmetric positive definite), sparse LU
/// otherwise or where Cholesky meets a non-positive pivot; the symbolic part of `cache` is
/// reused while the pattern is the same.
pub(crate) fn factor(cache: &SymbolicCache, n: usize, trip: &[Triplet<usize, usize, f64>], symmetric: bool) -> Result<Factor> {
    let fail = |e: String| Error::SolverFailure { solver: "sparse factorisation of the exact step (faer)".into(), message: e };
    let mat = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, trip).map_err(|e| fail(format!("{e:?}")))?;
    let mut cache = cache.lock().unwrap_or_else(|e| e.into_inner());
    let same = cache
        .as_ref()
        .is_some_and(|(p, r, sym)| p[..] == *mat.symbolic().col_ptr() && r[..] == *mat.symbolic().row_idx() && matches!(sym, Symbolic::Llt(_)) == symmetric);
    if !same {
        let sym = if symmetric {
            Symbolic::Llt(SymbolicLlt::try_new(mat.symbolic(), faer::Side::Lower).map_err(|e| fail(format!("{e:?}")))?)
        } else {
            Symbolic::Lu(SymbolicLu::try_new(mat.symbolic()).map_err(|e| fail(format!("{e:?}")))?)
        };
        *cache = Some((mat.symbolic().col_ptr().to_vec(), mat.symbolic().row_idx().to_vec(), sym));
    }
    match cache.as_ref().expect("set above").2.clone() {
        Symbolic::Llt(sym) => match Llt::try_new_with_symbolic(sym, mat.as_ref(), faer::Side::Lower) {
            Ok(f) => Ok(Factor::Llt(f)),
            Err(_) => {
                let sym = SymbolicLu::try_new(mat.symbolic()).map_err(|e| fail(format!("{e:?}")))?;
                Ok(Factor::Lu(Box::new(Lu::try_new_with_symbolic(sym, mat.as_ref()).map_err(|e| fail(format!("{e:?}")))?)))
            }
        },
        Symbolic::Lu(sym) => Ok(Factor::Lu(Box::new(Lu::try_new_with_symbolic(sym, mat.as_ref()).map_err(|e| fail(format!("{e:?}")))?))),
    }
}
