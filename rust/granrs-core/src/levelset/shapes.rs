//! Initial shapes of the dense phase and their signed distance functions (paper §2.4: "at time
//! t = 0, the level-set function is initialised as the signed distance to the interface").
//!
//! Equation:  Φ(x) = +dist(x, ∂D) for x ∈ D (dense), −dist(x, ∂D) outside, with
//! dist(x, ∂D) = min_{y ∈ ∂D} |x − y|.
//!
//! Exactness:
//! - `Rectangle`, `Circle`, `HalfPlane`, `SlottedDisk` are exact distance functions (the slotted
//!   disk computes the distance to each piece of its boundary: the arc, its two end points, the
//!   two slot sides and the slot top — Zalesak 1979's disk).
//! - `Union(a, b, …)` uses Φ = max(Φ_a, Φ_b, …) and `Difference(a, b)` uses Φ = min(Φ_a, −Φ_b).
//!   Their sign, and so their zero level set, is exact; the magnitude is exact wherever the
//!   nearest boundary point of the combination lies on a single piece *and* that piece's
//!   distance is the active one, which fails near the new corners (outside a union near a
//!   concave corner, inside a difference near a convex one), where |Φ| under-estimates the
//!   distance. Apply [`super::Redistancer`] after the initialisation when that matters.
//!
//! Evaluated at the cell centres, an exact distance function puts the zero level set of the
//! piecewise-linear interpolant exactly on straight interfaces, wherever they cut the cells: the
//! paper's 0.2 m × 0.4 m column on h = 0.45/256 m (113.8 × 227.6 cells) sits at x = 0.2, y = 0.4.

use crate::error::{check_finite, check_positive, Error, Result};
use crate::grid::{Field, Grid, Location, HALO};

/// A region of the plane occupied by the dense phase.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// The axis-aligned rectangle (x0, x1) × (y0, y1).
    Rectangle { x0: f64, x1: f64, y0: f64, y1: f64 },
    /// The disk of centre (xc, yc).
    Circle { xc: f64, yc: f64, radius: f64 },
    /// Zalesak's slotted disk: the disk minus the vertical slot |x − xc| ≤ slot_width/2,
    /// y ≤ slot_top (the slot is open at the bottom of the disk).
    SlottedDisk { xc: f64, yc: f64, radius: f64, slot_width: f64, slot_top: f64 },
    /// The half-plane {(x − px, y − py)·n ≤ 0} below the line through (px, py) with normal
    /// (nx, ny) pointing into the light phase; n need not be unit. A flat layer of height H is
    /// `HalfPlane { px: 0.0, py: H, nx: 0.0, ny: 1.0 }`; tilt n for an inclined layer.
    HalfPlane { px: f64, py: f64, nx: f64, ny: f64 },
    /// The union of shapes (Φ = max Φ_k).
    Union(Vec<Shape>),
    /// The first shape minus the second (Φ = min(Φ_a, −Φ_b)).
    Difference(Box<Shape>, Box<Shape>),
}

impl Shape {
    /// Checks the parameters (finite, positive sizes, non-empty union, slot inside the disk).
    pub fn validate(&self) -> Result<()> {
        match self {
            Shape::Rectangle { x0, x1, y0, y1 } => {
                for (n, v) in [("x0", x0), ("x1", x1), ("y0", y0), ("y1", y1)] {
                    check_finite(n, *v)?;
                }
                check_positive("x1 - x0", x1 - x0)?;
                check_positive("y1 - y0", y1 - y0)
            }
            Shape::Circle { xc, yc, radius } => {
                check_finite("xc", *xc)?;
                check_finite("yc", *yc)?;
                check_positive("radius", *radius)
            }
            Shape::SlottedDisk { xc, yc, radius, slot_width, slot_top } => {
                check_finite("xc", *xc)?;
                check_finite("yc", *yc)?;
                check_positive("radius", *radius)?;
                if !(slot_width.is_finite() && *slot_width > 0.0 && *slot_width < 2.0 * radius) {
                    return Err(Error::param("slot_width", slot_width, "a number in (0, 2·radius)"));
                }
                let hw = 0.5 * slot_width;
                let ymax = yc + (radius * radius - hw * hw).sqrt();
                let ymin = yc - (radius * radius - hw * hw).sqrt();
                if !(slot_top.is_finite() && *slot_top > ymin && *slot_top < ymax) {
                    return Err(Error::param("slot_top", slot_top, &format!("a number in ({ymin}, {ymax}) (the slot top inside the disk)")));
                }
                Ok(())
            }
            Shape::HalfPlane { px, py, nx, ny } => {
                check_finite("px", *px)?;
                check_finite("py", *py)?;
                check_positive("|(nx, ny)|", nx.hypot(*ny))
            }
            Shape::Union(v) => {
                if v.is_empty() {
                    return Err(Error::param("Union", "[]", "at least one shape"));
                }
                v.iter().try_for_each(Shape::validate)
            }
            Shape::Difference(a, b) => {
                a.validate()?;
                b.validate()
            }
        }
    }

    /// Signed distance at (x, y): positive inside (dense phase), negative outside.
    pub fn signed_distance(&self, x: f64, y: f64) -> f64 {
        match self {
            Shape::Rectangle { x0, x1, y0, y1 } => rectangle_sd(x, y, *x0, *x1, *y0, *y1),
            Shape::Circle { xc, yc, radius } => radius - (x - xc).hypot(y - yc),
            Shape::SlottedDisk { xc, yc, radius, slot_width, slot_top } => slotted_disk_sd(x, y, *xc, *yc, *radius, *slot_width, *slot_top),
            Shape::HalfPlane { px, py, nx, ny } => {
                let n = nx.hypot(*ny);
                -((x - px) * nx + (y - py) * ny) / n
            }
            Shape::Union(v) => v.iter().map(|s| s.signed_distance(x, y)).fold(f64::NEG_INFINITY, f64::max),
            Shape::Difference(a, b) => a.signed_distance(x, y).min(-b.signed_distance(x, y)),
        }
    }

    /// Whether (x, y) lies in the dense phase (Φ > 0).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        self.signed_distance(x, y) > 0.0
    }

    /// Exact area of the shape when it is known in closed form (rectangle, circle, slotted disk);
    /// `None` for half-planes and combinations.
    pub fn area(&self) -> Option<f64> {
        match self {
            Shape::Rectangle { x0, x1, y0, y1 } => Some((x1 - x0) * (y1 - y0)),
            Shape::Circle { radius, .. } => Some(std::f64::consts::PI * radius * radius),
            Shape::SlottedDisk { radius, slot_width, slot_top, yc, .. } => {
                // disk − ∫_{−w/2}^{w/2} (slot_top − (yc − √(r² − s²))) ds
                let (r, a) = (*radius, 0.5 * slot_width);
                let chord = a * (r * r - a * a).sqrt() + r * r * (a / r).asin();
                Some(std::f64::consts::PI * r * r - (2.0 * a * (slot_top - yc) + chord))
            }
            _ => None,
        }
    }
}

fn rectangle_sd(x: f64, y: f64, x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    // Distances outside each slab (≤ 0 inside it).
    let dx = (x0 - x).max(x - x1);
    let dy = (y0 - y).max(y - y1);
    if dx <= 0.0 && dy <= 0.0 {
        -(dx.max(dy)) // inside: distance to the nearest edge
    } else {
        -(dx.max(0.0).hypot(dy.max(0.0)))
    }
}

/// Distance from (x, y) to the segment (ax, ay)–(bx, by).
fn segment_distance(x: f64, y: f64, ax: f64, ay: f64, bx: f64, by: f64) -> f64 {
    let (ex, ey) = (bx - ax, by - ay);
    let t = (((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey)).clamp(0.0, 1.0);
    (x - ax - t * ex).hypot(y - ay - t * ey)
}

fn slotted_disk_sd(x: f64, y: f64, xc: f64, yc: f64, r: f64, w: f64, top: f64) -> f64 {
    let hw = 0.5 * w;
    let (xl, xr) = (xc - hw, xc + hw);
    // The slot cuts the circle at (xc ± hw, y_cut), on its lower half.
    let y_cut = yc - (r * r - hw * hw).sqrt();
    let in_slot = |px: f64, py: f64| (px - xc).abs() < hw && py < top;
    let rho = (x - xc).hypot(y - yc);
    let inside = rho < r && !in_slot(x, y);
    // Arc: the circle without its part inside the slot gap. If the radial projection of the
    // point falls in the gap, the nearest arc point is one of the two cut points.
    let d_arc = if rho > 0.0 {
        let (qx, qy) = (xc + r * (x - xc) / rho, yc + r * (y - yc) / rho);
        if (qx - xc).abs() < hw && qy < yc {
            (x - xl).hypot(y - y_cut).min((x - xr).hypot(y - y_cut))
        } else {
            (rho - r).abs()
        }
    } else {
        r
    };
    let d_left = segment_distance(x, y, xl, y_cut, xl, top);
    let d_right = segment_distance(x, y, xr, y_cut, xr, top);
    let d_top = segment_distance(x, y, xl, top, xr, top);
    let d = d_arc.min(d_left).min(d_right).min(d_top);
    if inside {
        d
    } else {
        -d
    }
}

/// Fills `phi` (a cell-centre field on `grid`) with the signed distance to `shape`, on the
/// interior and the ghost cells (evaluated at the ghosts' own centres).
pub fn init_signed_distance(shape: &Shape, grid: &Grid, phi: &mut Field) -> Result<()> {
    shape.validate()?;
    super::transport::check_field("phi", phi, grid, Location::Centre)?;
    let h = HALO as isize;
    for j in -h..grid.ny as isize + h {
        for i in -h..grid.nx as isize + h {
            let k = phi.idx(i, j);
            phi.slice_mut()[k] = shape.signed_distance(grid.xc(i), grid.yc(j));
        }
    }
    Ok(())
}
