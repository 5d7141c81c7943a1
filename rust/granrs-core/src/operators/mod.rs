//! Staggered-grid operators on MAC fields (Aravena et al. §3.2: second-order finite volumes).
//!
//! Names say where the result lives (see [`README`](https://) legend in `operators/README.md`):
//!
//! | operator | from → to | discrete form |
//! |---|---|---|
//! | [`divergence`] | (XFace u, YFace v) → Centre | (u_{i+1,j} − u_{ij})/dx + (v_{i,j+1} − v_{ij})/dy |
//! | [`gradient`] | Centre p → (XFace, YFace) | ((p_{ij} − p_{i−1,j})/dx, (p_{ij} − p_{i,j−1})/dy) |
//! | [`strain_rate`] | (u, v) → D_xx at Centre, D_xy at Node | D_xx = ∂u/∂x, D_yy = −D_xx in the discrete divergence-free limit is *not* assumed: D_yy = ∂v/∂y; D_xy = ½(∂u/∂y + ∂v/∂x) |
//! | [`viscous`] | (u, v), η_c, η_n → (XFace, YFace) | div(2 η D(u)) with 2η D_xx, 2η D_yy at centres and 2η D_xy at nodes |
//! | [`convection`] | (u, v) → (XFace, YFace) | (u·∇)u, centred second order, advective form |
//!
//! All kernels are allocation-free, take an [`Exec`] and work row by row. Ghost values must be
//! filled first by [`fill_velocity_ghosts`] (velocity) or by the caller (scalars).

mod ghosts;
mod kernels;
pub mod simd;
pub mod weno5;

pub use ghosts::{fill_velocity_ghosts, periodic_pair, unknown_face_range, BcMode};
pub use kernels::{
    cell_to_face_x, cell_to_face_y, cell_to_node, convection, convection_weno5, divergence, divergence_max_abs, gradient, max_abs, max_speed, max_speed_where,
    strain_rate, strain_rate_norm_centre, viscous, viscous_helmholtz, viscous_helmholtz_dots, RowDots,
};

use crate::exec::Exec;
use crate::grid::{Field, HALO};

/// Left-to-right sums along `R` rows at once: `s[m][k]` = Σ_{c < n} `term(m, c)[k]`, each added
/// in column order from 0.0 as a fold along one row adds it (the same bits), with the R·K chains
/// of additions in one loop over the columns, so that the processor overlaps them where one
/// row's sum would wait on each addition.
#[inline(always)]
pub fn row_sums<const R: usize, const K: usize>(n: usize, term: impl Fn(usize, usize) -> [f64; K]) -> [[f64; K]; R] {
    let mut s = [[0.0; K]; R];
    for c in 0..n {
        for (m, sm) in s.iter_mut().enumerate() {
            let t = term(m, c);
            for k in 0..K {
                sm[k] += t[k];
            }
        }
    }
    s
}

/// Rows whose sums [`sums_by_row`] adds together in one loop.
pub const SUM_ROWS: usize = 4;

/// `out[k]` = the left-to-right sums over the columns c < n of `term` at the inputs of row k
/// (`rows(k)`: P slices of at least n values), by [`row_sums`] on [`SUM_ROWS`] rows at a time and
/// the remaining rows one by one: the bits of separate folds along each row.
#[inline(always)]
pub fn sums_by_row<'a, const P: usize, const K: usize>(
    out: &mut [[f64; K]],
    n: usize,
    rows: impl Fn(usize) -> [&'a [f64]; P],
    term: impl Fn([f64; P]) -> [f64; K],
) {
    let mut k = 0;
    while k + SUM_ROWS <= out.len() {
        let ins: [[&[f64]; P]; SUM_ROWS] = std::array::from_fn(|m| rows(k + m).map(|r| &r[..n]));
        out[k..k + SUM_ROWS].copy_from_slice(&row_sums::<SUM_ROWS, K>(n, |m, c| term(std::array::from_fn(|p| ins[m][p][c]))));
        k += SUM_ROWS;
    }
    for (kk, o) in out.iter_mut().enumerate().skip(k) {
        let ins = rows(kk).map(|r| &r[..n]);
        *o = row_sums::<1, K>(n, |_, c| term(std::array::from_fn(|p| ins[p][c])))[0];
    }
}

/// Runs `f(j, row)` over the interior rows j = 0..ny of `field`, where `row` is the full storage
/// row (ghost columns included; interior column i sits at `row[HALO + i]`).
pub fn for_each_interior_row<F>(exec: Exec, field: &mut Field, f: F)
where
    F: Fn(usize, &mut [f64]) + Sync + Send,
{
    let stride = field.stride();
    let ny = field.ny;
    let data = field.slice_mut();
    let interior = &mut data[HALO * stride..(HALO + ny) * stride];
    exec.for_each_row(interior, stride, f);
}

/// [`for_each_interior_row`] for a sweep that also reduces: returns the largest of the values
/// `f(j, row)` returns (NaN propagates), the same on any number of threads.
pub fn for_each_interior_row_max<F>(exec: Exec, field: &mut Field, f: F) -> f64
where
    F: Fn(usize, &mut [f64]) -> f64 + Sync + Send,
{
    let stride = field.stride();
    let ny = field.ny;
    let data = field.slice_mut();
    exec.max_each_row(&mut data[HALO * stride..(HALO + ny) * stride], stride, f)
}

/// Runs `f(j, row_a, row_b)` over interior rows of two fields of the same shape.
pub fn for_each_interior_row2<F>(exec: Exec, a: &mut Field, b: &mut Field, f: F)
where
    F: Fn(usize, &mut [f64], &mut [f64]) + Sync + Send,
{
    use rayon::prelude::*;
    assert_eq!(a.data.dim(), b.data.dim());
    let stride = a.stride();
    let ny = a.ny;
    let ra = &mut a.slice_mut()[HALO * stride..(HALO + ny) * stride];
    let rb = &mut b.slice_mut()[HALO * stride..(HALO + ny) * stride];
    if exec.use_parallel(ra.len()) {
        ra.par_chunks_mut(stride).zip(rb.par_chunks_mut(stride)).enumerate().for_each(|(j, (x, y))| f(j, x, y));
    } else {
        for (j, (x, y)) in ra.chunks_mut(stride).zip(rb.chunks_mut(stride)).enumerate() {
            f(j, x, y);
        }
    }
}

/// Rows of pseudo-random values in [−0.5, 0.5) from `seed` (a linear congruential generator):
/// the inputs of the row kernels' bit-for-bit tests.
#[cfg(test)]
pub(crate) fn random_rows(seed: u64) -> impl FnMut(usize) -> Vec<f64> {
    let mut s = seed;
    move |n| {
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::{random_rows, row_sums, sums_by_row};

    /// Sums along four rows at once and along one are those of separate left-to-right folds of
    /// each row, bit for bit, for one to three products per column.
    #[test]
    fn row_sums_are_the_separate_folds_bit_for_bit() {
        let mut row = random_rows(11);
        let n = 53;
        let rows: Vec<[Vec<f64>; 3]> = (0..4).map(|_| [row(n), row(n), row(n)]).collect();
        let fold = |a: &[f64], b: &[f64]| a.iter().zip(b).fold(0.0, |s, (p, q)| s + p * q);
        let got = row_sums::<4, 3>(n, |m, c| {
            let [b, r, z] = &rows[m];
            [b[c] * b[c], r[c] * r[c], r[c] * z[c]]
        });
        let dots = row_sums::<4, 1>(n, |m, c| [rows[m][0][c] * rows[m][2][c]]);
        for (m, [b, r, z]) in rows.iter().enumerate() {
            let want = [fold(b, b), fold(r, r), fold(r, z)];
            assert_eq!(got[m].map(f64::to_bits), want.map(f64::to_bits));
            assert_eq!(row_sums::<1, 2>(n, |_, c| [b[c] * b[c], r[c] * r[c]])[0].map(f64::to_bits), [want[0], want[1]].map(f64::to_bits));
            assert_eq!(dots[m][0].to_bits(), fold(b, z).to_bits());
        }
        // seven rows: a group of four, then three one by one; rows longer than n are cut at n
        let long: Vec<[Vec<f64>; 2]> = (0..7).map(|_| [row(n + 5), row(n + 5)]).collect();
        let mut out = [[f64::NAN; 2]; 7];
        sums_by_row(&mut out, n, |k| [&long[k][0][..], &long[k][1][..]], |[a, b]| [a * b, a * a]);
        for (o, [a, b]) in out.iter().zip(&long) {
            assert_eq!(o.map(f64::to_bits), [fold(&a[..n], &b[..n]), fold(&a[..n], &a[..n])].map(f64::to_bits));
        }
    }
}
