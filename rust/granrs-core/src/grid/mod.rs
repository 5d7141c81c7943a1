//! Uniform Cartesian 2D grid with MAC (marker-and-cell) staggering, and the fields that live on it.
//!
//! Domain Ω = (x0, x0 + Lx) × (y0, y0 + Ly) split into nx × ny cells K_ij = (x_i, x_{i+1}) × (y_j, y_{j+1})
//! of size dx × dy (Aravena et al., §3.2, Figure 3). Unknowns:
//!
//! ```text
//!        +------- v(i,j+1) -------+        Centre  (i+½, j+½): p, p_f, Φ, ρ, η, Σ_xx   nx   × ny
//!        |                        |        XFace   (i,   j+½): u                       nx+1 × ny
//!     u(i,j)     c(i,j)        u(i+1,j)    YFace   (i+½, j  ): v                       nx   × ny+1
//!        |                        |        Node    (i,   j  ): Σ_xy, D_xy              nx+1 × ny+1
//!      n(i,j) ---- v(i,j) ------ n(i+1,j)
//! ```
//!
//! Every field is stored row-major (index `[j][i]`, rows along x) with [`HALO`] ghost layers on
//! each side, wide enough for the WENO5 stencil. Interior index (i, j) of a field sits at array
//! position `[j + HALO][i + HALO]`. Arrays are allocated once and never reallocated, so views
//! handed to Python stay valid for the life of the model.

pub mod bc;

use crate::error::{check_finite, check_positive, Error, Result};
use ndarray::Array2;

pub use bc::{BoundaryConditions, PressureBc, Side, VelocityBc};

/// Number of ghost layers around every field (WENO5 needs three).
pub const HALO: usize = 3;

/// Where on a MAC cell a field lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Location {
    /// Cell centres (x_{i+½}, y_{j+½}).
    Centre,
    /// Vertical faces (x_i, y_{j+½}): the x-velocity u.
    XFace,
    /// Horizontal faces (x_{i+½}, y_j): the y-velocity v.
    YFace,
    /// Cell corners (x_i, y_j).
    Node,
}

impl Location {
    /// Number of interior points (along x, along y) for a grid of nx × ny cells.
    pub fn interior_shape(self, nx: usize, ny: usize) -> (usize, usize) {
        match self {
            Location::Centre => (nx, ny),
            Location::XFace => (nx + 1, ny),
            Location::YFace => (nx, ny + 1),
            Location::Node => (nx + 1, ny + 1),
        }
    }

    /// Offsets (in cells) of the point (i, j) from the node (x_i, y_j).
    pub fn offset(self) -> (f64, f64) {
        match self {
            Location::Centre => (0.5, 0.5),
            Location::XFace => (0.0, 0.5),
            Location::YFace => (0.5, 0.0),
            Location::Node => (0.0, 0.0),
        }
    }
}

/// A uniform Cartesian grid of nx × ny cells.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    pub nx: usize,
    pub ny: usize,
    pub x0: f64,
    pub y0: f64,
    pub lx: f64,
    pub ly: f64,
    pub dx: f64,
    pub dy: f64,
}

impl Grid {
    /// A grid of `nx × ny` cells covering `(x0, x0 + lx) × (y0, y0 + ly)`.
    pub fn new(nx: usize, ny: usize, lx: f64, ly: f64) -> Result<Self> {
        Self::with_origin(nx, ny, 0.0, 0.0, lx, ly)
    }

    /// Same as [`Grid::new`] with an explicit origin.
    pub fn with_origin(nx: usize, ny: usize, x0: f64, y0: f64, lx: f64, ly: f64) -> Result<Self> {
        if !(2..=1 << 16).contains(&nx) {
            return Err(Error::param("nx", nx, "an integer in [2, 65536]"));
        }
        if !(2..=1 << 16).contains(&ny) {
            return Err(Error::param("ny", ny, "an integer in [2, 65536]"));
        }
        check_positive("lx", lx)?;
        check_positive("ly", ly)?;
        check_finite("x0", x0)?;
        check_finite("y0", y0)?;
        let dx = lx / nx as f64;
        let dy = ly / ny as f64;
        let aspect = dx / dy;
        if !(0.1..=10.0).contains(&aspect) {
            return Err(Error::param("lx/nx ÷ ly/ny", aspect, "a cell aspect ratio dx/dy in [0.1, 10]"));
        }
        Ok(Grid { nx, ny, x0, y0, lx, ly, dx, dy })
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.nx * self.ny
    }

    /// Smallest cell size min(dx, dy).
    pub fn h(&self) -> f64 {
        self.dx.min(self.dy)
    }

    /// Coordinates of the interior point (i, j) of a field at `loc`.
    #[inline]
    pub fn coord(&self, loc: Location, i: isize, j: isize) -> (f64, f64) {
        let (ox, oy) = loc.offset();
        (self.x0 + (i as f64 + ox) * self.dx, self.y0 + (j as f64 + oy) * self.dy)
    }

    /// Cell-centre x coordinate of column i.
    #[inline]
    pub fn xc(&self, i: isize) -> f64 {
        self.x0 + (i as f64 + 0.5) * self.dx
    }

    /// Cell-centre y coordinate of row j.
    #[inline]
    pub fn yc(&self, j: isize) -> f64 {
        self.y0 + (j as f64 + 0.5) * self.dy
    }
}

/// A scalar field on a grid location, with [`HALO`] ghost layers.
#[derive(Clone, Debug)]
pub struct Field {
    pub loc: Location,
    /// Interior points along x.
    pub nx: usize,
    /// Interior points along y.
    pub ny: usize,
    /// Storage, shape (ny + 2·HALO, nx + 2·HALO), index [j + HALO][i + HALO].
    pub data: Array2<f64>,
}

impl Field {
    /// A zero field at `loc` on `grid`.
    pub fn zeros(grid: &Grid, loc: Location) -> Self {
        let (nx, ny) = loc.interior_shape(grid.nx, grid.ny);
        Field { loc, nx, ny, data: Array2::zeros((ny + 2 * HALO, nx + 2 * HALO)) }
    }

    /// A field filled from `f(x, y)` at every interior point (ghosts are zero).
    pub fn from_fn(grid: &Grid, loc: Location, f: impl Fn(f64, f64) -> f64) -> Self {
        let mut fld = Self::zeros(grid, loc);
        for j in 0..fld.ny {
            for i in 0..fld.nx {
                let (x, y) = grid.coord(loc, i as isize, j as isize);
                fld.set(i, j, f(x, y));
            }
        }
        fld
    }

    /// Row stride of the storage (= nx + 2·HALO).
    #[inline]
    pub fn stride(&self) -> usize {
        self.nx + 2 * HALO
    }

    /// Flat storage index of interior point (i, j); ghosts are reached with negative or
    /// past-the-end indices down to −HALO.
    #[inline]
    pub fn idx(&self, i: isize, j: isize) -> usize {
        ((j + HALO as isize) as usize) * self.stride() + (i + HALO as isize) as usize
    }

    /// Value at interior (or ghost) point (i, j).
    #[inline]
    pub fn at(&self, i: isize, j: isize) -> f64 {
        self.slice()[self.idx(i, j)]
    }

    /// Sets the value at interior point (i, j).
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, v: f64) {
        let k = self.idx(i as isize, j as isize);
        self.slice_mut()[k] = v;
    }

    /// The whole storage, halos included, as a flat slice.
    #[inline]
    pub fn slice(&self) -> &[f64] {
        self.data.as_slice().expect("fields are contiguous")
    }

    /// The whole storage as a mutable flat slice.
    #[inline]
    pub fn slice_mut(&mut self) -> &mut [f64] {
        self.data.as_slice_mut().expect("fields are contiguous")
    }

    /// A view of the interior points only, shape (ny, nx).
    pub fn interior(&self) -> ndarray::ArrayView2<'_, f64> {
        self.data.slice(ndarray::s![HALO..HALO + self.ny, HALO..HALO + self.nx])
    }

    /// A mutable view of the interior points, shape (ny, nx).
    pub fn interior_mut(&mut self) -> ndarray::ArrayViewMut2<'_, f64> {
        let (nx, ny) = (self.nx, self.ny);
        self.data.slice_mut(ndarray::s![HALO..HALO + ny, HALO..HALO + nx])
    }

    /// Copies the values (halos included) of another field of the same shape.
    pub fn assign(&mut self, other: &Field) {
        debug_assert_eq!(self.data.dim(), other.data.dim());
        self.slice_mut().copy_from_slice(other.slice());
    }

    /// Sets every value, halos included.
    pub fn fill(&mut self, v: f64) {
        self.slice_mut().fill(v);
    }

    /// Maximum of |value| over the interior, and where it is (NaN wins).
    pub fn max_abs_with_location(&self) -> (f64, (usize, usize)) {
        let mut best = (0.0f64, (0, 0));
        for j in 0..self.ny {
            for i in 0..self.nx {
                let v = self.at(i as isize, j as isize);
                if v.is_nan() {
                    return (f64::NAN, (i, j));
                }
                if v.abs() > best.0 {
                    best = (v.abs(), (i, j));
                }
            }
        }
        best
    }

    /// Maximum of |value| over the interior.
    pub fn max_abs(&self) -> f64 {
        self.max_abs_with_location().0
    }

    /// Fills the ghost layers by constant (zeroth-order) extrapolation of the nearest interior
    /// value; corners included.
    pub fn extrapolate_ghosts_constant(&mut self) {
        let (nx, ny) = (self.nx as isize, self.ny as isize);
        let g = HALO as isize;
        // on the raw storage (k(i, j): the flat index of point (i, j), ghosts included)
        let st = self.stride() as isize;
        let k = |i: isize, j: isize| ((j + g) * st + i + g) as usize;
        let s = self.slice_mut();
        for j in 0..ny {
            let (left, right) = (s[k(0, j)], s[k(nx - 1, j)]);
            for m in 1..=g {
                s[k(-m, j)] = left;
                s[k(nx - 1 + m, j)] = right;
            }
        }
        for i in -g..nx + g {
            let (bot, top) = (s[k(i, 0)], s[k(i, ny - 1)]);
            for m in 1..=g {
                s[k(i, -m)] = bot;
                s[k(i, ny - 1 + m)] = top;
            }
        }
    }

    /// Fills the ghost layers by linear extrapolation from the two nearest interior values
    /// (keeps a signed-distance function's slope across the boundary).
    pub fn extrapolate_ghosts_linear(&mut self) {
        let (nx, ny) = (self.nx as isize, self.ny as isize);
        let g = HALO as isize;
        let st = self.stride() as isize;
        let k = |i: isize, j: isize| ((j + g) * st + i + g) as usize;
        let s = self.slice_mut();
        for j in 0..ny {
            let (l0, l1) = (s[k(0, j)], s[k(1, j)]);
            let (r0, r1) = (s[k(nx - 1, j)], s[k(nx - 2, j)]);
            for m in 1..=g {
                s[k(-m, j)] = l0 + m as f64 * (l0 - l1);
                s[k(nx - 1 + m, j)] = r0 + m as f64 * (r0 - r1);
            }
        }
        for i in -g..nx + g {
            let (b0, b1) = (s[k(i, 0)], s[k(i, 1)]);
            let (t0, t1) = (s[k(i, ny - 1)], s[k(i, ny - 2)]);
            for m in 1..=g {
                s[k(i, -m)] = b0 + m as f64 * (b0 - b1);
                s[k(i, ny - 1 + m)] = t0 + m as f64 * (t0 - t1);
            }
        }
    }
}

/// One named entry of a checkpoint: a flat array of f64 (scalars as one element).
pub type StateEntry = (String, Vec<f64>);

/// A room's part of the state a step reads, for checkpoints and the snapshot a failed step
/// returns to (`models/checkpoint.rs`): the room names its arrays and visits them in a fixed
/// order, so that the model needs none of its fields.
pub trait StateArrays {
    /// Calls `f(name, values)` for each state array of the room, in a fixed order.
    fn visit_state(&self, f: &mut dyn FnMut(&str, &[f64]));
    /// The same arrays in the same order, writable (a restore).
    fn visit_state_mut(&mut self, f: &mut dyn FnMut(&str, &mut [f64]));
}

/// A room's part of the state on the grid, for the active window (`models/window.rs`): the
/// window copies a room's [`WindowState::state_fields`] from the whole model when it is built
/// (the block it covers) and back after each step, and its [`WindowState::shown_fields`] (what
/// a step computes and the model shows) back only; the rest of the room's state, off the grid,
/// goes by [`WindowState::copy_other_state`].
pub trait WindowState {
    /// The state fields, in a fixed order.
    fn state_fields(&self) -> Vec<&Field>;
    /// The same fields in the same order, writable.
    fn state_fields_mut(&mut self) -> Vec<&mut Field>;
    /// Fields a step computes that the model shows (none by default).
    fn shown_fields(&self) -> Vec<&Field> {
        Vec::new()
    }
    /// The same fields in the same order, writable.
    fn shown_fields_mut(&mut self) -> Vec<&mut Field> {
        Vec::new()
    }
    /// Copies the state off the grid from `src` (the whole model's when a window is built, the
    /// window's after its step: `back`); nothing by default.
    fn copy_other_state(&mut self, _src: &Self, _back: bool) {}
}
