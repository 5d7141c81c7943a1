//! The mechanical energy budget of the two-phase (and granular-only) model.
//!
//! Multiplying the momentum balance (Aravena et al. eq. 10b) by u and integrating over Ω, with
//! div u = 0 and u·n = 0 on the walls, gives (per unit width, J m⁻¹):
//!
//!   d/dt ∫ ½ρ|u|² = ∫ (ρ − ρ_ref) g·u − ∫ 2η D:D − ∫ τ Σ:D + Σ_walls ∫ τ_b s·u_t − (2/W) ∫ τ_w s·u
//!
//! (the last term only with the channel's side walls, `walls/side.rs`, not in the paper).
//!
//! The pressure and the pore pressure p_f do no net work on a solenoidal field with u·n = 0 (their
//! effect is through τ = tan(α) p⁺), and the mass equation of ρ carries kinetic energy without
//! creating it. Each term is dissipative in the continuous model:
//! - the plastic power τ Σ:D ≥ 0 **pointwise**: Σ = D/|D| where D ≠ 0 (eq. 6), so Σ:D = 2|D|
//!   (|D|² = ½ D:D). A negative τ Σ:D is stress given back to the flow, as by an elastic
//!   body: it measures how far the θ-relaxed Picard fixed point (eq. 12) is from eq. (11);
//! - the friction power τ_b s·u_t ≤ 0 (s = −u_t/|u_t| while sliding, eq. 9);
//! - the viscous power 2η D:D ≥ 0.
//!
//! **Discretisation.** The force div(τΣ) and div(2ηD) of the predictor are differences of
//! T_xx at centres and T_xy at nodes (`rheology/plastic.rs`), and the power of such a force on
//! the face velocities is, by summation by parts, Σ_centres (T_xx D_xx + T_yy D_yy) h² +
//! Σ_nodes 2 T_xy D_xy h² with the nodes on a wall weighted ½ (¼ at a corner): the sums below are
//! the exact discrete powers of the predictor's forces evaluated at the end of the step
//! (u^{n+1}, Σ^{n+1}, τ^{n+1}, s^{n+1}). The gravity power uses the model's face densities
//! (ρ(Φ) of Φ averaged to the face; in the granular-only model ρ_s on faces beside a granular
//! cell and nothing elsewhere) and the body force (ρ − ρ_ref) g of the predictor. The time
//! integrals are trapezoidal over the steps ([`EnergyLedger`]), and
//!
//!   residual = E_k(t) − E_k(0) − W_g + W_visc + W_pl + W_wall + W_side
//!
//! is the energy the discretisation adds (> 0) or removes (< 0): time stepping, convection,
//! interface transport and mass correction, the projection of the predictor. The budget assumes
//! walls at rest (no prescribed tangential velocity) and closed sides; an open side's work
//! (p u·n) shows in the residual. E_p = ∫ (ρ − ρ_light) (−g·x) is reported for reference: with
//! a moving interface its drop equals W_g only up to the level set's transport and mass
//! correction.
//!
//! Reductions are fixed-order row blocks ([`crate::solvers::par`]): one thread and many give the
//! same sums.

/// Instantaneous rates [W m⁻¹], at the end of a step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EnergyRates {
    /// ∫ (ρ − ρ_ref) g·u: power of gravity.
    pub gravity: f64,
    /// ∫ τ Σ:D: plastic dissipation (≥ 0 for eq. 11).
    pub plastic: f64,
    /// The negative part of τ Σ:D summed over the points where it is negative (≤ 0).
    pub plastic_negative: f64,
    /// ∫ 2η D:D: viscous dissipation.
    pub viscous: f64,
    /// −Σ ∫ τ_b s·u_t: friction dissipation on the Coulomb walls, by side (left, right, bottom, top).
    pub wall: [f64; 4],
    /// (2/W) ∫ τ_w s·u: friction dissipation on the channel's side walls (`walls/side.rs`).
    pub side_walls: f64,
}

/// The budget since the model's state was last set: energies now and the time integrals of the
/// rates [J m⁻¹].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EnergyBudget {
    /// ½ ∫ ρ|u|² now and at the start of the budget.
    pub kinetic: f64,
    pub kinetic_initial: f64,
    /// ∫ (ρ − ρ_light)(−g·x) now and at the start.
    pub potential: f64,
    pub potential_initial: f64,
    /// Work of gravity, and the dissipated works (plastic, its negative part, viscous, walls).
    pub gravity_work: f64,
    pub plastic_work: f64,
    pub plastic_negative_work: f64,
    pub viscous_work: f64,
    pub wall_work: [f64; 4],
    /// Work of the side walls' friction (0 without side walls).
    pub side_wall_work: f64,
    /// E_k − E_k(0) − W_g + W_visc + W_pl + W_wall + W_side: added (> 0) or removed (< 0) by the numerics.
    pub residual: f64,
    /// The rates at the end of the last step.
    pub rates: EnergyRates,
}

/// Running time integrals of the rates (trapezoidal over the accepted steps); reset when the
/// state is set from outside (initial conditions, a restored checkpoint).
#[derive(Clone, Debug, Default)]
pub struct EnergyLedger {
    pub(crate) kinetic_initial: f64,
    pub(crate) potential_initial: f64,
    pub(crate) last: EnergyRates,
    pub(crate) gravity_work: f64,
    pub(crate) plastic_work: f64,
    pub(crate) plastic_negative_work: f64,
    pub(crate) viscous_work: f64,
    pub(crate) wall_work: [f64; 4],
    pub(crate) side_wall_work: f64,
    pub(crate) partials: Vec<[f64; 4]>,
}

impl EnergyLedger {
    /// Forgets the integrals (the next step starts a new budget).
    pub fn reset(&mut self) {
        let partials = std::mem::take(&mut self.partials);
        *self = EnergyLedger { partials, ..Default::default() };
    }
}
