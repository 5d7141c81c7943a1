//! The settings of the active region: each step runs on a window of the grid around the dense
//! phase instead of on the whole domain. The window itself (its equations, its sizing and the
//! transfer of the state) is `models/window.rs`.

use crate::error::Result;
use crate::options::{self, OptionSpec, Value};

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

/// The options of the active region (`ModelConfig::active_region`; `active_region` None: every
/// step on the whole domain).
pub const ACTIVE_REGION_OPTIONS: &[OptionSpec] = &[
    options::int("active_region", "active_region", 16, 2, 100_000, "cells", "run each step on a window around the dense phase with at least this many cells of light phase to its right and above (None: the whole domain)").off_by_default(),
    options::int("active_region", "active_region_align", 8, 1, 4096, "cells", "the window's sizes are multiples of this many cells (for the multigrid)"),
    options::choice("active_region", "active_region_sides", "walls", &["walls", "open-right", "open-right-top"], "the window's right and top sides inside the domain: walls; its right side open (outflow at the air's hydrostatic pressure); or both open with backflow stabilisation"),
];

impl ActiveRegion {
    /// Checks the settings against [`ACTIVE_REGION_OPTIONS`], naming the offending one.
    pub fn validate(&self) -> Result<()> {
        let o = |k| options::spec(ACTIVE_REGION_OPTIONS, k);
        o("active_region").check_named("active_region.band", &Value::Int(self.band.min(i64::MAX as usize) as i64))?;
        o("active_region_align").check_named("active_region.align", &Value::Int(self.align.min(i64::MAX as usize) as i64))?;
        Ok(())
    }

    /// The options of an optional active region.
    pub fn get_option(region: &Option<ActiveRegion>, key: &str) -> Value {
        let o = |k| options::spec(ACTIVE_REGION_OPTIONS, k);
        match (key, region) {
            ("active_region", None) => Value::None,
            ("active_region", Some(r)) => Value::Int(r.band.min(i64::MAX as usize) as i64),
            ("active_region_align", r) => Value::Int(r.map_or(o("active_region_align").usize(), |r| r.align) as i64),
            ("active_region_sides", r) => Value::str(r.map_or(o("active_region_sides").name(), |r| r.sides.name())),
            _ => Value::None,
        }
    }

    /// The optional active region of checked option values (`active_region` None: none).
    pub fn from_options(map: &options::OptionMap) -> Result<Option<ActiveRegion>> {
        let mut vals = Vec::new();
        for s in ACTIVE_REGION_OPTIONS {
            vals.push(s.check(map.get(s.key).unwrap_or(&s.default))?);
        }
        Ok(match &vals[0] {
            Value::None => None,
            band => Some(ActiveRegion {
                band: options::as_usize(band),
                align: options::as_usize(&vals[1]),
                sides: WindowSides::from_name(options::as_name(&vals[2])).unwrap_or_default(),
            }),
        })
    }
}
