//! Anderson acceleration of the Picard iteration of the plastic projection (Aravena et al.
//! eq. 11–12; Anderson 1965, *J. ACM* 12, 547–560; Walker & Ni 2011, *SIAM J. Numer. Anal.* 49,
//! 1715–1735, "Type II" in the difference form of their Algorithm AA).
//!
//! The Picard iteration of eq. (12) is a fixed-point map x ↦ G(x) on the plastic tensor
//! x = (Σ_xx at centres, Σ_xy at nodes): solve the predictor with the force div(τ x), then
//! G(x) = P(x + r D_dev(ũ) + θ(Σ^n − x)). With θ = 0 (Uzawa) its fixed point is eq. (11) itself,
//! but the plain iteration only contracts like 1 − O(h²) on fine grids; with θ > 0 it contracts
//! like 1 − θ towards the *relaxed* fixed point, whose rigid zones are elastic (see
//! [`super::RheologyConfig::proximal_restarts`]). Anderson mixing of depth m replaces
//! x_{k+1} = G(x_k) by
//!
//!   f_k = G(x_k) − x_k,   γ = argmin_γ ‖f_k − ΔF_k γ‖_w,   x_{k+1} = G(x_k) − ΔG_k γ,
//!
//! with ΔF_k, ΔG_k the last m_k ≤ m differences f_{i+1} − f_i, G(x_{i+1}) − G(x_i). The fixed
//! point is unchanged (f = 0 gives γ = 0), so the converged Σ is the same to the Picard
//! tolerance; only the number of predictor solves changes. The norm is weighted by the yield
//! stress, ‖y‖²_w = Σ (τ y / τ_max)², the scale of the force τΣ (and of the Picard increment).
//!
//! The small least-squares problem is solved by its normal equations with a relative Tikhonov
//! shift of 1e-10 (Gaussian elimination with partial pivoting on a stack array). The history is
//! cleared whenever the map changes (a new step, a proximal restart of the anchor, a halving of
//! r) and when the mixed residual grows by more than `RESTART_GROWTH` over the smallest seen since
//! the last clearing (the map is only piecewise smooth: P switches between rigid and yielded
//! points). Reductions are serial, in a fixed order, so the iterates do not depend on the number
//! of threads; the normal matrix is kept by ring slot, so an iteration costs 2m + 1 dot products
//! of the length of Σ (the new column's row, the right-hand side, ‖f‖), against the hundreds of
//! stencil products of the predictor solve.

use super::plastic::PlasticState;

/// Largest depth accepted (the normal equations live on the stack).
pub const MAX_ANDERSON_DEPTH: usize = 20;

/// The history is cleared when ‖f_k‖_w exceeds this factor times the smallest ‖f‖_w since the
/// last clearing.
pub const RESTART_GROWTH: f64 = 1e2;

/// Relative Tikhonov shift of the normal equations.
const TIKHONOV: f64 = 1e-10;

/// Anderson mixing state for the plastic tensor (all buffers allocated once).
pub struct Anderson {
    depth: usize,
    /// Length of Σ_xx's storage (the first block of every vector).
    n_c: usize,
    /// Weights (τ/τ_max)² of the entries, set at the start of each step ([`Anderson::begin_step`]).
    w: Vec<f64>,
    /// The iterate x_k handed to G (saved before each update), then f_k = G(x_k) − x_k.
    x: Vec<f64>,
    f_prev: Vec<f64>,
    g_prev: Vec<f64>,
    /// Ring buffers of ΔF and ΔG columns; the valid slots are 0..count.
    df: Vec<Vec<f64>>,
    dg: Vec<Vec<f64>>,
    /// ⟨ΔF_i, ΔF_j⟩_w by ring slot (a new column only adds its own row).
    gram: [[f64; MAX_ANDERSON_DEPTH]; MAX_ANDERSON_DEPTH],
    /// Number of valid columns, and the ring slot of the next one.
    count: usize,
    head: usize,
    have_prev: bool,
    best: f64,
    /// Times the history was cleared by the growth safeguard (cumulative).
    pub restarts: usize,
}

/// ⟨a, b⟩_w in a fixed (serial) order.
fn wdot(w: &[f64], a: &[f64], b: &[f64]) -> f64 {
    w.iter().zip(a).zip(b).map(|((w, a), b)| w * a * b).sum()
}

impl Anderson {
    /// Mixing of depth `depth` (1..=[`MAX_ANDERSON_DEPTH`]) for the plastic tensor of `plastic`.
    pub fn new(depth: usize, plastic: &PlasticState) -> Self {
        let depth = depth.clamp(1, MAX_ANDERSON_DEPTH);
        let n_c = plastic.sigma_xx.slice().len();
        let n = n_c + plastic.sigma_xy.slice().len();
        Anderson {
            depth,
            n_c,
            w: vec![0.0; n],
            x: vec![0.0; n],
            f_prev: vec![0.0; n],
            g_prev: vec![0.0; n],
            df: (0..depth).map(|_| vec![0.0; n]).collect(),
            dg: (0..depth).map(|_| vec![0.0; n]).collect(),
            gram: [[0.0; MAX_ANDERSON_DEPTH]; MAX_ANDERSON_DEPTH],
            count: 0,
            head: 0,
            have_prev: false,
            best: f64::INFINITY,
            restarts: 0,
        }
    }

    /// Start of a step's Picard loop: the weights from this step's yield stress τ, no history.
    pub fn begin_step(&mut self, p: &PlasticState) {
        let scale = if p.tau_max > 0.0 { 1.0 / p.tau_max } else { 0.0 };
        for (w, t) in self.w.iter_mut().zip(p.tau_c.slice().iter().chain(p.tau_n.slice())) {
            *w = (t * scale) * (t * scale);
        }
        self.reset();
    }

    /// Forgets the history (the map changed).
    pub fn reset(&mut self) {
        self.count = 0;
        self.head = 0;
        self.have_prev = false;
        self.best = f64::INFINITY;
    }

    /// Saves x_k = Σ before the update G.
    pub fn save_iterate(&mut self, p: &PlasticState) {
        let (xc, xn) = self.x.split_at_mut(self.n_c);
        xc.copy_from_slice(p.sigma_xx.slice());
        xn.copy_from_slice(p.sigma_xy.slice());
    }

    /// After the update (Σ = G(x_k)): replaces Σ by the Anderson iterate x_{k+1}. Returns the
    /// number of history columns used (0: plain Picard step).
    pub fn mix(&mut self, p: &mut PlasticState) -> usize {
        // f_k = g − x (in x, which is not needed any more) and ‖f_k‖_w
        let g = p.sigma_xx.slice().iter().chain(p.sigma_xy.slice());
        let mut fnorm2 = 0.0;
        for ((x, g), w) in self.x.iter_mut().zip(g).zip(&self.w) {
            *x = g - *x;
            fnorm2 += w * *x * *x;
        }
        let fnorm = fnorm2.sqrt();
        if !fnorm.is_finite() {
            self.reset();
            return 0;
        }
        if fnorm > RESTART_GROWTH * self.best {
            self.restarts += 1;
            self.reset();
        }
        self.best = self.best.min(fnorm);
        let Anderson { w, x, f_prev, g_prev, df, dg, gram, .. } = self;
        // the new columns ΔF, ΔG in slot `head` (from the second iteration on); f, g become the
        // previous ones
        let g = p.sigma_xx.slice().iter().chain(p.sigma_xy.slice());
        let slot = self.head;
        if self.have_prev {
            let (dfs, dgs) = (&mut df[slot], &mut dg[slot]);
            for (k, &g) in g.enumerate() {
                dfs[k] = x[k] - f_prev[k];
                dgs[k] = g - g_prev[k];
                f_prev[k] = x[k];
                g_prev[k] = g;
            }
            self.head = (self.head + 1) % self.depth;
            self.count = (self.count + 1).min(self.depth);
            for j in 0..self.count {
                let v = wdot(w, &df[slot], &df[j]);
                gram[slot][j] = v;
                gram[j][slot] = v;
            }
        } else {
            for ((fp, gp), (&f, &g)) in f_prev.iter_mut().zip(g_prev.iter_mut()).zip(x.iter().zip(g)) {
                *fp = f;
                *gp = g;
            }
            self.have_prev = true;
        }
        let m = self.count;
        if m == 0 {
            return 0;
        }
        // normal equations (ΔFᵀWΔF + λI) γ = ΔFᵀW f over the valid slots
        let mut a = [[0.0f64; MAX_ANDERSON_DEPTH + 1]; MAX_ANDERSON_DEPTH];
        let shift = TIKHONOV * (0..m).map(|i| gram[i][i]).sum::<f64>() / m as f64;
        for (i, row) in a.iter_mut().enumerate().take(m) {
            row[..m].copy_from_slice(&gram[i][..m]);
            row[i] += shift;
            row[m] = wdot(w, &df[i], x);
        }
        let Some(gamma) = solve_dense(&mut a, m) else {
            self.reset();
            return 0;
        };
        // Σ ← g − ΔG γ
        let sigma = p.sigma_xx.slice_mut().iter_mut().chain(p.sigma_xy.slice_mut().iter_mut());
        for (k, s) in sigma.enumerate() {
            *s -= (0..m).map(|i| gamma[i] * dg[i][k]).sum::<f64>();
        }
        m
    }
}

/// Solves the m × m system in `a` (augmented with its right-hand side in column m) by Gaussian
/// elimination with partial pivoting; `None` if it is singular or not finite.
fn solve_dense(a: &mut [[f64; MAX_ANDERSON_DEPTH + 1]; MAX_ANDERSON_DEPTH], m: usize) -> Option<[f64; MAX_ANDERSON_DEPTH]> {
    for c in 0..m {
        let piv = (c..m).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        let p = a[piv][c];
        if p == 0.0 || !p.is_finite() {
            return None;
        }
        a.swap(c, piv);
        let pivot_row = a[c];
        for row in a.iter_mut().take(m).skip(c + 1) {
            let f = row[c] / pivot_row[c];
            for (x, &y) in row.iter_mut().zip(&pivot_row).take(m + 1).skip(c) {
                *x -= f * y;
            }
        }
    }
    let mut x = [0.0f64; MAX_ANDERSON_DEPTH];
    for r in (0..m).rev() {
        let s: f64 = (r + 1..m).map(|k| a[r][k] * x[k]).sum();
        x[r] = (a[r][m] - s) / a[r][r];
        if !x[r].is_finite() {
            return None;
        }
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_solve_matches_a_known_system() {
        let mut a = [[0.0; MAX_ANDERSON_DEPTH + 1]; MAX_ANDERSON_DEPTH];
        // [[0, 2], [3, 1]] x = [4, 5] → x = (1, 2); the zero pivot needs the row swap
        a[0][0] = 0.0;
        a[0][1] = 2.0;
        a[0][2] = 4.0;
        a[1][0] = 3.0;
        a[1][1] = 1.0;
        a[1][2] = 5.0;
        let x = solve_dense(&mut a, 2).unwrap();
        assert!((x[0] - 1.0).abs() < 1e-14 && (x[1] - 2.0).abs() < 1e-14);
        let mut s = [[0.0; MAX_ANDERSON_DEPTH + 1]; MAX_ANDERSON_DEPTH];
        s[0][0] = 1.0;
        s[0][1] = 1.0;
        s[1][0] = 1.0;
        s[1][1] = 1.0;
        assert!(solve_dense(&mut s, 2).is_none());
    }
}
