//! Conservative transport of the dense phase's volume fraction F and the level set rebuilt from
//! its interface: the coupled level set / volume of fluid (CLSVOF) of
//! `interface_transport = "clsvof"`.
//!
//! Equation (Weymouth & Yue 2010, *J. Comput. Phys.* 229, 2853–2865, eq. 9): with the cell's
//! indicator c = H(Fⁿ − ½), fixed over the step,
//!
//! ```text
//!   ∂F/∂t + ∇·(u F) − c ∇·u = 0,
//! ```
//!
//! which is ∂F/∂t + u·∇F = 0 where ∇·u = 0. Direction split, in the order x then y on even steps
//! and y then x on odd ones, each sweep on the MAC faces with the Courant numbers
//! C_{i+½} = u_{i+½} δt/δx (D_{j+½} = v_{j+½} δt/δy for y):
//!
//! ```text
//!   F* = Fⁿ − (f_{i+½} − f_{i−½}) + c (C_{i+½} − C_{i−½})
//!   Fⁿ⁺¹ = F* − (g_{j+½} − g_{j−½}) + c (D_{j+½} − D_{j−½})
//! ```
//!
//! f, g the signed volumes (in cell volumes) that cross a face in δt: the area of the upwind
//! cell's dense polygon in the strip of width |C| beside the face (a pure cell, F ≤ 0 or ≥ 1,
//! gives F|C|). The fluxes telescope, so that the dense volume V = Σ F δx δy changes by
//!
//! ```text
//!   Vⁿ⁺¹ − Vⁿ = (the fluxes through the domain's sides) + δt Σ c (∇_h·u) δx δy,
//! ```
//!
//! the last term the discrete divergence the pressure solve leaves, weighted by c: with
//! ∇_h·u = 0 the volume is conserved to round-off, cell by cell fluxes included
//! ([`VolumeBudget`]). With |C|, |D| ≤ ½ the scheme keeps 0 ≤ F ≤ 1 (Weymouth & Yue §3.2).
//!
//! Reconstruction (PLIC): in a mixed cell the interface is the line m·X = α in the cell's
//! coordinates X = ((x − x_i)/δx, (y − y_j)/δy) ∈ [0, 1]², dense below it, with
//! m = (n_x δx, n_y δy) from the outward normal n: n = −∇Φ by central differences
//! ([`PlicNormal::LevelSet`], Sussman & Puckett 2000) or n = −∇F by Youngs's 3 × 3 stencil
//! ([`PlicNormal::Youngs`], Youngs 1982). α is the inverse of the area of the cut square
//! (Scardovelli & Zaleski 2000, *J. Comput. Phys.* 164, 228–237, §3): with m₁ ≤ m₂,
//! m₁ + m₂ = 1 and F ≤ ½, α = √(2 m₁ m₂ F) for F < m₁/(2m₂), else F m₂ + m₁/2 (F > ½ by the
//! symmetry α(1 − F) = 1 − α(F)).
//!
//! Level set from F (Sussman & Puckett 2000, *J. Comput. Phys.* 162, 301–337, §3.3): at each
//! cell centre Φ = ±d, d the distance to the nearest PLIC segment within [`SEARCH_CELLS`] cells,
//! positive on the dense side of the cell's own line (a cell without a line: F > ½). Where d exceeds
//! [`BAND_CELLS`] h (no segment near enough for d to be exact) Φ keeps the magnitude of the
//! transported Φ, at least [`BAND_CELLS`] h, with the sign of F. Φ's zero level is then the
//! fractions' interface and Φ the exact distance to it in the band |Φ| ≤ 3h that H_ε(Φ)
//! (ε = 1.5h) reads. Cells with F below [`F_MIN`] (above 1 − F_MIN) count as empty (full) for
//! the rebuild: a speck of volume would otherwise raise H_ε(Φ) around it.
//!
//! Every kernel writes each row from rows read only (the y-sweep's face fluxes are computed by
//! both rows beside the face with the same arithmetic), and the sums add rows in the fixed
//! blocks of [`Exec::sum_rows`]: serial and parallel runs give the same bits. The work fields are
//! allocated in [`VolumeFraction::new`]; the steps allocate nothing.

use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, HALO};

/// Width of the band, in cells, where the rebuilt Φ is the exact distance to the PLIC segments.
pub const BAND_CELLS: f64 = 3.0;

/// Cells searched on each side for the nearest segment: a point at distance ≤ 3h from a cell
/// centre lies in a cell at most ⌈3 + ½⌉ = 4 cells away.
pub const SEARCH_CELLS: usize = 4;

/// Fractions below F_MIN (above 1 − F_MIN) are empty (full) cells for the rebuild of Φ.
pub const F_MIN: f64 = 1e-6;

/// How the interface is transported (model option `interface_transport`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InterfaceTransport {
    /// Φ alone, by WENO5 + TVD-RK3 ([`super::transport`]).
    #[default]
    LevelSet,
    /// Φ as today and F by the conservative split PLIC scheme, Φ rebuilt from F each step.
    Clsvof,
}

impl InterfaceTransport {
    /// Name used in the options and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            InterfaceTransport::LevelSet => "level-set",
            InterfaceTransport::Clsvof => "clsvof",
        }
    }

    /// The choice named `name` (an option's validated value).
    pub fn from_name(name: &str) -> Self {
        if name == "clsvof" {
            InterfaceTransport::Clsvof
        } else {
            InterfaceTransport::LevelSet
        }
    }
}

/// Where the PLIC normal comes from (model option `plic_normal`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlicNormal {
    /// n = −∇Φ, central differences of the level set (the default: Zalesak's disk 2.5 % against
    /// 3.1 % symmetric difference with Youngs's, the vortex 0.12 % against 0.41 %,
    /// `tests/clsvof.rs`).
    #[default]
    LevelSet,
    /// n = −∇F, Youngs's 3 × 3 stencil of the fractions.
    Youngs,
}

impl PlicNormal {
    /// Name used in the options and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            PlicNormal::LevelSet => "level-set",
            PlicNormal::Youngs => "youngs",
        }
    }

    /// The choice named `name` (an option's validated value).
    pub fn from_name(name: &str) -> Self {
        if name == "level-set" {
            PlicNormal::LevelSet
        } else {
            PlicNormal::Youngs
        }
    }
}

/// The dense volume's budget of the last step (m², per unit depth): Vⁿ⁺¹ − Vⁿ =
/// `boundary` + `divergence` to round-off.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VolumeBudget {
    /// Volume in through the domain's sides (negative: out).
    pub boundary: f64,
    /// δt Σ c (∇_h·u) δx δy: what the discrete divergence of the velocity adds.
    pub divergence: f64,
}

/// The volume fraction F of the dense phase and the work fields of its transport and of the
/// rebuild of Φ.
#[derive(Clone, Debug)]
pub struct VolumeFraction {
    /// Fⁿ (cell centres, in [0, 1]).
    pub f: Field,
    /// The normals' source.
    pub normal: PlicNormal,
    /// F after the first sweep.
    half: Field,
    /// The cells' PLIC segments, end points (a_x, a_y, b_x, b_y) relative to the cell centre (m):
    /// for storage row r (F's layout, stride s) component c of cell i at `seg[(4r + c) s + i]`;
    /// a_x NaN where the cell has none.
    seg: Vec<f64>,
    /// Per row, the columns [first, last + 1) that hold a segment ((0, 0): none).
    rows: Vec<(usize, usize)>,
    /// Per row j, the union of `rows` over the rows j ± [`SEARCH_CELLS`] (a cell farther than
    /// that from it along x has no segment in its search window).
    near: Vec<(usize, usize)>,
    /// The last step's budget.
    pub budget: VolumeBudget,
}

impl VolumeFraction {
    /// F = 0 on `grid`, with its work fields.
    pub fn new(grid: &Grid, normal: PlicNormal) -> Self {
        let c = || Field::zeros(grid, Location::Centre);
        let f = c();
        let seg = vec![f64::NAN; 4 * f.slice().len()];
        VolumeFraction { f, normal, half: c(), seg, rows: vec![(0, 0); grid.ny], near: vec![(0, 0); grid.ny], budget: VolumeBudget::default() }
    }

    /// The dense volume Σ F δx δy (m² per unit depth), summed in the fixed row blocks.
    pub fn volume(&self, grid: &Grid, exec: Exec) -> f64 {
        fraction_volume(&self.f, grid, exec)
    }

    /// F of each cell from a signed distance Φ (> 0 dense): the area of the cell on the dense side
    /// of the line through the centre's closest interface point, normal to −∇Φ (central
    /// differences): exact for a straight interface, O(h²) for a curved one.
    pub fn set_from_level_set(&mut self, phi: &mut Field, grid: &Grid) {
        phi.extrapolate_ghosts_linear();
        let (ps, st) = (phi.slice(), phi.stride());
        let (dx, dy) = (grid.dx, grid.dy);
        for j in 0..grid.ny {
            for i in 0..grid.nx {
                let k = (j + HALO) * st + i + HALO;
                let gx = (ps[k + 1] - ps[k - 1]) / (2.0 * dx);
                let gy = (ps[k + st] - ps[k - st]) / (2.0 * dy);
                let norm = gx.hypot(gy);
                let f = if norm > 0.0 && norm.is_finite() {
                    let (m1, m2) = (-gx / norm * dx, -gy / norm * dy);
                    plic_area(m1, m2, ps[k] + 0.5 * (m1 + m2))
                } else if ps[k] > 0.0 {
                    1.0
                } else {
                    0.0
                };
                self.f.set(i, j, f);
            }
        }
        self.f.extrapolate_ghosts_constant();
    }

    /// Advances F over δt with the MAC velocity (u, v), the x-sweep first when `x_first`
    /// (alternate it from step to step). `phi` is Φⁿ, read for the normals with
    /// [`PlicNormal::LevelSet`] (its ghosts filled here). Fails before any change for a Courant
    /// number |u| δt/δx or |v| δt/δy above 1 on a face.
    #[allow(clippy::too_many_arguments)]
    pub fn transport(&mut self, phi: &mut Field, u: &Field, v: &Field, grid: &Grid, dt: f64, x_first: bool, exec: Exec) -> Result<()> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(Error::param("dt", dt, "a finite number >= 0"));
        }
        let courant = exec.max_rows(grid.ny + 1, grid.cells(), |j| {
            let mut m = 0.0f64;
            if j < grid.ny {
                for i in 0..=grid.nx {
                    m = m.max((u.at(i as isize, j as isize) * dt / grid.dx).abs());
                }
            }
            for i in 0..grid.nx {
                m = m.max((v.at(i as isize, j as isize) * dt / grid.dy).abs());
            }
            m
        });
        if courant.is_nan() || courant > 1.0 {
            return Err(Error::param(
                "dt",
                dt,
                &format!("a step whose face Courant numbers are at most 1 for the volume-fraction transport (largest {courant:.3})"),
            ));
        }
        phi.extrapolate_ghosts_linear();
        self.f.extrapolate_ghosts_constant();
        let axes = if x_first { [Axis::X, Axis::Y] } else { [Axis::Y, Axis::X] };
        let mut budget = VolumeBudget::default();
        // first sweep: F → half (c from the source, Fⁿ); second: half → F (c from F's own row
        // before it is overwritten, Fⁿ again)
        let b = sweep(&mut self.half, &self.f, None, phi, u, v, grid, dt, axes[0], self.normal, exec);
        budget.boundary += b.boundary;
        budget.divergence += b.divergence;
        self.half.extrapolate_ghosts_constant();
        let b = sweep(&mut self.f, &self.half, Some(()), phi, u, v, grid, dt, axes[1], self.normal, exec);
        budget.boundary += b.boundary;
        budget.divergence += b.divergence;
        self.f.extrapolate_ghosts_constant();
        self.budget = budget;
        Ok(())
    }

    /// Rebuilds Φ from F's interface (the module's "Level set from F"): the exact distance to the
    /// PLIC segments in the band |Φ| ≤ [`BAND_CELLS`] h, the sign of F beyond. `phi` holds the
    /// transported Φ on entry (its magnitude is kept beyond the band; its gradient gives the
    /// normals with [`PlicNormal::LevelSet`]).
    pub fn rebuild_level_set(&mut self, phi: &mut Field, grid: &Grid, exec: Exec) {
        phi.extrapolate_ghosts_linear();
        self.f.extrapolate_ghosts_constant();
        let (fs, ps, st) = (self.f.slice(), phi.slice(), self.f.stride());
        let (dx, dy, nx, ny) = (grid.dx, grid.dy, grid.nx, grid.ny);
        let normal = self.normal;
        // the segments: the four rows of storage row r hold one component each
        exec.for_each_row(&mut self.seg, 4 * st, |r, rows4| {
            if r < HALO || r >= ny + HALO {
                return;
            }
            for i in HALO..HALO + nx {
                let s = segment(fs, ps, r * st + i, st, normal, dx, dy).unwrap_or([f64::NAN; 4]);
                for (c, x) in s.into_iter().enumerate() {
                    rows4[c * st + i] = x;
                }
            }
        });
        // the columns of each row that hold a segment
        for (j, range) in self.rows.iter_mut().enumerate() {
            let b = 4 * (j + HALO) * st + HALO;
            let row = &self.seg[b..b + nx];
            *range = match (row.iter().position(|x| !x.is_nan()), row.iter().rposition(|x| !x.is_nan())) {
                (Some(a), Some(b)) => (a, b + 1),
                _ => (0, 0),
            };
        }
        for j in 0..ny {
            let (lo, hi) = (j.saturating_sub(SEARCH_CELLS), (j + SEARCH_CELLS + 1).min(ny));
            self.near[j] = self.rows[lo..hi].iter().filter(|r| r.1 > r.0).fold((usize::MAX, 0), |(a, b), r| (a.min(r.0), b.max(r.1)));
        }
        let near = &self.near;
        let seg = &self.seg;
        // component c of the cell at flat index k = r st + i
        let at = move |k: usize, c: usize| seg[4 * (k / st) * st + c * st + k % st];
        let rows = &self.rows;
        let band = BAND_CELLS * grid.h();
        exec.for_each_row(phi.slice_mut(), st, |r, row| {
            if r < HALO || r >= ny + HALO {
                return;
            }
            let j = r - HALO;
            let (jlo, jhi) = (j.saturating_sub(SEARCH_CELLS), (j + SEARCH_CELLS + 1).min(ny));
            for i in 0..nx {
                let k = r * st + i + HALO;
                let dense = if at(k, 0).is_nan() {
                    fs[k] > 0.5
                } else {
                    // the centre (0, 0) on the left of a → b (or on it): dense
                    let (ax, ay, bx, by) = (at(k, 0), at(k, 1), at(k, 2), at(k, 3));
                    (bx - ax) * (-ay) - (by - ay) * (-ax) >= 0.0
                };
                let (ilo, ihi) = (i.saturating_sub(SEARCH_CELLS), (i + SEARCH_CELLS + 1).min(nx));
                let mut d2 = f64::INFINITY;
                let (nlo, nhi) = near[j];
                if ihi <= nlo || ilo >= nhi {
                    // no segment in the window
                    let mag = row[i + HALO].abs().max(band);
                    row[i + HALO] = if dense { mag } else { -mag };
                    continue;
                }
                for (jj, &(a, b)) in rows.iter().enumerate().take(jhi).skip(jlo) {
                    let (lo, hi) = (ilo.max(a), ihi.min(b));
                    let base = 4 * (jj + HALO) * st + HALO;
                    for ii in lo..hi {
                        let ax = seg[base + ii];
                        if ax.is_nan() {
                            continue;
                        }
                        // the point: the centre of (i, j) relative to the centre of (ii, jj)
                        let px = (i as f64 - ii as f64) * dx;
                        let py = (j as f64 - jj as f64) * dy;
                        let (ay, bx, by) = (seg[base + st + ii], seg[base + 2 * st + ii], seg[base + 3 * st + ii]);
                        d2 = d2.min(segment_distance2(px, py, ax, ay, bx, by));
                    }
                }
                let d = d2.sqrt();
                let mag = if d <= band { d } else { row[i + HALO].abs().max(band) };
                row[i + HALO] = if dense { mag } else { -mag };
            }
        });
        phi.extrapolate_ghosts_linear();
    }
}

impl crate::grid::StateArrays for VolumeFraction {
    /// F.
    fn visit_state(&self, f: &mut dyn FnMut(&str, &[f64])) {
        f("volume_fraction", self.f.slice());
    }

    fn visit_state_mut(&mut self, f: &mut dyn FnMut(&str, &mut [f64])) {
        f("volume_fraction", self.f.slice_mut());
    }
}

impl crate::grid::WindowState for VolumeFraction {
    /// F.
    fn state_fields(&self) -> Vec<&Field> {
        vec![&self.f]
    }

    fn state_fields_mut(&mut self) -> Vec<&mut Field> {
        vec![&mut self.f]
    }

    /// The last step's budget goes back with the window's state.
    fn copy_other_state(&mut self, src: &Self, back: bool) {
        if back {
            self.budget = src.budget;
        }
    }
}

/// Σ F δx δy over the interior of `f`, in the fixed row blocks of [`Exec::sum_rows`].
pub fn fraction_volume(f: &Field, grid: &Grid, exec: Exec) -> f64 {
    let (fs, st, nx) = (f.slice(), f.stride(), f.nx);
    exec.sum_rows(f.ny, grid.cells(), |j| fs[(j + HALO) * st + HALO..(j + HALO) * st + HALO + nx].iter().sum::<f64>()) * grid.dx * grid.dy
}

/// The area fraction of the unit square [0, 1]² below the line a X + b Y = α
/// ({a X + b Y ≤ α}), for any signs of a, b (Scardovelli & Zaleski 2000, §3).
pub fn plic_area(a: f64, b: f64, alpha: f64) -> f64 {
    let al = alpha - a.min(0.0) - b.min(0.0);
    let (a, b) = (a.abs(), b.abs());
    let s = a + b;
    if s == 0.0 {
        return if al >= 0.0 { 1.0 } else { 0.0 };
    }
    let t = al / s;
    let (m, mx) = (a.min(b) / s, a.max(b) / s);
    if t <= 0.0 {
        0.0
    } else if t >= 1.0 {
        1.0
    } else if t > 0.5 {
        1.0 - area_half(m, mx, 1.0 - t)
    } else {
        area_half(m, mx, t)
    }
}

/// The area below m X + M Y = t in the unit square, m ≤ M, m + M = 1, 0 ≤ t ≤ ½.
#[inline]
fn area_half(m: f64, mx: f64, t: f64) -> f64 {
    if t < m {
        t * t / (2.0 * m * mx)
    } else {
        (t - 0.5 * m) / mx
    }
}

/// The α of the line a X + b Y = α that leaves the area fraction `f` ∈ [0, 1] of the unit square
/// below it (the inverse of [`plic_area`]; (a, b) ≠ 0).
pub fn plic_alpha(a: f64, b: f64, f: f64) -> f64 {
    let (aa, bb) = (a.abs(), b.abs());
    let s = aa + bb;
    let (m, mx) = (aa.min(bb) / s, aa.max(bb) / s);
    let f = f.clamp(0.0, 1.0);
    let t = if f <= 0.5 { alpha_half(m, mx, f) } else { 1.0 - alpha_half(m, mx, 1.0 - f) };
    t * s + a.min(0.0) + b.min(0.0)
}

/// t with [`area_half`](m, M, t) = f, f ≤ ½.
#[inline]
fn alpha_half(m: f64, mx: f64, f: f64) -> f64 {
    if f < 0.5 * m / mx {
        (2.0 * m * mx * f).sqrt()
    } else {
        f * mx + 0.5 * m
    }
}

/// The signed volume (in cell volumes) that crosses a face in a step of Courant number `c`
/// (> 0: from the cell below the face's index to the one above), taken from the upwind cell of
/// fraction `f` whose line has the normal (`m_along`, `m_across`) in cell units (along the sweep,
/// across it): the dense area in the strip of width |c| beside the face.
#[inline]
pub fn swept_volume(c: f64, f: f64, m_along: f64, m_across: f64) -> f64 {
    if c == 0.0 {
        return 0.0;
    }
    let w = c.abs();
    let vol = if f <= 0.0 || f >= 1.0 || (m_along == 0.0 && m_across == 0.0) {
        f * w
    } else {
        let alpha = plic_alpha(m_along, m_across, f);
        // the strip: X ∈ [1 − w, 1] of the upwind cell for c > 0, X ∈ [0, w] for c < 0
        let x0 = if c > 0.0 { 1.0 - w } else { 0.0 };
        w * plic_area(m_along * w, m_across, alpha - m_along * x0)
    };
    if c > 0.0 {
        vol
    } else {
        -vol
    }
}

/// The outward normal (n_x δx, n_y δy) of cell `k` (flat index into fields of stride `st`).
#[inline]
fn cell_normal(fs: &[f64], ps: &[f64], k: usize, st: usize, normal: PlicNormal) -> (f64, f64) {
    match normal {
        PlicNormal::LevelSet => (-0.5 * (ps[k + 1] - ps[k - 1]), -0.5 * (ps[k + st] - ps[k - st])),
        PlicNormal::Youngs => {
            let f = |di: isize, dj: isize| fs[(k as isize + dj * st as isize + di) as usize];
            let gx = (f(1, 1) + 2.0 * f(1, 0) + f(1, -1)) - (f(-1, 1) + 2.0 * f(-1, 0) + f(-1, -1));
            let gy = (f(1, 1) + 2.0 * f(0, 1) + f(-1, 1)) - (f(1, -1) + 2.0 * f(0, -1) + f(-1, -1));
            (-0.125 * gx, -0.125 * gy)
        }
    }
}

/// The PLIC segment of cell `k`, end points relative to the cell centre (m), ordered so that
/// the dense phase is on the left of a → b; None for a cell with F outside (F_MIN, 1 − F_MIN)
/// or no normal.
#[inline]
fn segment(fs: &[f64], ps: &[f64], k: usize, st: usize, normal: PlicNormal, dx: f64, dy: f64) -> Option<[f64; 4]> {
    let f = fs[k];
    if !(f > F_MIN && f < 1.0 - F_MIN) {
        return None;
    }
    let (m1, m2) = cell_normal(fs, ps, k, st, normal);
    if m1 == 0.0 && m2 == 0.0 {
        return None;
    }
    let alpha = plic_alpha(m1, m2, f);
    // the line m·X = α clipped to [0, 1]²: X = p + t d, p = α m/|m|², d = (−m₂, m₁)
    let n2 = m1 * m1 + m2 * m2;
    let (px, py) = (alpha * m1 / n2, alpha * m2 / n2);
    let (ddx, ddy) = (-m2, m1);
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for (p, d) in [(px, ddx), (py, ddy)] {
        if d != 0.0 {
            let (a, b) = ((0.0 - p) / d, (1.0 - p) / d);
            lo = lo.max(a.min(b));
            hi = hi.min(a.max(b));
        } else if !(0.0..=1.0).contains(&p) {
            return None;
        }
    }
    if lo.is_nan() || hi.is_nan() || lo > hi {
        return None;
    }
    // d = (−m₂, m₁) is m turned left, so m points to the right of a → b and the dense side
    // (m·X < α) is on its left
    let at = |t: f64| (((px + t * ddx).clamp(0.0, 1.0) - 0.5) * dx, ((py + t * ddy).clamp(0.0, 1.0) - 0.5) * dy);
    let (a, b) = (at(lo), at(hi));
    Some([a.0, a.1, b.0, b.1])
}

/// The squared distance from (px, py) to the segment a b.
#[inline]
fn segment_distance2(px: f64, py: f64, ax: f64, ay: f64, bx: f64, by: f64) -> f64 {
    let (ex, ey) = (bx - ax, by - ay);
    let l2 = ex * ex + ey * ey;
    let t = if l2 > 0.0 { (((px - ax) * ex + (py - ay) * ey) / l2).clamp(0.0, 1.0) } else { 0.0 };
    let (qx, qy) = (ax + t * ex - px, ay + t * ey - py);
    qx * qx + qy * qy
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Axis {
    X,
    Y,
}

/// One sweep along `axis`: out = src − (flux differences) + c (Courant differences), c from
/// `src`'s cell (`c_from_out` None) or from `out`'s cell before it is written (Some). Returns the
/// sweep's part of the budget.
#[allow(clippy::too_many_arguments)]
fn sweep(
    out: &mut Field,
    src: &Field,
    c_from_out: Option<()>,
    phi: &Field,
    u: &Field,
    v: &Field,
    grid: &Grid,
    dt: f64,
    axis: Axis,
    normal: PlicNormal,
    exec: Exec,
) -> VolumeBudget {
    let (nx, ny, st) = (grid.nx, grid.ny, src.stride());
    let (ss, ps, us, vs) = (src.slice(), phi.slice(), u.slice(), v.slice());
    let (ust, vst) = (u.stride(), v.stride());
    let (cx, cy) = (dt / grid.dx, dt / grid.dy);
    // the flux through the face between cells kl (low) and kh (high) with Courant number c
    let flux = move |c: f64, kl: usize, kh: usize| -> f64 {
        if c == 0.0 {
            return 0.0;
        }
        let k = if c > 0.0 { kl } else { kh };
        let f = ss[k];
        if f <= 0.0 || f >= 1.0 {
            // a pure cell: F|c| signed, without its normal (the same value as swept_volume's)
            return f * c;
        }
        let (m1, m2) = cell_normal(ss, ps, k, st, normal);
        match axis {
            Axis::X => swept_volume(c, ss[k], m1, m2),
            Axis::Y => swept_volume(c, ss[k], m2, m1),
        }
    };
    // the Courant number of face `i` (x) or `j` (y) of row j
    let courant = move |i: usize, j: usize| -> f64 {
        match axis {
            Axis::X => us[(j + HALO) * ust + i + HALO] * cx,
            Axis::Y => vs[(j + HALO) * vst + i + HALO] * cy,
        }
    };
    // the divergence term Σ c (C_hi − C_lo) of the budget, c from Fⁿ: the source of the first
    // sweep, `out` before the second overwrites it
    let cells = grid.cells();
    let divergence = {
        let fnow = if c_from_out.is_some() { out.slice() } else { ss };
        exec.sum_rows(ny, cells, |j| {
            let r = j + HALO;
            let mut s = 0.0;
            for i in 0..nx {
                let (clo, chi) = match axis {
                    Axis::X => (courant(i, j), courant(i + 1, j)),
                    Axis::Y => (courant(i, j), courant(i, j + 1)),
                };
                if fnow[r * st + i + HALO] > 0.5 {
                    s += chi - clo;
                }
            }
            s
        })
    };
    exec.for_each_row(out.slice_mut(), st, |r, row| {
        if r < HALO || r >= ny + HALO {
            return;
        }
        let j = r - HALO;
        let mut lo_flux = match axis {
            Axis::X => flux(courant(0, j), r * st + HALO - 1, r * st + HALO),
            Axis::Y => 0.0,
        };
        for i in 0..nx {
            let k = r * st + i + HALO;
            let fc = ss[k];
            let fn_ = if c_from_out.is_some() { row[i + HALO] } else { fc };
            let c = if fn_ > 0.5 { 1.0 } else { 0.0 };
            let (flo, fhi, clo, chi) = match axis {
                Axis::X => {
                    let chi = courant(i + 1, j);
                    let fhi = flux(chi, k, k + 1);
                    (lo_flux, fhi, courant(i, j), chi)
                }
                Axis::Y => {
                    let (clo, chi) = (courant(i, j), courant(i, j + 1));
                    (flux(clo, k - st, k), flux(chi, k, k + st), clo, chi)
                }
            };
            lo_flux = fhi;
            row[i + HALO] = fc - (fhi - flo) + c * (chi - clo);
        }
    });
    let boundary = match axis {
        Axis::X => exec.sum_rows(ny, cells, |j| {
            let r = j + HALO;
            flux(courant(0, j), r * st + HALO - 1, r * st + HALO) - flux(courant(nx, j), r * st + HALO + nx - 1, r * st + HALO + nx)
        }),
        Axis::Y => exec.sum_rows(1, cells, |_| {
            let mut s = 0.0;
            for i in 0..nx {
                let (kb, kt) = (HALO * st + i + HALO, (ny - 1 + HALO) * st + i + HALO);
                s += flux(courant(i, 0), kb - st, kb) - flux(courant(i, ny), kt, kt + st);
            }
            s
        }),
    };
    VolumeBudget { boundary: boundary * grid.dx * grid.dy, divergence: divergence * grid.dx * grid.dy }
}
