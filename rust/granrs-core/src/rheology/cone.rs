//! The cone program of the exact step (`exact.rs`, `interior_point.rs`): its terms and the
//! sparse factorisation its two solvers share. The step of eq. (11) of Aravena et al. minimises
//!
//!   J(u) = ½ uᵀA u − bᵀu + Σ_k w_k |B_k u + β_k|,
//!
//! one term per plastic location (B_k its deviatoric rate, w_k its yield stress share) and per
//! Coulomb wall face (B_k the face's velocity, w_k = τ_b/h): a second-order cone program
//! (Muravleva & Olshanskii 2008, *Russ. J. Numer. Anal. Math. Model.* 23; Bleyer 2018,
//! *Comput. Methods Appl. Mech. Eng.* 330).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, Triplet};
use faer::{Conj, Par};
use std::ops::Range;
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::grid::Side;

/// The symbolic factorisation of the last matrix with its pattern (column pointers, row
/// indices), reused while the pattern holds.
pub(crate) type SymbolicCache = std::sync::Mutex<Option<(Vec<usize>, Vec<usize>, Symbolic)>>;

/// A symbolic factorisation: supernodal Cholesky for a symmetric matrix, LU otherwise.
#[derive(Clone)]
pub(crate) enum Symbolic {
    Llt(Arc<SymbolicCholesky<usize>>),
    Lu(SymbolicLu<usize>),
}

/// A numeric factorisation (`factor`): the Cholesky factor's values beside its symbolic part.
pub(crate) enum Factor {
    Llt(Arc<SymbolicCholesky<usize>>, Vec<f64>),
    Lu(Box<Lu<usize, f64>>),
}

impl Factor {
    /// x ← M⁻¹x (serial: the same bits on every thread setting).
    pub(crate) fn solve_in_place(&self, x: &mut [f64]) {
        let n = x.len();
        let rhs = faer::MatMut::from_column_major_slice_mut(x, n, 1);
        match self {
            Factor::Llt(sym, values) => {
                let mut buf = MemBuffer::new(sym.solve_in_place_scratch::<f64>(1, Par::Seq));
                LltRef::new(sym, values).solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut buf));
            }
            Factor::Lu(f) => f.solve_in_place(rhs),
        }
    }
}

/// The symbolic Cholesky factorisation of `mat`'s lower triangle: AMD ordering, supernodal (the
/// Newton and interior-point matrices couple faces two cells apart and fill in enough for the
/// dense blocks of the supernodal factorisation to pay on every grid of the column).
fn symbolic_llt(mat: faer::sparse::SymbolicSparseColMatRef<'_, usize>) -> std::result::Result<SymbolicCholesky<usize>, faer::sparse::FaerError> {
    let params = CholeskySymbolicParams { supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL, ..Default::default() };
    factorize_symbolic_cholesky(mat, faer::Side::Lower, SymmetricOrdering::Amd, params)
}

/// The numeric Cholesky factor of `mat` with the symbolic part `sym`, serial.
fn numeric_llt(sym: &Arc<SymbolicCholesky<usize>>, mat: faer::sparse::SparseColMatRef<'_, usize, f64>) -> Option<Factor> {
    let mut values = vec![0.0; sym.len_val()];
    let mut buf = MemBuffer::new(sym.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()));
    sym.factorize_numeric_llt(&mut values, mat, faer::Side::Lower, Default::default(), Par::Seq, MemStack::new(&mut buf), Default::default()).ok()?;
    Some(Factor::Llt(sym.clone(), values))
}

/// The n × n compressed matrix of `trips` (duplicates summed in their order): a counting sort by
/// column, then a stable sort of each column's few rows, in O(nnz) for a stencil's matrix.
pub(crate) fn compress(n: usize, trips: &[Triplet<usize, usize, f64>]) -> Result<SparseColMat<usize, f64>> {
    let mut ptr = vec![0usize; n + 1];
    for t in trips {
        if t.row >= n || t.col >= n {
            return Err(Error::SolverFailure {
                solver: "sparse matrix of the exact step".into(),
                message: format!("entry ({}, {}) outside {n} × {n}", t.row, t.col),
            });
        }
        ptr[t.col + 1] += 1;
    }
    for j in 0..n {
        ptr[j + 1] += ptr[j];
    }
    let mut next = ptr.clone();
    let mut bucket = vec![(0usize, 0.0f64); trips.len()];
    for t in trips {
        bucket[next[t.col]] = (t.row, t.val);
        next[t.col] += 1;
    }
    let (mut col_ptr, mut rows, mut vals) = (vec![0usize; n + 1], Vec::with_capacity(trips.len()), Vec::with_capacity(trips.len()));
    for j in 0..n {
        let col = &mut bucket[ptr[j]..ptr[j + 1]];
        col.sort_by_key(|e| e.0);
        for (k, &(r, v)) in col.iter().enumerate() {
            if k > 0 && r == col[k - 1].0 {
                *vals.last_mut().expect("a previous entry") += v;
            } else {
                rows.push(r);
                vals.push(v);
            }
        }
        col_ptr[j + 1] = rows.len();
    }
    Ok(SparseColMat::new(SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows), vals))
}

/// out ← A x (serial, the same bits on every thread setting).
pub(crate) fn apply(a: &SparseColMat<usize, f64>, x: &[f64], out: &mut [f64]) {
    apply_ref(a.as_ref(), x, out);
}

/// out ← A x for a borrowed matrix (`apply`).
pub(crate) fn apply_ref(a: SparseColMatRef<'_, usize, f64>, x: &[f64], out: &mut [f64]) {
    let n = x.len();
    faer::sparse::linalg::matmul::sparse_dense_matmul(
        faer::MatMut::from_column_major_slice_mut(out, a.nrows(), 1),
        faer::Accum::Replace,
        a,
        faer::MatRef::from_column_major_slice(x, n, 1),
        1.0,
        faer::Par::Seq,
    );
}

/// |(a, b)| as √(a² + b²): the multipliers and strain rates of the exact step stay far from
/// the range where the squares overflow (|·| < 1e150), and `f64::hypot` costs several times more.
#[inline]
pub(crate) fn norm(a: f64, b: f64) -> f64 {
    (a * a + b * b).sqrt()
}

/// The projection of σ on the unit ball.
pub(crate) fn onto_ball(s: [f64; 2]) -> [f64; 2] {
    let m = norm(s[0], s[1]);
    if m > 1.0 {
        [s[0] / m, s[1] / m]
    } else {
        s
    }
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

/// The step's cone program as the interior-point and augmented-Lagrangian stages read it: A as
/// triplets (in the assembly's order) and compressed, b, the terms with B's compressed rows
/// (`cols`, `vals`; `apply_b(t, x)` = B_k x + β_k) and the factorisation's symbolic cache.
#[derive(Clone, Copy)]
pub(crate) struct Program<'a> {
    pub(crate) n: usize,
    pub(crate) a_trip: &'a [Triplet<usize, usize, f64>],
    pub(crate) a_mat: &'a SparseColMat<usize, f64>,
    pub(crate) b: &'a [f64],
    pub(crate) terms: &'a [Term],
    pub(crate) cols: &'a [usize],
    pub(crate) vals: &'a [f64],
    pub(crate) apply_b: &'a dyn Fn(&Term, &[f64]) -> [f64; 2],
    pub(crate) cache: &'a SymbolicCache,
    pub(crate) symmetric: bool,
}

/// The matrix A + Σ_k B_kᵀ M_k B_k of both solvers (M_k a term's dim × dim block) on a pattern
/// built once per step: each coefficient's place among the compressed values is found once, so
/// an iteration sums its coefficients in place, in a fixed order, without sorting.
pub(crate) struct Assembly {
    symbolic: SymbolicSparseColMat<usize>,
    /// The value index of each of A's triplets, then of each term coefficient in the order
    /// `assemble` visits them (term k, c, d, e ∈ rows[c], g ∈ rows[d]).
    place: Vec<usize>,
    values: Vec<f64>,
}

/// The conjugate-gradient iteration (`conjugate_gradient`) stops when ‖r‖₂ is below this times
/// ‖b‖₂ ...
const CG_TOL: f64 = 1e-14;

/// ... or after this many iterations without a tenfold fall of ‖r‖₂; where ‖r‖₂ is then above
/// [`CG_ACCEPT`]·‖b‖₂ the matrix is factorised instead.
const CG_STALL: usize = 8;

/// See [`CG_STALL`].
const CG_ACCEPT: f64 = 1e-11;

impl Assembly {
    /// The pattern of A (`a_trip`) and of every term's BᵀB (`cols`: B's column indices).
    pub(crate) fn new(n: usize, a_trip: &[Triplet<usize, usize, f64>], terms: &[Term], cols: &[usize]) -> Result<Self> {
        let mut entries: Vec<(usize, usize)> = a_trip.iter().map(|t| (t.row, t.col)).collect();
        for t in terms {
            for c in 0..t.dim {
                for d in 0..t.dim {
                    for e in t.rows[c].clone() {
                        for g in t.rows[d].clone() {
                            entries.push((cols[e], cols[g]));
                        }
                    }
                }
            }
        }
        // a counting sort by column, then each column's rows sorted and merged
        let mut col_ptr = vec![0usize; n + 1];
        for &(_, c) in &entries {
            col_ptr[c + 1] += 1;
        }
        for j in 0..n {
            col_ptr[j + 1] += col_ptr[j];
        }
        let mut next = col_ptr.clone();
        let mut bucket = vec![(0usize, 0usize); entries.len()];
        for (p, &(r, c)) in entries.iter().enumerate() {
            bucket[next[c]] = (r, p);
            next[c] += 1;
        }
        let mut place = vec![0usize; entries.len()];
        let (mut ptr, mut rows) = (vec![0usize; n + 1], Vec::new());
        for j in 0..n {
            let col = &mut bucket[col_ptr[j]..col_ptr[j + 1]];
            col.sort_unstable();
            for (k, &(r, p)) in col.iter().enumerate() {
                if k == 0 || r != col[k - 1].0 {
                    rows.push(r);
                }
                place[p] = rows.len() - 1;
            }
            ptr[j + 1] = rows.len();
        }
        let nnz = rows.len();
        let symbolic = SymbolicSparseColMat::new_checked(n, n, ptr, None, rows);
        Ok(Assembly { symbolic, place, values: vec![0.0; nnz] })
    }

    /// The factorisation of the matrix last assembled (`assemble`): `factor`, with `cache`.
    pub(crate) fn factor<'a>(&'a self, cache: &SymbolicCache, symmetric: bool) -> Result<Solver<'a>> {
        let k = SparseColMatRef::new(self.symbolic.as_ref(), &self.values);
        Ok(Solver { k, fac: factor(cache, k, symmetric)? })
    }

    /// The matrix with A's values (`a_trip`, in `new`'s order) and the blocks `block(k)` of the
    /// terms (B's values `vals`).
    #[allow(clippy::needless_range_loop)] // c and d index both the block and the term's rows
    pub(crate) fn assemble(&mut self, a_trip: &[Triplet<usize, usize, f64>], terms: &[Term], vals: &[f64], block: impl Fn(usize) -> [[f64; 2]; 2]) {
        self.values.iter_mut().for_each(|v| *v = 0.0);
        let mut p = 0;
        for t in a_trip {
            self.values[self.place[p]] += t.val;
            p += 1;
        }
        for (k, t) in terms.iter().enumerate() {
            let m = block(k);
            for c in 0..t.dim {
                for d in 0..t.dim {
                    let coef = m[c][d];
                    for e in t.rows[c].clone() {
                        let ce = coef * vals[e];
                        for g in t.rows[d].clone() {
                            self.values[self.place[p]] += ce * vals[g];
                            p += 1;
                        }
                    }
                }
            }
        }
    }
}

/// The solve with the Newton matrix K of an iteration (`Assembly::factor`).
pub(crate) struct Solver<'a> {
    k: SparseColMatRef<'a, usize, f64>,
    fac: Factor,
}

impl Solver<'_> {
    /// The matrix K.
    pub(crate) fn matrix(&self) -> SparseColMatRef<'_, usize, f64> {
        self.k
    }

    /// x ← K⁻¹x (serial: the same bits on every thread setting).
    pub(crate) fn solve_in_place(&self, x: &mut [f64]) -> Result<()> {
        self.fac.solve_in_place(x);
        Ok(())
    }
}

/// The factorisation of `mat`: sparse Cholesky where `symmetric` (the matrices of both solvers
/// are then symmetric positive definite), sparse LU otherwise or where Cholesky meets a
/// non-positive pivot; the symbolic part of `cache` is reused while the pattern is the same.
pub(crate) fn factor(cache: &SymbolicCache, mat: SparseColMatRef<'_, usize, f64>, symmetric: bool) -> Result<Factor> {
    let fail = |e: String| Error::SolverFailure { solver: "sparse factorisation of the exact step (faer)".into(), message: e };
    let mut cache = cache.lock().unwrap_or_else(|e| e.into_inner());
    let same = cache
        .as_ref()
        .is_some_and(|(p, r, sym)| p[..] == *mat.symbolic().col_ptr() && r[..] == *mat.symbolic().row_idx() && matches!(sym, Symbolic::Llt(_)) == symmetric);
    if !same {
        let sym = if symmetric {
            Symbolic::Llt(Arc::new(symbolic_llt(mat.symbolic()).map_err(|e| fail(format!("{e:?}")))?))
        } else {
            Symbolic::Lu(SymbolicLu::try_new(mat.symbolic()).map_err(|e| fail(format!("{e:?}")))?)
        };
        *cache = Some((mat.symbolic().col_ptr().to_vec(), mat.symbolic().row_idx().to_vec(), sym));
    }
    match cache.as_ref().expect("set above").2.clone() {
        Symbolic::Llt(sym) => match numeric_llt(&sym, mat) {
            Some(f) => Ok(f),
            None => {
                let sym = SymbolicLu::try_new(mat.symbolic()).map_err(|e| fail(format!("{e:?}")))?;
                Ok(Factor::Lu(Box::new(Lu::try_new_with_symbolic(sym, mat).map_err(|e| fail(format!("{e:?}")))?)))
            }
        },
        Symbolic::Lu(sym) => Ok(Factor::Lu(Box::new(Lu::try_new_with_symbolic(sym, mat).map_err(|e| fail(format!("{e:?}")))?))),
    }
}

/// x ← K⁻¹x by the preconditioned conjugate-gradient iteration from zero (`k(p, q)`: q ← K p;
/// `precondition(r, z)`: z ← P⁻¹r), serial. Stops when the updated ‖r‖₂ ≤ [`CG_TOL`]·‖b‖₂ or after [`CG_STALL`]
/// iterations without a tenfold fall; returns whether the true residual b − K x is then within
/// [`CG_ACCEPT`]·‖b‖₂ (x is the solution), and otherwise leaves x = b.
fn conjugate_gradient(mut k: impl FnMut(&[f64], &mut [f64]), x: &mut [f64], mut precondition: impl FnMut(&[f64], &mut [f64])) -> bool {
    let n = x.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
    let bnorm = dot(x, x).sqrt();
    if bnorm == 0.0 {
        return true;
    }
    let b = x.to_vec();
    let (mut r, mut z, mut q) = (b.clone(), vec![0.0; n], vec![0.0; n]);
    x.iter_mut().for_each(|v| *v = 0.0);
    precondition(&r, &mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let (mut rnorm, mut best, mut since) = (bnorm, bnorm, 0);
    while rnorm > CG_TOL * bnorm && since < CG_STALL && rz > 0.0 {
        k(&p, &mut q);
        let pq = dot(&p, &q);
        if !(pq > 0.0 && pq.is_finite()) {
            break;
        }
        let alpha = rz / pq;
        x.iter_mut().zip(&p).for_each(|(x, p)| *x += alpha * p);
        r.iter_mut().zip(&q).for_each(|(r, q)| *r -= alpha * q);
        rnorm = dot(&r, &r).sqrt();
        if rnorm < 0.1 * best {
            (best, since) = (rnorm, 0);
        } else {
            since += 1;
        }
        precondition(&r, &mut z);
        let rz_new = dot(&r, &z);
        p.iter_mut().zip(&z).for_each(|(p, z)| *p = z + (rz_new / rz) * *p);
        rz = rz_new;
    }
    // the true residual: the updated one drifts from it by round-off
    k(x, &mut q);
    let accepted = b.iter().zip(&q).map(|(b, q)| (b - q) * (b - q)).sum::<f64>().sqrt() <= CG_ACCEPT * bnorm;
    if !accepted {
        x.copy_from_slice(&b);
    }
    accepted
}

/// x ← A⁻¹x for the predictor's operator A alone (the interior point's start): the
/// conjugate-gradient iteration preconditioned by A's diagonal where A is symmetric (its
/// viscous coupling is ≪ its diagonal on the column), A factorised (`factor`, `cache`) where
/// that iteration stalls or A is not symmetric.
pub(crate) fn solve_predictor(a: &SparseColMat<usize, f64>, cache: &SymbolicCache, symmetric: bool, x: &mut [f64]) -> Result<()> {
    if symmetric {
        return solve_block(a, &vec![true; a.ncols()], cache, x);
    }
    factor(cache, a.as_ref(), false)?.solve_in_place(x);
    Ok(())
}

/// x ← A_RR⁻¹x for A's block on the faces `rest` (`rest[f]`; x zero elsewhere on entry and on
/// return), A symmetric: the conjugate-gradient iteration on the products with A masked to the
/// block, preconditioned by its diagonal (its viscous coupling is ≪ its diagonal on the
/// column), the block factorised (`factor`, `cache`) where that iteration stalls.
pub(crate) fn solve_block(a: &SparseColMat<usize, f64>, rest: &[bool], cache: &SymbolicCache, x: &mut [f64]) -> Result<()> {
    let (cp, ri, v) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let dinv: Vec<f64> = (0..a.ncols()).map(|j| if rest[j] { (cp[j]..cp[j + 1]).find(|&e| ri[e] == j).map_or(1.0, |e| 1.0 / v[e]) } else { 0.0 }).collect();
    let masked = |p: &[f64], q: &mut [f64]| {
        apply(a, p, q);
        q.iter_mut().zip(rest).for_each(|(q, &r)| {
            if !r {
                *q = 0.0
            }
        });
    };
    if conjugate_gradient(masked, x, |r, z| z.iter_mut().zip(r.iter().zip(&dinv)).for_each(|(z, (r, d))| *z = r * d)) {
        return Ok(());
    }
    // the block alone, factorised
    let local: Vec<usize> = rest
        .iter()
        .scan(0, |k, &r| {
            Some(if r {
                *k += 1;
                *k - 1
            } else {
                usize::MAX
            })
        })
        .collect();
    let mut trips = Vec::new();
    for j in 0..a.ncols() {
        for e in cp[j]..cp[j + 1] {
            if rest[j] && rest[ri[e]] {
                trips.push(Triplet::new(local[ri[e]], local[j], v[e]));
            }
        }
    }
    let m = rest.iter().filter(|&&r| r).count();
    let mut y: Vec<f64> = x.iter().zip(rest).filter(|(_, &r)| r).map(|(x, _)| *x).collect();
    factor(cache, compress(m, &trips)?.as_ref(), true)?.solve_in_place(&mut y);
    for (f, &l) in local.iter().enumerate() {
        x[f] = if l == usize::MAX { 0.0 } else { y[l] };
    }
    Ok(())
}
