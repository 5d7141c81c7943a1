//! Boundary conditions per side of the rectangular domain, and the ghost-cell rules that
//! impose them on MAC velocity fields.
//!
//! Normal velocity lives on the boundary itself (u on x = 0 and x = Lx, v on y = 0 and y = Ly);
//! the tangential velocity lives half a cell inside, and its ghost values encode the condition:
//!
//! | condition | tangential ghost (k = 1..HALO)          | normal velocity on the wall |
//! |-----------|-----------------------------------------|-----------------------------|
//! | no-slip   | u_t(−k) = −u_t(k−1)                     | 0                           |
//! | free-slip | u_t(−k) = u_t(k−1)                      | 0                           |
//! | velocity  | u_t(−k) = 2U − u_t(k−1)                 | prescribed (into the domain)|
//! | Navier    | u_t(−1) = c u_t(0), c = (b/h − ½)/(b/h + ½) (u_t = b ∂u_t/∂n at the wall) | 0 |
//! | outflow   | u_t(−k) = u_t(k−1) (∂u_t/∂n = 0)        | unknown, ∂u_n/∂n = 0, p = 0 |
//! | Coulomb   | as free-slip; the friction stress σ_t = τ_b s is added as a wall flux by the rheology (eq. 8–9) | 0 |
//! | fully developed (pairs) | periodic with the opposite side   | periodic (face n = face 0), ∂p/∂n = 0 |
//!
//! *Fully developed* sides come in opposite pairs and stand in for periodic ones in flows that
//! are invariant along the normal (channels, layers on an incline): the velocity is periodic
//! between them, the pressure has a zero normal gradient, so a hydrostatic pressure that varies
//! along the side is allowed (an outflow side would pin it to 0) while the pressure solver keeps
//! its Neumann form. Exact for flows invariant along the normal.
//!
//! The pressure (and pressure increment) sees homogeneous Neumann on every side except outflow,
//! where it is Dirichlet: p = p_b on the boundary, p_b = 0 unless an outlet pressure is set
//! ([`BoundaryConditions::with_outlet_pressure`]: a value linear along the side, such as the
//! ambient air's hydrostatic pressure on the open side of an active window), and δp = 0.

use crate::error::{Error, Result};

/// A side of the rectangular domain.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    Left,
    Right,
    Bottom,
    Top,
}

impl Side {
    /// All four sides in the storage order of [`BoundaryConditions`].
    pub const ALL: [Side; 4] = [Side::Left, Side::Right, Side::Bottom, Side::Top];

    /// Lower-case name used in Python and the docs.
    pub fn name(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
            Side::Bottom => "bottom",
            Side::Top => "top",
        }
    }

    /// Whether the side is normal to x (left/right).
    pub fn is_x(self) -> bool {
        matches!(self, Side::Left | Side::Right)
    }

    fn index(self) -> usize {
        match self {
            Side::Left => 0,
            Side::Right => 1,
            Side::Bottom => 2,
            Side::Top => 3,
        }
    }
}

/// Velocity boundary condition on one side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VelocityBc {
    /// u = 0.
    NoSlip,
    /// u·n = 0, zero tangential stress.
    FreeSlip,
    /// Prescribed velocity: `normal` is the inflow speed (positive into the domain), `tangential`
    /// the wall speed along the side (positive along +x or +y). A lid is `normal = 0`.
    Velocity { normal: f64, tangential: f64 },
    /// u·n = 0 and u_t = slip_length ∂u_t/∂n.
    NavierSlip { slip_length: f64 },
    /// Open boundary: zero normal gradient of velocity, pressure p = 0.
    Outflow,
    /// Coulomb friction wall for the granular phase (paper eq. 8–9): impermeable, with the
    /// tangential stress supplied by the friction projection; behaves as free-slip in air.
    Coulomb,
    /// Fully developed in/outflow, on two opposite sides: velocity periodic between them, zero
    /// normal gradient of the pressure (exact for flows invariant along the normal).
    FullyDeveloped,
}

impl VelocityBc {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            VelocityBc::NoSlip => "no-slip",
            VelocityBc::FreeSlip => "free-slip",
            VelocityBc::Velocity { .. } => "velocity",
            VelocityBc::NavierSlip { .. } => "navier",
            VelocityBc::Outflow => "outflow",
            VelocityBc::Coulomb => "coulomb",
            VelocityBc::FullyDeveloped => "fully-developed",
        }
    }

    /// Normal velocity on the boundary, positive into the domain (0 for walls; None for outflow,
    /// where it is an unknown).
    pub fn normal_inflow(&self) -> Option<f64> {
        match self {
            VelocityBc::Velocity { normal, .. } => Some(*normal),
            VelocityBc::Outflow | VelocityBc::FullyDeveloped => None,
            _ => Some(0.0),
        }
    }

    /// Whether the normal velocity on the side is an unknown (outflow, fully developed).
    pub fn normal_is_unknown(&self) -> bool {
        matches!(self, VelocityBc::Outflow | VelocityBc::FullyDeveloped)
    }

    /// Ghost-value rule for the tangential component: ghost(−1) = a·interior(0) + b, where
    /// `h` is the cell size normal to the side.
    pub fn tangential_ghost(&self, h: f64) -> (f64, f64) {
        match *self {
            VelocityBc::NoSlip => (-1.0, 0.0),
            VelocityBc::FreeSlip | VelocityBc::Outflow | VelocityBc::Coulomb | VelocityBc::FullyDeveloped => (1.0, 0.0),
            VelocityBc::Velocity { tangential, .. } => (-1.0, 2.0 * tangential),
            VelocityBc::NavierSlip { slip_length } => {
                let r = slip_length / h;
                ((r - 0.5) / (r + 0.5), 0.0)
            }
        }
    }
}

/// Pressure boundary condition implied by a velocity condition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PressureBc {
    /// ∂p/∂n = 0 (walls, prescribed velocity).
    Neumann,
    /// p = p_b on the boundary (outflow; p_b = 0 unless an outlet pressure is set).
    Dirichlet,
}

/// The velocity conditions on the four sides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryConditions {
    /// Conditions in the order left, right, bottom, top.
    pub sides: [VelocityBc; 4],
    /// Pressure on the boundary of each outflow side, linear along it: `[a, b]` gives
    /// p_b = a + b·k at the k-th cell centre along the side (k from 0, along +y on left/right,
    /// +x on bottom/top). Zero by default; read only on outflow sides.
    pub outlet_pressure: [[f64; 2]; 4],
    /// Backflow stabilisation of each outflow side (read only there): on a boundary face where
    /// the flow enters (outward normal velocity u·n < 0) the boundary pressure of the predictor
    /// is lowered by the normal dynamic pressure, p_b − ½ρ(u·n)², the normal part of the
    /// directional do-nothing condition (Braack & Mucha 2014, *J. Comput. Math.* 32; Bazilevs et
    /// al. 2009, *CMAME* 198): fluid entering from an ambient reservoir at p_b pays its dynamic
    /// pressure, so an open side no longer feeds kinetic energy into the domain where air flows
    /// back in ([`crate::projection::add_backflow_pressure`]). `false` by default.
    pub backflow: [bool; 4],
}

impl BoundaryConditions {
    /// The same condition on every side.
    pub fn uniform(bc: VelocityBc) -> Self {
        BoundaryConditions { sides: [bc; 4], outlet_pressure: [[0.0; 2]; 4], backflow: [false; 4] }
    }

    /// Builder: the boundary pressure of an outflow `side`, p_b = `at_first` + `per_cell`·k at the
    /// k-th cell along it (see [`BoundaryConditions::outlet_pressure`]).
    pub fn with_outlet_pressure(mut self, side: Side, at_first: f64, per_cell: f64) -> Self {
        self.outlet_pressure[side.index()] = [at_first, per_cell];
        self
    }

    /// Builder: backflow stabilisation of the outflow `side` (see [`BoundaryConditions::backflow`]).
    pub fn with_backflow_stabilisation(mut self, side: Side) -> Self {
        self.backflow[side.index()] = true;
        self
    }

    /// Whether `side` is an outflow side with backflow stabilisation.
    #[inline]
    pub fn backflow_on(&self, side: Side) -> bool {
        self.backflow[side.index()] && self.pressure(side) == PressureBc::Dirichlet
    }

    /// The boundary pressure of `side` at position `k` along it (cells, k = 0 the first centre):
    /// 0 on sides that are not outflow.
    #[inline]
    pub fn outlet_pressure_at(&self, side: Side, k: f64) -> f64 {
        if self.pressure(side) != PressureBc::Dirichlet {
            return 0.0;
        }
        let [a, b] = self.outlet_pressure[side.index()];
        a + b * k
    }

    /// Builder: sets one side.
    pub fn with(mut self, side: Side, bc: VelocityBc) -> Self {
        self.sides[side.index()] = bc;
        self
    }

    /// The condition on `side`.
    pub fn get(&self, side: Side) -> VelocityBc {
        self.sides[side.index()]
    }

    /// Pressure condition on `side`.
    pub fn pressure(&self, side: Side) -> PressureBc {
        match self.get(side) {
            VelocityBc::Outflow => PressureBc::Dirichlet,
            _ => PressureBc::Neumann,
        }
    }

    /// Pressure conditions in the order left, right, bottom, top.
    pub fn pressure_all(&self) -> [PressureBc; 4] {
        Side::ALL.map(|s| self.pressure(s))
    }

    /// Whether the pressure is only defined up to a constant (no Dirichlet side).
    pub fn pressure_is_singular(&self) -> bool {
        Side::ALL.iter().all(|&s| self.pressure(s) == PressureBc::Neumann)
    }

    /// Checks parameters and the compatibility of the four conditions on a domain of size
    /// `lx × ly`: finite values, positive slip lengths, and, for a closed domain, zero net inflow
    /// (otherwise div u = 0 has no solution).
    pub fn validate(&self, lx: f64, ly: f64) -> Result<()> {
        let mut net_inflow = 0.0;
        for side in Side::ALL {
            let name = |what: &str| format!("bc.{}.{}", side.name(), what);
            match self.get(side) {
                VelocityBc::Velocity { normal, tangential } => {
                    if !normal.is_finite() {
                        return Err(Error::param(&name("normal"), normal, "a finite velocity"));
                    }
                    if !tangential.is_finite() {
                        return Err(Error::param(&name("tangential"), tangential, "a finite velocity"));
                    }
                    net_inflow += normal * if side.is_x() { ly } else { lx };
                }
                VelocityBc::NavierSlip { slip_length } if !(slip_length.is_finite() && slip_length > 0.0) => {
                    return Err(Error::param(&name("slip_length"), slip_length, "a finite length > 0"));
                }
                _ => {}
            }
            let [a, b] = self.outlet_pressure[side.index()];
            if !(a.is_finite() && b.is_finite()) {
                return Err(Error::param(&name("outlet_pressure"), format!("[{a}, {b}]"), "finite values (Pa, Pa per cell)"));
            }
        }
        for (a, b) in [(Side::Left, Side::Right), (Side::Bottom, Side::Top)] {
            if (self.get(a) == VelocityBc::FullyDeveloped) != (self.get(b) == VelocityBc::FullyDeveloped) {
                return Err(Error::param(
                    &format!("bc.{}", if self.get(a) == VelocityBc::FullyDeveloped { a.name() } else { b.name() }),
                    "fully-developed",
                    &format!("fully-developed on both {} and {} (the velocity is periodic between them)", a.name(), b.name()),
                ));
            }
        }
        if self.pressure_is_singular() && net_inflow.abs() > 1e-12 * (lx + ly) {
            return Err(Error::param(
                "bc",
                format!("net inflow {net_inflow:.3e} m²/s through a closed domain"),
                "zero net inflow unless one side is `outflow` (div u = 0 has no solution otherwise)",
            ));
        }
        Ok(())
    }
}
