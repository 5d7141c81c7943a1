//! Depth-averaged (shallow-layer, Savage–Hutter type) model of a granular layer along a channel,
//! with the depth-integrated pore pressure of the two-phase model.
//!
//! # Equations
//!
//! Unknowns h(x, t) (depth), q = h u (discharge) and the pore-pressure variable m, on 0 < x < L
//! over a bed b(x) (flat, b = 0, unless set). With the default transport
//! ([`PoreTransport::DepthIntegrated`]) m = ∫₀ʰ p_f dz / (ρ g) is the depth-integrated pore
//! pressure over the weight (m², ρ the bulk density):
//!
//! ```text
//!   h_t + (h u)_x                       = 0
//!   (h u)_t + (h u² + ½ K g h²)_x        = − K g h b_x − g h tan(α_b) (1 − β)⁺ sign(u)
//!   m_t + (m u)_x                       = − 2 κ m / h² + κ β_s χ_s(x)
//!   β = 2 m / h²,   K = k (1 − β̂) + β̂,   β̂ = min(max(β, 0), 1)
//! ```
//!
//! - Mass and momentum: Savage & Hutter (1989, J. Fluid Mech. 199, 177–215), on a horizontal
//!   channel (no cos θ / sin θ factors). The basal friction is Coulomb with angle α_b on the
//!   effective normal stress: τ_b = tan α_b (ρ g h − p_b)⁺ = ρ g h tan α_b (1 − β)⁺ (Iverson
//!   1997, Rev. Geophys. 35). When u = 0 the friction is a threshold: |τ_b| ≤ ρ g h tan α_b
//!   (1 − β)⁺ (the layer stays at rest while the driving force is below it).
//! - Lateral pressure: the pore fluid's pressure is isotropic; only the effective (grain) stress
//!   has an earth-pressure coefficient k (Iverson & Denlinger 2001, J. Geophys. Res. 106;
//!   Pitman & Le 2005, Phil. Trans. R. Soc. A 363): σ_xx = k (σ_zz − p_f) + p_f with
//!   σ_zz = ρ g (h − z). Integrated over the depth, ∫σ_xx dz = ½ ρ g h² [k (1 − β) + β] with the
//!   linear profile below (∫p_f dz = ½ β ρ g h²), hence K. An effective stress cannot pull:
//!   β̂ = min(β, 1). k is [`EarthPressure`]: a constant (1: the total stress hydrostatic and
//!   isotropic, K = 1 whatever β), or Savage & Hutter's active coefficient
//!   k_act = 2 sec²φ (1 − √(1 − cos²φ sec²δ)) − 1 of a spreading layer with internal friction φ
//!   and basal friction δ = α_b (their eq. 3.14; δ > φ clipped to δ = φ), of the dry angles:
//!   friction acts on the effective stress, which the factor (1 − β̂) already carries.
//! - Pore pressure: eq. (7d) of the two-phase model, ∂_t p_f + div(u_s p_f) = κ Δp_f, integrated
//!   over 0 < z < h with a drained surface (p_f(h) = 0), grains that do not cross the base (w = 0
//!   at z = 0) and a depth-uniform u: the boundary terms of Leibniz's rule vanish with p_f(h),
//!   and with κ ∂_xx p_f neglected against κ ∂_zz p_f (a thin layer),
//!   P_t + (u P)_x = κ ∂_z p_f|_h − κ ∂_z p_f|_0, P = ∫₀ʰ p_f dz. The base supplies
//!   −κ ∂_z p_f|_0 = κ β_s ρ g under the reservoir (the paper's ∂p_f/∂y = −β_s φ ρ_s g, gas
//!   flowing up; χ_s = 1 at cell centres x < x_s) and nothing elsewhere. The surface flux needs a
//!   profile: p_f = p_b (1 − z/h), the two-phase model's initial profile and its steady state
//!   under the supply, gives P = ½ p_b h and κ ∂_z p_f|_h = −κ p_b / h = −2 κ P / h², the decay
//!   rate 2κ/h² (the slowest diffusion mode cos(π z/2h) decays at π²κ/4h², 23 % faster). With
//!   m = P/(ρ g): β = p_b/(ρ g h) = 2 m / h², and under a steady supply β → β_s exactly. As a
//!   column spreads faster than it drains (h falls along a path, m/h is carried), β rises above
//!   1: the friction vanishes, as in the two-phase model (docs/models.md).
//! - [`PoreTransport::BasalRatio`] carries m = h β instead, relaxing at the slowest mode's rate
//!   π²κ/4h² and held at β ≥ β_s under the supply; β then never exceeds its initial value. It is
//!   kept for the comparison of docs/models.md.
//!
//! # Numerics
//!
//! Finite volumes on n cells (Δx = L/n) with two ghost cells at each end:
//! - MUSCL reconstruction (minmod slopes) of h, u, the specific pore variable s = m/h and the free
//!   surface η = h + b;
//! - hydrostatic reconstruction (Audusse, Bouchut, Bristeau, Klein & Perthame 2004, SIAM J. Sci.
//!   Comput. 25) at each face: h* = max(0, h + b − max(b_L, b_R)), with the pressure corrections
//!   ½ K g (h² − h*²) and the centred bed term −K g h_i (Δη − Δh)_i for second order;
//! - HLL flux for (h, h u) with the dry-bed wave speeds u ± 2c (Toro 2001, *Shock-capturing
//!   methods for free-surface shallow flows*, §10), c = √(K g h) of each side; m is fluxed upwind
//!   with the mass flux (F_m = F_h s_upwind), so s stays within its neighbours' bounds. Between
//!   two states at rest (u_L = u_R = 0) the mass flux is zero: HLL's diffusion term
//!   S_L S_R (h_R − h_L) would otherwise let a deposit held by friction creep. The momentum flux
//!   there is HLL's, so a column edge still starts to move;
//! - SSP-RK2 (Heun) in time, Δt = cfl Δx / max |S| from the faces' wave speeds (cfl ≤ 0.5 keeps
//!   h ≥ 0 for MUSCL + hydrostatic reconstruction);
//! - Coulomb friction as a projection after each stage with that stage's share of Δt
//!   (Δt, then Δt/2 in the final convex combination): with J = τ g h tan α_b (1 − β)⁺,
//!   q ← 0 if |q| ≤ J, else q − J sign(q). Friction can stop a cell, never reverse it, and a cell
//!   whose driving impulse is below J stays exactly at rest;
//! - after the step the pore source, exact for frozen h: m ← m_eq + (m − m_eq) e^{−2κΔt/h²},
//!   m_eq = ½ β_s h² under the supply, 0 elsewhere ([`PoreTransport::BasalRatio`]:
//!   m ← m e^{−Δt π²κ/4h²}, then β ≥ β_s under the supply); cells with h < h_dry (the wet/dry
//!   threshold) have u = 0 and m = 0;
//! - walls (reflective ghosts: h, m mirrored, u reversed) at both ends: the mass flux through a
//!   wall is exactly zero, so Σ h Δx is conserved to round-off.
//!
//! A step allocates nothing: every work array is allocated in [`DepthAveragedModel::new`].
//! After a step non-finite values or a negative depth stop the run with [`Error::Simulation`]
//! (step, time and cell `(i, 0)`).
//!
//! # Where the model fails
//!
//! Savage–Hutter assumes a long, thin layer (aspect ratio ε = H/L ≪ 1): the pressure is
//! hydrostatic and the velocity uniform over the depth. A tall column (a = H_c/L_c ≳ 1) first
//! collapses vertically, with non-hydrostatic pressure and a failure surface inside the column
//! (internal friction α matters, not only α_b); the model starts that phase as a dam break, so
//! its early front speed (2√(g H_c)) is too high. Granular columns with a ≳ 1 are known to need
//! ad-hoc friction to match experiments (Lube et al. 2005; Larrieu, Staron & Hinch 2006;
//! Kerswell 2005). docs/models.md tabulates the measured difference with the two-phase model.

use ndarray::Array1;

use crate::error::{check_non_negative, check_positive, check_range, Error, Result};

/// Ghost cells at each end.
pub const GHOSTS: usize = 2;

/// What the pore-pressure variable m carries (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoreTransport {
    /// m = ∫p_f dz/(ρ g), eq. (7d) integrated over the depth with a linear profile: β = 2m/h²,
    /// decay 2κ/h², the supply κ β_s under the reservoir.
    DepthIntegrated,
    /// m = h β: β carried with the flow, decaying at π²κ/4h², held at β ≥ β_s under the supply.
    BasalRatio,
}

/// Pore-pressure part of the depth-averaged model (absent: β ≡ 0, nothing solved).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthAveragedPore {
    /// Pore-pressure diffusivity κ [m² s⁻¹].
    pub diffusivity: f64,
    /// Supply ratio β_s in [0, 1] (0.9 in the paper): the basal flux κ β_s ρ g under the supply.
    pub supply_ratio: f64,
    /// The supply acts on cells with centre x < `supply_x_max` [m] (L_c for the column; 0: none).
    pub supply_x_max: f64,
    /// What m carries.
    pub transport: PoreTransport,
}

/// The earth-pressure coefficient k of the effective stress (the lateral pressure
/// K = k (1 − β̂) + β̂, the pore pressure isotropic).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EarthPressure {
    /// A constant k (1: the total stress hydrostatic, K = 1 whatever β).
    Constant(f64),
    /// Savage & Hutter's active coefficient of the internal friction angle φ (degrees) and the
    /// basal friction angle.
    SavageHutterActive {
        /// Internal friction angle φ in degrees.
        internal_friction_angle: f64,
    },
}

/// Savage & Hutter's (1989) active earth-pressure coefficient of tan φ and tan δ (δ > φ clipped
/// to φ): 2 sec²φ (1 − √(1 − cos²φ sec²δ)) − 1; δ = 0 gives Rankine's (1 − sin φ)/(1 + sin φ),
/// δ = φ gives 2 sec²φ − 1.
pub fn active_earth_pressure(tan_phi: f64, tan_delta: f64) -> f64 {
    let (tp, td) = (tan_phi, tan_delta.min(tan_phi));
    let cos2_phi = 1.0 / (1.0 + tp * tp);
    let sec2_delta = 1.0 + td * td;
    2.0 / cos2_phi * (1.0 - (1.0 - cos2_phi * sec2_delta).max(0.0).sqrt()) - 1.0
}

/// The lateral pressure coefficient K = k (1 − β̂) + β̂, β̂ = min(max(β, 0), 1): the effective
/// stress with the earth-pressure coefficient k, the pore pressure isotropic.
#[inline]
pub fn lateral_pressure(k: f64, beta: f64) -> f64 {
    let b = beta.clamp(0.0, 1.0);
    k * (1.0 - b) + b
}

/// Configuration of [`DepthAveragedModel`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthAveragedConfig {
    /// Number of cells n.
    pub cells: usize,
    /// Channel length L [m].
    pub length: f64,
    /// Gravity g [m s⁻²].
    pub gravity: f64,
    /// Earth-pressure coefficient k of the effective stress (`Constant(1.0)`: hydrostatic).
    pub earth_pressure: EarthPressure,
    /// Basal friction angle α_b in degrees.
    pub basal_friction_angle: f64,
    /// CFL number (≤ 0.5 for positivity).
    pub cfl: f64,
    /// Wet/dry threshold h_dry [m]: thinner cells have u = 0.
    pub dry_depth: f64,
    /// Largest time step [s].
    pub max_dt: f64,
    /// Pore pressure (None: not fluidised).
    pub pore: Option<DepthAveragedPore>,
}

impl DepthAveragedConfig {
    /// n cells on a channel of length L, g = 9.81, k = 1, no friction, cfl = 0.4,
    /// h_dry = 1e-6 m, Δt ≤ 0.01 s, no pore pressure.
    pub fn new(cells: usize, length: f64) -> Self {
        DepthAveragedConfig {
            cells,
            length,
            gravity: 9.81,
            earth_pressure: EarthPressure::Constant(1.0),
            basal_friction_angle: 0.0,
            cfl: 0.4,
            dry_depth: 1e-6,
            max_dt: 1e-2,
            pore: None,
        }
    }

    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        if !(4..=10_000_000).contains(&self.cells) {
            return Err(Error::param("cells", self.cells, "an integer in [4, 10000000]"));
        }
        check_positive("length", self.length)?;
        check_positive("gravity", self.gravity)?;
        match self.earth_pressure {
            EarthPressure::Constant(k) => check_positive("earth_pressure", k)?,
            EarthPressure::SavageHutterActive { internal_friction_angle } => check_range("internal_friction_angle", internal_friction_angle, 0.0, 89.0)?,
        }
        check_range("basal_friction_angle", self.basal_friction_angle, 0.0, 89.0)?;
        if !(self.cfl.is_finite() && self.cfl > 0.0 && self.cfl <= 0.5) {
            return Err(Error::param("cfl", self.cfl, "a number in (0, 0.5] (positivity of the depth)"));
        }
        check_positive("dry_depth", self.dry_depth)?;
        check_positive("max_dt", self.max_dt)?;
        if let Some(p) = &self.pore {
            check_positive("diffusivity", p.diffusivity)?;
            check_range("supply_ratio", p.supply_ratio, 0.0, 1.0)?;
            check_non_negative("supply_x_max", p.supply_x_max)?;
        }
        Ok(())
    }
}

/// minmod limiter.
#[inline]
fn minmod(a: f64, b: f64) -> f64 {
    if a * b <= 0.0 {
        0.0
    } else if a.abs() < b.abs() {
        a
    } else {
        b
    }
}

/// The depth-averaged model: configuration, state (with ghosts) and work arrays.
pub struct DepthAveragedModel {
    cfg: DepthAveragedConfig,
    dx: f64,
    tan_b: f64,
    /// k of the effective stress.
    k_eff: f64,
    /// K g per cell (padded; K = k (1 − β̂) + β̂).
    kg: Vec<f64>,
    /// Depth h, n + 4 entries (2 ghosts each end).
    pub h: Array1<f64>,
    /// Discharge q = h u.
    pub q: Array1<f64>,
    /// The pore variable m (zero without pore pressure): ∫p_f dz/(ρ g) [m²], or h β with
    /// [`PoreTransport::BasalRatio`].
    pub m: Array1<f64>,
    /// Velocity u = q/h (0 where h < h_dry), refreshed after each step.
    pub u: Array1<f64>,
    /// Basal pore pressure ratio β = p_b/(ρ g h) (0 where h < h_dry), refreshed after each step.
    pub beta: Array1<f64>,
    /// Specific pore variable s = m/h (0 where h < h_dry).
    spec: Array1<f64>,
    /// Bed elevation b (ghosts mirrored).
    pub bed: Array1<f64>,
    // work: state at t_n (interior), slopes (padded), face fluxes (n + 1), centred bed term (n)
    h0: Vec<f64>,
    q0: Vec<f64>,
    m0: Vec<f64>,
    s_h: Vec<f64>,
    s_u: Vec<f64>,
    s_b: Vec<f64>,
    s_eta: Vec<f64>,
    f_h: Vec<f64>,
    f_m: Vec<f64>,
    f_q_left: Vec<f64>,
    f_q_right: Vec<f64>,
    bed_src: Vec<f64>,
    /// Simulated time [s].
    pub time: f64,
    /// Steps taken.
    pub step_count: u64,
    /// Last time step [s].
    pub last_dt: f64,
    land: Option<f64>,
}

impl DepthAveragedModel {
    /// Builds a model at rest with h = 0 everywhere (set the state with [`Self::set_state`]).
    pub fn new(cfg: DepthAveragedConfig) -> Result<Self> {
        cfg.validate()?;
        let n = cfg.cells;
        let p = n + 2 * GHOSTS;
        let z = || Array1::<f64>::zeros(p);
        Ok(DepthAveragedModel {
            dx: cfg.length / n as f64,
            k_eff: match cfg.earth_pressure {
                EarthPressure::Constant(k) => k,
                EarthPressure::SavageHutterActive { internal_friction_angle } => {
                    active_earth_pressure(internal_friction_angle.to_radians().tan(), cfg.basal_friction_angle.to_radians().tan())
                }
            },
            kg: vec![0.0; p], // set by refresh_primitive
            tan_b: cfg.basal_friction_angle.to_radians().tan(),
            h: z(),
            q: z(),
            m: z(),
            u: z(),
            beta: z(),
            spec: z(),
            bed: z(),
            h0: vec![0.0; n],
            q0: vec![0.0; n],
            m0: vec![0.0; n],
            s_h: vec![0.0; p],
            s_u: vec![0.0; p],
            s_b: vec![0.0; p],
            s_eta: vec![0.0; p],
            f_h: vec![0.0; n + 1],
            f_m: vec![0.0; n + 1],
            f_q_left: vec![0.0; n + 1],
            f_q_right: vec![0.0; n + 1],
            bed_src: vec![0.0; n],
            time: 0.0,
            step_count: 0,
            last_dt: 0.0,
            land: None,
            cfg,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &DepthAveragedConfig {
        &self.cfg
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.cfg.cells
    }

    /// Cell size Δx.
    pub fn dx(&self) -> f64 {
        self.dx
    }

    /// Centre of cell i (0-based, interior).
    pub fn x(&self, i: usize) -> f64 {
        (i as f64 + 0.5) * self.dx
    }

    /// Interior depth (n values).
    pub fn depth(&self) -> &[f64] {
        &self.h.as_slice().unwrap()[GHOSTS..GHOSTS + self.cfg.cells]
    }

    /// Interior velocity (n values).
    pub fn velocity(&self) -> &[f64] {
        &self.u.as_slice().unwrap()[GHOSTS..GHOSTS + self.cfg.cells]
    }

    /// Interior pore pressure ratio (n values).
    pub fn pore_ratio(&self) -> &[f64] {
        &self.beta.as_slice().unwrap()[GHOSTS..GHOSTS + self.cfg.cells]
    }

    /// Sets h, u and β (n values each; h ≥ 0, β in [0, 1], all finite): m = β h²/2 (h β with
    /// [`PoreTransport::BasalRatio`]). β is ignored (kept 0) without pore pressure. Time and step
    /// count are not reset.
    pub fn set_state(&mut self, h: &[f64], u: &[f64], beta: &[f64]) -> Result<()> {
        let n = self.cfg.cells;
        for (name, a) in [("h", h), ("u", u), ("beta", beta)] {
            if a.len() != n {
                return Err(Error::Shape { name: name.into(), got: vec![a.len()], expected: vec![n] });
            }
            if let Some(i) = a.iter().position(|v| !v.is_finite()) {
                return Err(Error::param(name, format!("non-finite value at index {i}"), "finite values"));
            }
        }
        if let Some(i) = h.iter().position(|&v| v < 0.0) {
            return Err(Error::param("h", format!("{} at index {i}", h[i]), "depths >= 0"));
        }
        if let Some(i) = beta.iter().position(|&v| !(0.0..=1.0).contains(&v)) {
            return Err(Error::param("beta", format!("{} at index {i}", beta[i]), "ratios in [0, 1]"));
        }
        for i in 0..n {
            let k = i + GHOSTS;
            let wet = h[i] >= self.cfg.dry_depth;
            self.h[k] = h[i];
            self.q[k] = if wet { h[i] * u[i] } else { 0.0 };
            self.m[k] = match self.cfg.pore {
                Some(p) if wet => match p.transport {
                    PoreTransport::DepthIntegrated => 0.5 * beta[i] * h[i] * h[i],
                    PoreTransport::BasalRatio => beta[i] * h[i],
                },
                _ => 0.0,
            };
        }
        self.apply_supply();
        self.refresh_primitive();
        Ok(())
    }

    /// Sets the bed elevation b (n finite values).
    pub fn set_bed(&mut self, b: &[f64]) -> Result<()> {
        let n = self.cfg.cells;
        if b.len() != n {
            return Err(Error::Shape { name: "bed".into(), got: vec![b.len()], expected: vec![n] });
        }
        if let Some(i) = b.iter().position(|v| !v.is_finite()) {
            return Err(Error::param("bed", format!("non-finite value at index {i}"), "finite values"));
        }
        for (dst, &v) in self.bed.iter_mut().skip(GHOSTS).zip(b) {
            *dst = v;
        }
        for g in 0..GHOSTS {
            self.bed[GHOSTS - 1 - g] = self.bed[GHOSTS + g];
            self.bed[GHOSTS + n + g] = self.bed[GHOSTS + n - 1 - g];
        }
        Ok(())
    }

    /// Caps the next steps so that the clock lands on `time + remaining` (None: no cap).
    pub fn set_time_to_land(&mut self, remaining: Option<f64>) {
        self.land = remaining;
    }

    /// Volume per unit width Σ h Δx [m²].
    pub fn mass(&self) -> f64 {
        self.depth().iter().sum::<f64>() * self.dx
    }

    /// Largest |u| over the cells.
    pub fn max_speed(&self) -> f64 {
        self.velocity().iter().fold(0.0, |a, &v| a.max(v.abs()))
    }

    /// Front: the largest x where h crosses `threshold`, walking from the wall while h > threshold
    /// (linear interpolation between the last cell above it and the next one); 0 if h ≤ threshold
    /// in the first cell.
    pub fn front(&self, threshold: f64) -> f64 {
        let h = self.depth();
        let n = h.len();
        let mut last = None;
        for (i, &v) in h.iter().enumerate() {
            if v > threshold {
                last = Some(i);
            } else if last.is_some() {
                break;
            }
        }
        match last {
            None => 0.0,
            Some(i) if i + 1 == n => self.cfg.length,
            Some(i) => self.x(i) + self.dx * (h[i] - threshold) / (h[i] - h[i + 1]),
        }
    }

    /// Mirrors the state into the ghost cells (reflective walls at both ends).
    fn fill_ghosts(&mut self) {
        let n = self.cfg.cells;
        for g in 0..GHOSTS {
            let (gl, il) = (GHOSTS - 1 - g, GHOSTS + g);
            let (gr, ir) = (GHOSTS + n + g, GHOSTS + n - 1 - g);
            self.h[gl] = self.h[il];
            self.q[gl] = -self.q[il];
            self.m[gl] = self.m[il];
            self.h[gr] = self.h[ir];
            self.q[gr] = -self.q[ir];
            self.m[gr] = self.m[ir];
        }
    }

    /// β of the pore variable m over a wet depth h.
    #[inline]
    fn beta_of(&self, m: f64, h: f64) -> f64 {
        match self.cfg.pore {
            None => 0.0,
            Some(p) => match p.transport {
                PoreTransport::DepthIntegrated => 2.0 * m / (h * h),
                PoreTransport::BasalRatio => m / h,
            },
        }
    }

    /// u, s, β and K g from (h, q, m) everywhere (ghosts included).
    fn refresh_primitive(&mut self) {
        let (hd, g) = (self.cfg.dry_depth, self.cfg.gravity);
        for k in 0..self.h.len() {
            let h = self.h[k];
            if h >= hd {
                self.u[k] = self.q[k] / h;
                self.spec[k] = self.m[k] / h;
                self.beta[k] = self.beta_of(self.m[k], h);
            } else {
                self.u[k] = 0.0;
                self.spec[k] = 0.0;
                self.beta[k] = 0.0;
            }
            self.kg[k] = g * lateral_pressure(self.k_eff, self.beta[k]);
        }
    }

    /// The earth-pressure coefficient k of the effective stress.
    pub fn effective_earth_pressure(&self) -> f64 {
        self.k_eff
    }

    /// Lateral pressure coefficient K = k (1 − β̂) + β̂ of the cells (n values).
    pub fn earth_pressure(&self) -> impl Iterator<Item = f64> + '_ {
        self.kg[GHOSTS..GHOSTS + self.cfg.cells].iter().map(move |v| v / self.cfg.gravity)
    }

    /// Reconstructs and computes the face fluxes of the current state; returns the largest
    /// wave speed |S| over the faces.
    fn fluxes(&mut self) -> f64 {
        self.fill_ghosts();
        self.refresh_primitive();
        let n = self.cfg.cells;
        // slopes of padded cells 1 ..= n + 2 (those adjacent to a face)
        for k in 1..n + 2 * GHOSTS - 1 {
            let (a, b, c) = (k - 1, k, k + 1);
            self.s_h[k] = minmod(self.h[b] - self.h[a], self.h[c] - self.h[b]);
            self.s_u[k] = minmod(self.u[b] - self.u[a], self.u[c] - self.u[b]);
            self.s_b[k] = minmod(self.spec[b] - self.spec[a], self.spec[c] - self.spec[b]);
            let (ea, eb, ec) = (self.h[a] + self.bed[a], self.h[b] + self.bed[b], self.h[c] + self.bed[c]);
            self.s_eta[k] = minmod(eb - ea, ec - eb);
        }
        let mut smax = 0.0_f64;
        for f in 0..=n {
            let (l, r) = (f + GHOSTS - 1, f + GHOSTS);
            let h_l = self.h[l] + 0.5 * self.s_h[l];
            let h_r = self.h[r] - 0.5 * self.s_h[r];
            let b_l = self.h[l] + self.bed[l] + 0.5 * self.s_eta[l] - h_l;
            let b_r = self.h[r] + self.bed[r] - 0.5 * self.s_eta[r] - h_r;
            let (u_l, u_r) = (self.u[l] + 0.5 * self.s_u[l], self.u[r] - 0.5 * self.s_u[r]);
            let (sp_l, sp_r) = (self.spec[l] + 0.5 * self.s_b[l], self.spec[r] - 0.5 * self.s_b[r]);
            // hydrostatic reconstruction
            let b_face = b_l.max(b_r);
            let hs_l = (h_l + b_l - b_face).max(0.0);
            let hs_r = (h_r + b_r - b_face).max(0.0);
            let (kg_l, kg_r) = (self.kg[l], self.kg[r]);
            let (fh, fq, s) = hll(hs_l, u_l, kg_l, hs_r, u_r, kg_r);
            smax = smax.max(s);
            let fh = if u_l == 0.0 && u_r == 0.0 { 0.0 } else { fh };
            self.f_h[f] = fh;
            self.f_m[f] = fh * if fh > 0.0 { sp_l } else { sp_r };
            self.f_q_left[f] = fq + 0.5 * kg_l * (h_l * h_l - hs_l * hs_l);
            self.f_q_right[f] = fq + 0.5 * kg_r * (h_r * h_r - hs_r * hs_r);
        }
        for i in 0..n {
            let k = i + GHOSTS;
            self.bed_src[i] = -self.kg[k] * self.h[k] * (self.s_eta[k] - self.s_h[k]);
        }
        smax
    }

    /// U ← a U⁰ + (1 − a) (U − Δt/Δx ΔF + Δt S), using the fluxes just computed.
    fn update(&mut self, dt: f64, a: f64) {
        let n = self.cfg.cells;
        let r = dt / self.dx;
        for i in 0..n {
            let k = i + GHOSTS;
            let h1 = self.h[k] - r * (self.f_h[i + 1] - self.f_h[i]);
            let q1 = self.q[k] - r * (self.f_q_left[i + 1] - self.f_q_right[i] - self.bed_src[i]);
            let m1 = self.m[k] - r * (self.f_m[i + 1] - self.f_m[i]);
            self.h[k] = a * self.h0[i] + (1.0 - a) * h1;
            self.q[k] = a * self.q0[i] + (1.0 - a) * q1;
            self.m[k] = a * self.m0[i] + (1.0 - a) * m1;
        }
    }

    /// Coulomb friction as a projection with the impulse budget of `tau` seconds; dry cells
    /// (h < h_dry) get q = 0; depths below zero by round-off (> −1e-14 max h) are set to 0.
    fn friction(&mut self, tau: f64) {
        let n = self.cfg.cells;
        let (g, hd) = (self.cfg.gravity, self.cfg.dry_depth);
        for i in 0..n {
            let k = i + GHOSTS;
            let h = self.h[k];
            if h < hd {
                self.q[k] = 0.0;
                continue;
            }
            let beta = self.beta_of(self.m[k], h);
            let j = tau * g * h * self.tan_b * (1.0 - beta).max(0.0);
            let q = self.q[k];
            self.q[k] = if q.abs() <= j { 0.0 } else { q - j * q.signum() };
        }
    }

    /// [`PoreTransport::BasalRatio`]: β ≥ β_s on the wet cells under the supply.
    fn apply_supply(&mut self) {
        if let Some(p) = self.cfg.pore {
            if p.transport != PoreTransport::BasalRatio {
                return;
            }
            for i in 0..self.cfg.cells {
                let k = i + GHOSTS;
                if self.x(i) < p.supply_x_max && self.h[k] >= self.cfg.dry_depth {
                    self.m[k] = self.m[k].max(p.supply_ratio * self.h[k]);
                }
            }
        }
    }

    /// The pore source over Δt, exact for frozen h: m ← m_eq + (m − m_eq) e^{−2κΔt/h²}
    /// (m_eq = ½ β_s h² under the supply, else 0); [`PoreTransport::BasalRatio`]:
    /// m ← m e^{−Δt π²κ/4h²}, then the supply. Cells thinner than h_dry get m = 0.
    fn pore_relaxation(&mut self, dt: f64) {
        if let Some(p) = self.cfg.pore {
            let hd = self.cfg.dry_depth;
            for i in 0..self.cfg.cells {
                let k = i + GHOSTS;
                let h = self.h[k];
                if h < hd {
                    self.m[k] = 0.0;
                    continue;
                }
                self.m[k] = match p.transport {
                    PoreTransport::DepthIntegrated => {
                        let eq = if self.x(i) < p.supply_x_max { 0.5 * p.supply_ratio * h * h } else { 0.0 };
                        eq + (self.m[k] - eq) * (-2.0 * p.diffusivity * dt / (h * h)).exp()
                    }
                    PoreTransport::BasalRatio => {
                        let rate = std::f64::consts::PI.powi(2) * p.diffusivity / 4.0;
                        self.m[k] * (-dt * rate / (h * h)).exp()
                    }
                };
            }
            self.apply_supply();
        }
    }

    /// Non-finite values or a negative depth: the first bad cell.
    fn check(&self) -> Result<()> {
        let hmax = self.depth().iter().fold(0.0_f64, |a, &v| a.max(v));
        for i in 0..self.cfg.cells {
            let k = i + GHOSTS;
            let (h, q, m) = (self.h[k], self.q[k], self.m[k]);
            let what = if !(h.is_finite() && q.is_finite() && m.is_finite()) {
                format!("non-finite state (h = {h}, hu = {q}, pore variable m = {m})")
            } else if h < -1e-14 * hmax {
                format!("negative depth h = {h:e} (reduce cfl)")
            } else {
                continue;
            };
            return Err(Error::Simulation { what, step: self.step_count, time: self.time, location: Some((i, 0)) });
        }
        Ok(())
    }

    /// One SSP-RK2 step with friction projections, pore-pressure relaxation and checks.
    /// Returns Δt.
    pub fn step(&mut self) -> Result<f64> {
        let n = self.cfg.cells;
        for i in 0..n {
            let k = i + GHOSTS;
            self.h0[i] = self.h[k];
            self.q0[i] = self.q[k];
            self.m0[i] = self.m[k];
        }
        let smax = self.fluxes();
        let mut dt = if smax > 0.0 { (self.cfg.cfl * self.dx / smax).min(self.cfg.max_dt) } else { self.cfg.max_dt };
        if let Some(rem) = self.land {
            dt = dt.min(rem);
        }
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::Simulation {
                what: format!("time step {dt:e} (largest wave speed {smax:e})"),
                step: self.step_count,
                time: self.time,
                location: None,
            });
        }
        // stage 1: U¹ = P_Δt(Uⁿ + Δt L(Uⁿ))
        self.update(dt, 0.0);
        self.friction(dt);
        self.clip_round_off();
        // stage 2: Uⁿ⁺¹ = P_Δt/2(½ Uⁿ + ½ (U¹ + Δt L(U¹)))
        self.fluxes();
        self.update(dt, 0.5);
        self.friction(0.5 * dt);
        self.clip_round_off();
        self.pore_relaxation(dt);
        self.refresh_primitive();
        self.time += dt;
        self.step_count += 1;
        self.last_dt = dt;
        self.check()?;
        Ok(dt)
    }

    /// Sets depths in (−1e-14 max h, 0) to 0 (round-off of the positivity-preserving update).
    fn clip_round_off(&mut self) {
        let hmax = self.depth().iter().fold(0.0_f64, |a, &v| a.max(v));
        for k in GHOSTS..GHOSTS + self.cfg.cells {
            if self.h[k] < 0.0 && self.h[k] > -1e-14 * hmax {
                self.h[k] = 0.0;
                self.q[k] = 0.0;
                self.m[k] = 0.0;
            }
        }
    }

    /// Steps until `t_end` (the last step lands on it) or `max_steps`; returns the steps taken.
    pub fn advance(&mut self, t_end: f64, max_steps: u64) -> Result<u64> {
        let mut taken = 0;
        let result = loop {
            let remaining = t_end - self.time;
            if remaining <= 1e-12 * t_end.abs().max(1e-300) || taken >= max_steps {
                break Ok(taken);
            }
            self.land = Some(remaining);
            if let Err(e) = self.step() {
                break Err(e);
            }
            taken += 1;
        };
        self.land = None;
        result
    }
}

/// HLL flux of (h, h u) between two hydrostatically reconstructed states, each with its own
/// k g (c = √(k g h)); returns (F_h, F_q, max |S|). Dry sides use the dry-bed speeds u ± 2c.
#[inline]
fn hll(h_l: f64, u_l: f64, kg_l: f64, h_r: f64, u_r: f64, kg_r: f64) -> (f64, f64, f64) {
    if h_l <= 0.0 && h_r <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    let (c_l, c_r) = ((kg_l * h_l).sqrt(), (kg_r * h_r).sqrt());
    let (s_l, s_r) = if h_l <= 0.0 {
        (u_r - 2.0 * c_r, u_r + c_r)
    } else if h_r <= 0.0 {
        (u_l - c_l, u_l + 2.0 * c_l)
    } else {
        ((u_l - c_l).min(u_r - c_r), (u_l + c_l).max(u_r + c_r))
    };
    let (q_l, q_r) = (h_l * u_l, h_r * u_r);
    let (fh_l, fq_l) = (q_l, q_l * u_l + 0.5 * kg_l * h_l * h_l);
    let (fh_r, fq_r) = (q_r, q_r * u_r + 0.5 * kg_r * h_r * h_r);
    let s = s_l.abs().max(s_r.abs());
    if s_l >= 0.0 {
        (fh_l, fq_l, s)
    } else if s_r <= 0.0 {
        (fh_r, fq_r, s)
    } else {
        let d = 1.0 / (s_r - s_l);
        ((s_r * fh_l - s_l * fh_r + s_l * s_r * (h_r - h_l)) * d, (s_r * fq_l - s_l * fq_r + s_l * s_r * (q_r - q_l)) * d, s)
    }
}
