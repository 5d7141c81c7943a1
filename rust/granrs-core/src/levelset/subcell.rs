//! Sub-cell position of the interface between two cell centres, for Dirichlet conditions
//! imposed on the interface Φ = 0 (ghost-fluid method of Gibou, Fedkiw, Cheng & Kang 2002,
//! *J. Comput. Phys.* 176, 205–227):
//!
//!   θ = Φ_in/(Φ_in − Φ_out) ∈ (0, 1],
//!
//! the fraction of the centre-to-centre distance h from the centre inside (Φ_in > 0) to the
//! interface, from the linear interpolation of Φ. A value u = 0 there gives the ghost value
//! u_in(1 − 1/θ) on the outside centre, the one-sided gradient −u_in/(θh), and a diagonal
//! term 1/(θh²) per such face in a 5-point operator. θ is floored at [`THETA_MIN`] so that
//! the diagonal stays bounded when the interface passes through a centre (Gibou et al. §2).
//! Used by the pore pressure (p_f = 0) and the free-surface projection (p = 0).

use crate::grid::Field;

/// Smallest interface fraction θ.
pub const THETA_MIN: f64 = 1e-3;

/// θ = Φ_in/(Φ_in − Φ_out) ≥ THETA_MIN, for Φ_in > 0 ≥ Φ_out.
pub fn interface_fraction(phi_in: f64, phi_out: f64) -> f64 {
    (phi_in / (phi_in - phi_out)).max(THETA_MIN)
}

/// The faces of cell (i, j) (Φ > 0) that cross the interface: (θ, h) per face (left, right,
/// bottom, top) whose neighbour has Φ ≤ 0, h = dx or dy. Domain sides are not interface faces.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // !(Φ > 0): a NaN neighbour counts as outside
pub fn interface_faces(phi: &Field, i: usize, j: usize, dx: f64, dy: f64) -> [Option<(f64, f64)>; 4] {
    let (ii, jj) = (i as isize, j as isize);
    let pc = phi.at(ii, jj);
    let face = |pn: f64, h: f64, is_domain_face: bool| (!is_domain_face && !(pn > 0.0)).then(|| (interface_fraction(pc, pn), h));
    [
        face(phi.at(ii - 1, jj), dx, i == 0),
        face(phi.at(ii + 1, jj), dx, i + 1 == phi.nx),
        face(phi.at(ii, jj - 1), dy, j == 0),
        face(phi.at(ii, jj + 1), dy, j + 1 == phi.ny),
    ]
}

/// `base` + Σ coef/(θh²) over the interface faces of cell (i, j) (left, right, bottom, top, in
/// that order): the diagonal that the Dirichlet value 0 on the interface adds to a 5-point
/// operator with face coefficient `coef`.
pub fn interface_diagonal(phi: &Field, i: usize, j: usize, dx: f64, dy: f64, coef: f64, base: f64) -> f64 {
    interface_faces(phi, i, j, dx, dy).into_iter().flatten().fold(base, |s, (theta, h)| s + coef / (theta * h * h))
}
