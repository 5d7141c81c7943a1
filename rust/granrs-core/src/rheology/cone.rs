//! The cone program of the exact step (`exact.rs`, `interior_point.rs`): its terms and the
//! sparse factorisation its two solvers share. The step of eq. (11) of Aravena et al. minimises
//!
//!   J(u) = ½ uᵀA u − bᵀu + Σ_k w_k |B_k u + β_k|,
//!
//! one term per plastic location (B_k its deviatoric rate, w_k its yield stress share) and per
//! Coulomb wall face (B_k the face's velocity, w_k = τ_b/h): a second-order cone program
//! (Muravleva & Olshanskii 2008, *Russ. J. Numer. Anal. Math. Model.* 23; Bleyer 2018,
//! *Comput. Methods Appl. Mech. Eng.* 330).

use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{SparseColMat, Triplet};
use std::ops::Range;

use crate::error::{Error, Result};
use crate::grid::Side;

/// The symbolic LU of the last Newton matrix with its pattern (column pointers, row indices).
pub(crate) type SymbolicCache = std::sync::Mutex<Option<(Vec<usize>, Vec<usize>, SymbolicLu<usize>)>>;

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

/// The sparse LU of the matrix of `trip` (duplicates summed), reusing the symbolic
/// factorisation of `cache` while the pattern is the same.
pub(crate) fn factor(cache: &SymbolicCache, n: usize, trip: &[Triplet<usize, usize, f64>]) -> Result<Lu<usize, f64>> {
    let fail = |e: String| Error::SolverFailure { solver: "sparse LU of the exact step (faer)".into(), message: e };
    let mat = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, trip).map_err(|e| fail(format!("{e:?}")))?;
    let mut cache = cache.lock().unwrap_or_else(|e| e.into_inner());
    let same = cache.as_ref().is_some_and(|(p, r, _)| p[..] == *mat.symbolic().col_ptr() && r[..] == *mat.symbolic().row_idx());
    if !same {
        let symbolic = SymbolicLu::try_new(mat.symbolic()).map_err(|e| fail(format!("{e:?}")))?;
        *cache = Some((mat.symbolic().col_ptr().to_vec(), mat.symbolic().row_idx().to_vec(), symbolic));
    }
    let symbolic = cache.as_ref().expect("set above").2.clone();
    Lu::try_new_with_symbolic(symbolic, mat.as_ref()).map_err(|e| fail(format!("{e:?}")))
}
