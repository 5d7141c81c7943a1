//! The settings of the active region: each step runs on a window of the grid around the dense
//! phase instead of on the whole domain. The window itself (its equations, its sizing and the
//! transfer of the state) is `models/window.rs`.

use crate::error::{Error, Result};

/// Settings of the active window.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ActiveRegion {
    /// Cells of light phase kept between the dense phase and the window's right and top sides.
    pub band: usize,
    /// Window sizes are rounded up to a multiple of this many cells.
    pub align: usize,
    /// The window's right and top sides, where they lie inside the domain.
    pub sides: WindowSides,
}

/// The sides of an active window that lie inside the domain.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WindowSides {
    /// Right and top sides are walls (no normal flow).
    #[default]
    Walls,
    /// The right side is open: an outflow side at the ambient light phase's hydrostatic
    /// pressure, through which the air the advancing front pushes leaves W (no backflow
    /// stabilisation). The top is a wall.
    OpenRight,
    /// The right and top sides are open, both with backflow stabilisation (p_b − ½ρ(u·n)² where
    /// air enters, [`crate::grid::BoundaryConditions::backflow`]), which keeps an open top over
    /// the deposit from drawing jets.
    OpenRightTop,
}

impl WindowSides {
    /// Every value, in the order of the docs.
    pub const ALL: [WindowSides; 3] = [WindowSides::Walls, WindowSides::OpenRight, WindowSides::OpenRightTop];

    /// The value of a name (`None` for an unknown one).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            WindowSides::Walls => "walls",
            WindowSides::OpenRight => "open-right",
            WindowSides::OpenRightTop => "open-right-top",
        }
    }

    /// Whether the right side is open.
    pub fn right_open(self) -> bool {
        self != WindowSides::Walls
    }

    /// Whether the top side is open (and both open sides are stabilised).
    pub fn top_open(self) -> bool {
        self == WindowSides::OpenRightTop
    }
}

impl ActiveRegion {
    /// Checks the settings, naming the offending one.
    pub fn validate(&self) -> Result<()> {
        if !(2..=100_000).contains(&self.band) {
            return Err(Error::param("active_region.band", self.band, "an integer in [2, 100000] cells"));
        }
        if !(1..=4096).contains(&self.align) {
            return Err(Error::param("active_region.align", self.align, "an integer in [1, 4096] cells"));
        }
        Ok(())
    }
}
