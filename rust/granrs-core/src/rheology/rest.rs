//! The plastic tensor of a layer at rest ("lithostatic" initial stress).
//!
//! Equation: for a state at rest (u = 0) that does not vary along x, the x-momentum balance
//! (Aravena et al. eq. 10b with u = 0) reduces to
//!
//!   ∂_y(τ Σ_xy) + f_x = 0,   f_x = (ρ − ρ_ref) g_x − ∂_x(p + p_f),
//!
//! so that τ Σ_xy(y) = ∫_y^H f_x dy' (the shear stress of an infinite slope: ρ' g sin θ times the
//! depth in a uniform layer, Savage & Hutter 1989, *J. Fluid Mech.* 199). The rest state is
//! admissible for the plastic law iff |Σ| ≤ 1 everywhere (the Drucker–Prager criterion
//! |σ_dev| ≤ tan(α) p: tan θ ≤ tan α for a uniform layer on a slope θ).
//!
//! Why it is needed: the Picard iteration of eq. (12) starts from Σ^{n+1,0} = Σ^n and its fixed
//! point is Σ = P(Σ + r D + θ(Σ^n − Σ)). Started from Σ = 0, a "rigid" zone deforms at
//! D = θ(Σ − Σ^n)/r per step until Σ has built up: a layer that should stay at rest moves
//! (0.67 m/s after 0.2 s in `granrs validate fluidised-layer`, docs/validation.md). Starting from
//! the balancing Σ, the first Picard iterate already solves eq. (11) with ũ = 0.
//!
//! Discretisation: the discrete force of `PlasticState::add_force` on the u-face (i, j) is
//! [τ_n Σ_xy]_{j}^{j+1}/dy (Σ_xx = 0), and f_x is the predictor's right-hand side at rest
//! (ρ_u g_x − ρ_ref g_x − [p + p_f]_{i−1}^{i}/dx, `models/step.rs`). Node by node from the
//! top (τΣ_xy = 0 at the top nodes) T_j = T_{j+1} + dy f_x(i, j) and Σ_xy = T_j/τ_n, so the
//! discrete balance holds to round-off in every column (|T| below 1e-9 ρ g L_y, the round-off of
//! the pressure solve in the air, is taken as 0). Where |T|/τ_n > 1 the state cannot be at
//! rest: Σ_xy is clamped to ±1 there (the material yields) and the largest ratio is reported.
//! Boundary nodes whose Σ_xy is held at 0 (free-slip or Coulomb sides) carry nothing: on a
//! Coulomb base the wall friction builds up by its own iteration.

/// What `TwoPhaseModel::balance_plastic_stress` found (models/rest.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RestStress {
    /// Largest |τΣ_xy| / τ needed for rest over the nodes (≤ 1: the state can stay at rest).
    pub max_ratio: f64,
    /// Node (i, j) of the largest ratio.
    pub node: (usize, usize),
    /// Nodes where the ratio exceeded 1 (Σ_xy clamped to ±1 there).
    pub clamped: usize,
    /// max over the v-faces of |[τΣ_xy]_i^{i+1}/dx| / max |ρ g|: 0 for a state uniform in x, the
    /// size of the y-force the construction leaves unbalanced otherwise.
    pub x_residual: f64,
}
