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
//! Films (the cells' first moments). Each cell also carries the first moments of its dense
//! part about its centre, M = ∫(X − ½) dA (cell units), moved with the fluxes: in a sweep along
//! ξ a piece that crosses a face carries the moments of the upwind cell's dense part in the
//! strip (the polygon clipped by the strip, [`cut_moments`]) shifted by the face's Courant
//! number, the part that stays moves with the velocity linear between the cell's faces
//! (ξ → ξ + C_lo + (C_hi − C_lo) ξ) and the c-term's volume sits at the cell's centroid; a
//! centroid is kept within reach of its area (|M| ≤ F(1 − F)/2 per axis). A single line cannot
//! bound a film thinner than a cell, whose dense part lies between two: where the two
//! neighbours across the dense phase's direction (the major axis of the second moment of F over
//! 3 × 3 cells) each hold less than [`FILM_RATIO`] of the cell's F, the cell is a film cell and
//! its dense part is the slab {α_lo ≤ m·X ≤ α_hi} of area F whose moment across it is the
//! cell's (m across the direction). Where the cell ends a film, or a layer with no full cell
//! about it (the cells on one side along the direction hold less than [`FILM_RATIO`] of its F),
//! the slab, or the line, is capped along the lattice axis nearest the direction so that its
//! centroid along that axis is the cell's. A speck (F < [`SPECK`]) is the square of area F at
//! its centroid. The slabs' and caps' places are found by regula falsi on closed forms; the
//! fluxes are their areas in the strips, so the volume stays conserved to round-off and F
//! within [0, 1]. Other cells keep their line, whose moments can differ from the carried ones:
//! over a translation of 13 cells the dense volume's centroid moves off by 0.004–0.06 cell.
//! Moving the ends with the moments keeps a film's length: films of ½ and 1 cell translated
//! or rotated one turn stay within 1–2 cells of the exact film's extent (`tests/clsvof.rs`,
//! docs/validation.md).
//!
//! Level set from F (Sussman & Puckett 2000, *J. Comput. Phys.* 162, 301–337, §3.3): at each
//! cell centre Φ = ±d, d the distance to the nearest segment within [`SEARCH_CELLS`] cells (a
//! slab's two sides and its cap count), positive inside the cell's own dense part (a cell
//! without one, and every cell beyond: F > ½). From there outwards Φ is the chamfer distance:
//! [`CHAMFER_STEPS`] Jacobi sweeps of |Φ| ← min over the eight neighbours of |Φ_nb| + (δx, δy
//! or their diagonal), each cell never above its own d, and ±9h where no sweep reaches. Φ's zero level is then the fractions' interface, Φ the exact
//! distance to it in the band |Φ| ≤ [`BAND_CELLS`] h = 3h that H_ε(Φ) (ε = 1.5h) reads, and an
//! upper bound of the distance out to 9h (exact along the axes and diagonals, at most 8 % above
//! it between them), past the farthest threshold a reader puts on Φ (the light phase's CFL band,
//! 6h; the active window's support, 4.5h). The rebuild is the level set's redistancing: it sets
//! every cell at every step from the segments alone, so the PDE redistancing
//! (`redistance_every`) does not run with the volume fraction, and no value of the transported
//! Φ beyond the interface cells' normals reaches the next step. Cells with F below [`F_MIN`]
//! (above 1 − F_MIN) count as empty (full) for the rebuild: a speck of volume would otherwise
//! raise H_ε(Φ) around it.
//!
//! Thin zones (what the material properties read). Where no full cell (F ≥ 1 − [`F_MIN`]) lies
//! within [`THIN_ZONE_CELLS`] cells, the dense phase is a film or a speck thinner than the
//! blend's width 2ε, and H_ε of a distance to its slab is about ½ whatever its F: a film of
//! F ~ 1e-3 in the air would weigh half the grains' density over 3 cells. There the properties
//! read Φ_w = H_ε⁻¹(F) instead of Φ (−max(|Φ|, ε) where F ≤ [`F_MIN`]), so that
//! ρ = ρ_l + (ρ_d − ρ_l) F and η the harmonic blend with weight F; elsewhere Φ_w = Φ
//! ([`VolumeFraction::properties_level_set`]). Φ itself stays the distance to the segments: its
//! normals place the lines and the slabs.
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

/// Jacobi sweeps of the chamfer distance beyond the band: Φ is a distance bound out to
/// (BAND_CELLS + CHAMFER_STEPS) h = 9h and ±9h beyond, past the farthest threshold any reader
/// puts on Φ (the light phase's CFL band, 6h; the active window's support, 4.5h).
pub const CHAMFER_STEPS: usize = 6;
// an even number of sweeps ends in Φ
const _: () = assert!(CHAMFER_STEPS % 2 == 0);

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
    /// The first moments of each cell's dense part about the cell's centre, in cell units:
    /// M_x = ∫(X − ½) dA, M_y = ∫(Y − ½) dA over the dense part of [0, 1]² (zero in a pure
    /// cell). They place a film's slab (the module's "Films").
    pub mx: Field,
    pub my: Field,
    /// The normals' source.
    pub normal: PlicNormal,
    /// F and its moments after the first sweep.
    half: Field,
    half_mx: Field,
    half_my: Field,
    /// Each cell's reconstruction ([`Dense`]), [`REC`] rows per storage row.
    rec: Vec<f64>,
    /// The cells' interface segments, end points (a_x, a_y, b_x, b_y) relative to the cell centre
    /// (m), up to three per cell (a film's slab: its two sides and its end): for storage row r
    /// (F's layout, stride s) component c of cell i at `seg[(12r + c) s + i]`; a_x NaN where the
    /// cell has none.
    seg: Vec<f64>,
    /// Per row, the columns [first, last + 1) that hold a segment ((0, 0): none).
    rows: Vec<(usize, usize)>,
    /// Per row j, the union of `rows` over the rows j ± [`SEARCH_CELLS`] (a cell farther than
    /// that from it along x has no segment in its search window).
    near: Vec<(usize, usize)>,
    /// Per row, the columns [first, last + 1) whose Φ the chamfer sweeps can set below the
    /// far value (within [`SEARCH_CELLS`] + [`CHAMFER_STEPS`] cells of a segment).
    reach: Vec<(usize, usize)>,
    /// Φ as the properties read it ([`VolumeFraction::properties_level_set`]).
    weight: Field,
    /// The last step's budget.
    pub budget: VolumeBudget,
}

impl VolumeFraction {
    /// F = 0 on `grid`, with its work fields.
    pub fn new(grid: &Grid, normal: PlicNormal) -> Self {
        let c = || Field::zeros(grid, Location::Centre);
        let f = c();
        let seg = vec![f64::NAN; 12 * f.slice().len()];
        let rec = vec![0.0; REC * f.slice().len()];
        VolumeFraction {
            f,
            mx: c(),
            my: c(),
            normal,
            half: c(),
            half_mx: c(),
            half_my: c(),
            rec,
            seg,
            rows: vec![(0, 0); grid.ny],
            near: vec![(0, 0); grid.ny],
            reach: vec![(0, 0); grid.ny],
            weight: c(),
            budget: VolumeBudget::default(),
        }
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
                let (f, mom) = if norm > 0.0 && norm.is_finite() {
                    let (m1, m2) = (-gx / norm * dx, -gy / norm * dy);
                    let alpha = ps[k] + 0.5 * (m1 + m2);
                    let f = plic_area(m1, m2, alpha);
                    (f, centred_moments(f, cut_moments(m1, m2, alpha, [0.0, 1.0, 0.0, 1.0])))
                } else if ps[k] > 0.0 {
                    (1.0, [0.0; 2])
                } else {
                    (0.0, [0.0; 2])
                };
                self.f.set(i, j, f);
                self.mx.set(i, j, mom[0]);
                self.my.set(i, j, mom[1]);
            }
        }
        self.f.extrapolate_ghosts_constant();
        self.mx.extrapolate_ghosts_constant();
        self.my.extrapolate_ghosts_constant();
    }

    /// Sets the moments M_x, M_y of every cell from its line reconstruction (the PLIC normal of
    /// [`Self::normal`], Φ read for [`PlicNormal::LevelSet`]): for an F set cell by cell.
    pub fn reset_moments(&mut self, phi: &mut Field, grid: &Grid) {
        phi.extrapolate_ghosts_linear();
        self.f.extrapolate_ghosts_constant();
        let (fs, ps, st) = (self.f.slice(), phi.slice(), self.f.stride());
        for j in 0..grid.ny {
            for i in 0..grid.nx {
                let k = (j + HALO) * st + i + HALO;
                let f = fs[k];
                let (m1, m2) = cell_normal(fs, ps, k, st, self.normal);
                let mom = if f > 0.0 && f < 1.0 && (m1 != 0.0 || m2 != 0.0) {
                    centred_moments(f, cut_moments(m1, m2, plic_alpha(m1, m2, f), [0.0, 1.0, 0.0, 1.0]))
                } else {
                    [0.0; 2]
                };
                self.mx.set(i, j, mom[0]);
                self.my.set(i, j, mom[1]);
            }
        }
        self.mx.extrapolate_ghosts_constant();
        self.my.extrapolate_ghosts_constant();
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
        for fld in [&mut self.f, &mut self.mx, &mut self.my] {
            fld.extrapolate_ghosts_constant();
        }
        let axes = if x_first { [Axis::X, Axis::Y] } else { [Axis::Y, Axis::X] };
        let mut budget = VolumeBudget::default();
        // first sweep: F → half (c from the source, Fⁿ); second: half → F (c from F's own row
        // before it is overwritten, Fⁿ again)
        let src = [&self.f, &self.mx, &self.my];
        reconstruct_all(&mut self.rec, src, phi, grid, self.normal, exec);
        let b = sweep([&mut self.half, &mut self.half_mx, &mut self.half_my], src, false, &self.rec, u, v, grid, dt, axes[0], exec);
        budget.boundary += b.boundary;
        budget.divergence += b.divergence;
        let src = [&self.half, &self.half_mx, &self.half_my];
        reconstruct_all(&mut self.rec, src, phi, grid, self.normal, exec);
        let b = sweep([&mut self.f, &mut self.mx, &mut self.my], src, true, &self.rec, u, v, grid, dt, axes[1], exec);
        budget.boundary += b.boundary;
        budget.divergence += b.divergence;
        self.budget = budget;
        Ok(())
    }

    /// Rebuilds Φ from F's interface (the module's "Level set from F"): the exact distance to the
    /// PLIC segments in the band |Φ| ≤ [`BAND_CELLS`] h, the chamfer distance beyond, the sign of
    /// F. `phi` holds the transported Φ on entry (its gradient gives the normals with
    /// [`PlicNormal::LevelSet`]); every cell of it is overwritten.
    pub fn rebuild_level_set(&mut self, phi: &mut Field, grid: &Grid, exec: Exec) {
        phi.extrapolate_ghosts_linear();
        for fld in [&mut self.f, &mut self.mx, &mut self.my] {
            fld.extrapolate_ghosts_constant();
        }
        reconstruct_all(&mut self.rec, [&self.f, &self.mx, &self.my], phi, grid, self.normal, exec);
        let (fs, st) = (self.f.slice(), self.f.stride());
        let (dx, dy, nx, ny) = (grid.dx, grid.dy, grid.nx, grid.ny);
        let rec = &self.rec;
        // the segments: the twelve rows of storage row r hold one component each
        exec.for_each_row(&mut self.seg, 12 * st, |r, rows12| {
            if r < HALO || r >= ny + HALO {
                return;
            }
            for i in HALO..HALO + nx {
                let k = r * st + i;
                let f = fs[k];
                // the segments, then a NaN a_x after the last (the readers stop there)
                let mut s = [f64::NAN; 12];
                let mut n = 0;
                if f_is_interface(f) {
                    let unit = [0.0, 1.0, 0.0, 1.0];
                    let segs = match read_rec(rec, k, st) {
                        Dense::Line(m1, m2, alpha, _) => [line_segment(m1, m2, alpha, unit, dx, dy), None, None],
                        Dense::Slab(m1, m2, lo, hi, rect) => {
                            [line_segment(m1, m2, hi, rect, dx, dy), line_segment(m1, m2, lo, rect, dx, dy), cap_segment(m1, m2, lo, hi, rect, dx, dy)]
                        }
                        Dense::Uniform(_) => [None; 3],
                    };
                    for (m, a) in segs.into_iter().flatten().enumerate() {
                        s[4 * m..4 * m + 4].copy_from_slice(&a);
                        n = m + 1;
                    }
                }
                for (c, x) in s.into_iter().enumerate().take((4 * n + 1).min(12)) {
                    rows12[c * st + i] = x;
                }
            }
        });
        // the columns of each row that hold a segment
        for (j, range) in self.rows.iter_mut().enumerate() {
            let b = 12 * (j + HALO) * st + HALO;
            let row = &self.seg[b..b + nx];
            *range = match (row.iter().position(|x| !x.is_nan()), row.iter().rposition(|x| !x.is_nan())) {
                (Some(a), Some(b)) => (a, b + 1),
                _ => (0, 0),
            };
        }
        for j in 0..ny {
            self.near[j] = rows_union(&self.rows, j, SEARCH_CELLS);
        }
        let near = &self.near;
        let seg = &self.seg;
        let rows = &self.rows;
        let band = BAND_CELLS * grid.h();
        let far = (BAND_CELLS + CHAMFER_STEPS as f64) * grid.h();
        exec.for_each_row(phi.slice_mut(), st, |r, row| {
            if r < HALO || r >= ny + HALO {
                return;
            }
            let j = r - HALO;
            let (jlo, jhi) = (j.saturating_sub(SEARCH_CELLS), (j + SEARCH_CELLS + 1).min(ny));
            for i in 0..nx {
                let k = r * st + i + HALO;
                let dense = if f_is_interface(fs[k]) {
                    // the centre (½, ½) in the cell's dense part (on its line: dense)
                    match read_rec(rec, k, st) {
                        Dense::Line(m1, m2, alpha, _) => 0.5 * (m1 + m2) <= alpha,
                        Dense::Slab(m1, m2, lo, hi, [x0, x1, y0, y1]) => {
                            (lo..=hi).contains(&(0.5 * (m1 + m2))) && (x0..=x1).contains(&0.5) && (y0..=y1).contains(&0.5)
                        }
                        Dense::Uniform(f) => f > 0.5,
                    }
                } else {
                    fs[k] > 0.5
                };
                let (ilo, ihi) = (i.saturating_sub(SEARCH_CELLS), (i + SEARCH_CELLS + 1).min(nx));
                let mut d2 = f64::INFINITY;
                let (nlo, nhi) = near[j];
                if ihi <= nlo || ilo >= nhi {
                    // no segment in the window
                    row[i + HALO] = if dense { far } else { -far };
                    continue;
                }
                for (jj, &(a, b)) in rows.iter().enumerate().take(jhi).skip(jlo) {
                    let (lo, hi) = (ilo.max(a), ihi.min(b));
                    let base = 12 * (jj + HALO) * st + HALO;
                    for ii in lo..hi {
                        // the point: the centre of (i, j) relative to the centre of (ii, jj)
                        let px = (i as f64 - ii as f64) * dx;
                        let py = (j as f64 - jj as f64) * dy;
                        for b in [base, base + 4 * st, base + 8 * st] {
                            let ax = seg[b + ii];
                            if ax.is_nan() {
                                break;
                            }
                            let (ay, bx, by) = (seg[b + st + ii], seg[b + 2 * st + ii], seg[b + 3 * st + ii]);
                            d2 = d2.min(segment_distance2(px, py, ax, ay, bx, by));
                        }
                    }
                }
                let mag = d2.sqrt().min(far);
                row[i + HALO] = if dense { mag } else { -mag };
            }
        });
        // beyond the band: the chamfer distance from the band, by Jacobi sweeps between Φ and
        // `half` (equal outside `reach`, where no sweep can lower the far value)
        let spread = SEARCH_CELLS + CHAMFER_STEPS;
        for j in 0..ny {
            let (a, b) = rows_union(rows, j, spread);
            self.reach[j] = if b > a { (a.saturating_sub(spread), (b + spread).min(nx)) } else { (0, 0) };
        }
        self.half.slice_mut().copy_from_slice(phi.slice());
        let reach = &self.reach;
        let (wx, wy, wd) = (dx, dy, dx.hypot(dy));
        for step in 0..CHAMFER_STEPS {
            let (src, dst) = if step % 2 == 0 { (&*phi, &mut self.half) } else { (&self.half, &mut *phi) };
            let ps = src.slice();
            exec.for_each_row(dst.slice_mut(), st, |r, row| {
                if r < HALO || r >= ny + HALO {
                    return;
                }
                let j = r - HALO;
                let (lo, hi) = reach[j];
                for i in lo..hi {
                    let k = r * st + i + HALO;
                    let p = ps[k];
                    let mut m = p.abs();
                    if m <= band {
                        continue;
                    }
                    let (w, e, s, n) = (i > 0, i + 1 < nx, j > 0, j + 1 < ny);
                    for (ok, o, d) in [
                        (w, k - 1, wx),
                        (e, k + 1, wx),
                        (s, k - st, wy),
                        (n, k + st, wy),
                        (w && s, k - st - 1, wd),
                        (e && s, k - st + 1, wd),
                        (w && n, k + st - 1, wd),
                        (e && n, k + st + 1, wd),
                    ] {
                        if ok {
                            m = m.min(ps[o].abs() + d);
                        }
                    }
                    row[i + HALO] = m.copysign(p);
                }
            });
        }
        phi.extrapolate_ghosts_linear();
    }

    /// Φ as the material properties read it (the module's "Thin zones"): Φ itself wherever a
    /// full cell (F ≥ 1 − [`F_MIN`]) lies within [`THIN_ZONE_CELLS`] cells, and elsewhere the
    /// value whose H_ε is the cell's F (H_ε⁻¹(F); −max(|Φ|, ε) where F ≤ [`F_MIN`]), so that
    /// there ρ = ρ_l + (ρ_d − ρ_l) F. `phi` is the rebuilt Φ with its ghosts filled.
    pub fn properties_level_set(&mut self, phi: &Field, eps: f64, grid: &Grid, exec: Exec) -> &Field {
        self.f.extrapolate_ghosts_constant();
        let (fs, ps, st) = (self.f.slice(), phi.slice(), phi.stride());
        let nx = grid.nx;
        let z = THIN_ZONE_CELLS as isize;
        exec.for_each_row(self.weight.slice_mut(), st, |r, row| {
            if r < HALO || r >= grid.ny + HALO {
                return;
            }
            for (i, w) in row.iter_mut().enumerate().skip(HALO).take(nx) {
                let k = r * st + i;
                let (fk, pk) = (fs[k], ps[k]);
                *w = pk;
                // a full cell, or an empty one outside the blend, reads the same either way
                if fk >= 1.0 - F_MIN || (fk <= F_MIN && pk <= -eps) {
                    continue;
                }
                let full = (-z..=z).any(|dj| {
                    let b = (k as isize + dj * st as isize) as usize;
                    fs[b - THIN_ZONE_CELLS..=b + THIN_ZONE_CELLS].iter().any(|&x| x >= 1.0 - F_MIN)
                });
                if !full {
                    *w = if fk <= F_MIN { -(pk.abs().max(eps)) } else { heaviside_inverse(fk, eps) };
                }
            }
        });
        self.weight.extrapolate_ghosts_linear();
        &self.weight
    }
}

/// The reach, in cells, of the full cell that makes a cell's properties read Φ rather than F
/// ([`VolumeFraction::properties_level_set`]): two cells, beyond the blend's half-width
/// ε = 1.5 h, so that the properties of a layer at least one full cell thick are the level set's.
pub const THIN_ZONE_CELLS: usize = 2;

/// Φ ∈ (−ε, ε) with H_ε(Φ) = f for 0 < f < 1: H_ε is increasing there; bisection to the last bit
/// (62 halvings of [−ε, ε]).
pub fn heaviside_inverse(f: f64, eps: f64) -> f64 {
    let (mut a, mut b) = (-eps, eps);
    for _ in 0..62 {
        let m = 0.5 * (a + b);
        if crate::levelset::heaviside(m, eps) < f {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

impl crate::grid::StateArrays for VolumeFraction {
    /// F and its moments.
    fn visit_state(&self, f: &mut dyn FnMut(&str, &[f64])) {
        f("volume_fraction", self.f.slice());
        f("volume_fraction_moment_x", self.mx.slice());
        f("volume_fraction_moment_y", self.my.slice());
    }

    fn visit_state_mut(&mut self, f: &mut dyn FnMut(&str, &mut [f64])) {
        f("volume_fraction", self.f.slice_mut());
        f("volume_fraction_moment_x", self.mx.slice_mut());
        f("volume_fraction_moment_y", self.my.slice_mut());
    }
}

impl crate::grid::WindowState for VolumeFraction {
    /// F and its moments.
    fn state_fields(&self) -> Vec<&Field> {
        vec![&self.f, &self.mx, &self.my]
    }

    fn state_fields_mut(&mut self) -> Vec<&mut Field> {
        vec![&mut self.f, &mut self.mx, &mut self.my]
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

/// The segment of the line m·X = α (cell units) in the rectangle `rect` = [x₀, x₁, y₀, y₁] of
/// the cell, end points relative to the cell centre (m), ordered so that the side {m·X < α} is
/// on the left of a → b; None where the line misses the rectangle.
#[inline]
fn line_segment(m1: f64, m2: f64, alpha: f64, rect: [f64; 4], dx: f64, dy: f64) -> Option<[f64; 4]> {
    if m1 == 0.0 && m2 == 0.0 {
        return None;
    }
    // the line m·X = α clipped to [0, 1]²: X = p + t d, p = α m/|m|², d = (−m₂, m₁)
    let n2 = m1 * m1 + m2 * m2;
    let (px, py) = (alpha * m1 / n2, alpha * m2 / n2);
    let (ddx, ddy) = (-m2, m1);
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for (p, d, r0, r1) in [(px, ddx, rect[0], rect[1]), (py, ddy, rect[2], rect[3])] {
        if d != 0.0 {
            let (a, b) = ((r0 - p) / d, (r1 - p) / d);
            lo = lo.max(a.min(b));
            hi = hi.min(a.max(b));
        } else if !(r0..=r1).contains(&p) {
            return None;
        }
    }
    if lo.is_nan() || hi.is_nan() || lo > hi {
        return None;
    }
    // d = (−m₂, m₁) is m turned left, so m points to the right of a → b and the dense side
    // (m·X < α) is on its left
    let at = |t: f64| (((px + t * ddx).clamp(rect[0], rect[1]) - 0.5) * dx, ((py + t * ddy).clamp(rect[2], rect[3]) - 0.5) * dy);
    let (a, b) = (at(lo), at(hi));
    Some([a.0, a.1, b.0, b.1])
}

/// The end of a capped slab: the part of its rectangle's side inside the cell's interior that
/// lies between the slab's lines (relative to the cell centre, m); None for an uncapped slab.
#[inline]
fn cap_segment(m1: f64, m2: f64, lo: f64, hi: f64, rect: [f64; 4], dx: f64, dy: f64) -> Option<[f64; 4]> {
    let [x0, x1, y0, y1] = rect;
    // the capped side: a side of the rectangle strictly inside the cell
    let (fixed, along_x) = if x0 > 0.0 {
        (x0, false)
    } else if x1 < 1.0 {
        (x1, false)
    } else if y0 > 0.0 {
        (y0, true)
    } else if y1 < 1.0 {
        (y1, true)
    } else {
        return None;
    };
    // on the side, t runs along it: lo ≤ m_fixed·fixed + m_t·t ≤ hi, t ∈ [t₀, t₁]
    let (mf, mt, t0, t1) = if along_x { (m2, m1, x0, x1) } else { (m1, m2, y0, y1) };
    let (mut a, mut b) = (t0, t1);
    if mt != 0.0 {
        let (ta, tb) = ((lo - mf * fixed) / mt, (hi - mf * fixed) / mt);
        a = a.max(ta.min(tb));
        b = b.min(ta.max(tb));
    } else if !(lo..=hi).contains(&(mf * fixed)) {
        return None;
    }
    if a > b {
        return None;
    }
    let pt = |t: f64| if along_x { ((t - 0.5) * dx, (fixed - 0.5) * dy) } else { ((fixed - 0.5) * dx, (t - 0.5) * dy) };
    let (p, q) = (pt(a), pt(b));
    Some([p.0, p.1, q.0, q.1])
}

/// The columns [first, last + 1) holding a segment in the rows j ± `k` (`rows` per row; (usize::MAX,
/// 0) where none does).
fn rows_union(rows: &[(usize, usize)], j: usize, k: usize) -> (usize, usize) {
    let (lo, hi) = (j.saturating_sub(k), (j + k + 1).min(rows.len()));
    rows[lo..hi].iter().filter(|r| r.1 > r.0).fold((usize::MAX, 0), |(a, b), r| (a.min(r.0), b.max(r.1)))
}

/// A cell of the interface: F_MIN < F < 1 − F_MIN.
#[inline]
fn f_is_interface(f: f64) -> bool {
    f > F_MIN && f < 1.0 - F_MIN
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

/// The dense part of a cell, in cell units X ∈ [0, 1]².
#[derive(Clone, Copy, Debug, PartialEq)]
enum Dense {
    /// F spread evenly over the cell: a pure cell (F ≤ 0 or ≥ 1) or one without a normal.
    Uniform(f64),
    /// {m₁X + m₂Y ≤ α} (m₁, m₂, α, F): the PLIC half-plane.
    Line(f64, f64, f64, f64),
    /// {α_lo ≤ m₁X + m₂Y ≤ α_hi} ∩ [x₀, x₁] × [y₀, y₁] (m₁, m₂, α_lo, α_hi, the rectangle): a
    /// film's slab, capped where the film ends (the module's "Films").
    Slab(f64, f64, f64, f64, [f64; 4]),
}

/// Rows of [`VolumeFraction`]'s reconstruction buffer per storage row: kind, m₁, m₂, α_lo (a
/// line's F), α_hi (a line's α) and a slab's rectangle.
const REC: usize = 9;

/// The reconstruction of cell k from `rec` ([`reconstruct_all`]'s layout).
#[inline]
fn read_rec(rec: &[f64], k: usize, st: usize) -> Dense {
    let b = REC * (k / st) * st + k % st;
    let at = |c: usize| rec[b + c * st];
    let (kind, m1, m2, lo, hi) = (at(0), at(1), at(2), at(3), at(4));
    if kind == 1.0 {
        Dense::Line(m1, m2, hi, lo)
    } else if kind == 2.0 {
        Dense::Slab(m1, m2, lo, hi, [at(5), at(6), at(7), at(8)])
    } else {
        Dense::Uniform(m1)
    }
}

/// Reconstructs every mixed cell, 0 < F < 1 (ghosts to one cell from the storage's edge
/// included; a pure cell's readers take F itself), from F, its moments and Φ into `rec` ([`REC`] rows per storage row).
fn reconstruct_all(rec: &mut [f64], src: [&Field; 3], phi: &Field, grid: &Grid, normal: PlicNormal, exec: Exec) {
    let (fs, mxs, mys, ps, st) = (src[0].slice(), src[1].slice(), src[2].slice(), phi.slice(), src[0].stride());
    let rows = fs.len() / st;
    let (dx, dy) = (grid.dx, grid.dy);
    exec.for_each_row(rec, REC * st, |r, out| {
        if r == 0 || r + 1 >= rows {
            return;
        }
        for i in 1..st - 1 {
            let k = r * st + i;
            if fs[k] <= 0.0 || fs[k] >= 1.0 {
                // a pure cell: its readers take F itself
                continue;
            }
            let d = reconstruct(fs, [mxs, mys], ps, k, st, normal, dx, dy);
            // the components `read_rec` reads for the kind
            let (v, n) = match d {
                Dense::Uniform(f) => ([0.0, f, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 2),
                Dense::Line(m1, m2, alpha, f) => ([1.0, m1, m2, f, alpha, 0.0, 0.0, 0.0, 0.0], 5),
                Dense::Slab(m1, m2, lo, hi, r) => ([2.0, m1, m2, lo, hi, r[0], r[1], r[2], r[3]], REC),
            };
            for (c, x) in v.into_iter().enumerate().take(n) {
                out[c * st + i] = x;
            }
        }
    });
}

/// The dense part of cell k (the module's "Films"): a pure cell's F spread evenly; a film cell's
/// slab ([`shape_of`], [`slab_in`]); otherwise the PLIC line of the cell's normal; each capped
/// ([`capped`]) where it ends a film or a layer at most a cell thick.
#[allow(clippy::too_many_arguments)]
#[inline]
fn reconstruct(fs: &[f64], ms: [&[f64]; 2], ps: &[f64], k: usize, st: usize, normal: PlicNormal, dx: f64, dy: f64) -> Dense {
    let f = fs[k];
    let moments = [ms[0][k], ms[1][k]];
    if f <= 0.0 || f >= 1.0 {
        return Dense::Uniform(f);
    }
    if f < SPECK {
        return speck(f, moments);
    }
    let shape = shape_of(fs, moments, k, st, dx, dy);
    if shape.film {
        let (m1, m2) = shape.normal;
        return capped(m1, m2, f, moments, shape.end, |rect| slab_in(m1, m2, f, moments, rect));
    }
    let (m1, m2) = cell_normal(fs, ps, k, st, normal);
    if m1 == 0.0 && m2 == 0.0 {
        return Dense::Uniform(f);
    }
    if shape.end {
        // {m·X ≤ α} ∩ rect: a slab whose lower line misses the cell
        let below = -(m1.abs() + m2.abs()) - 1.0;
        return capped(m1, m2, f, moments, true, |rect: [f64; 4]| {
            let (wx, wy) = (rect[1] - rect[0], rect[3] - rect[2]);
            (below, plic_alpha(m1 * wx, m2 * wy, (f / (wx * wy)).min(1.0)) + m1 * rect[0] + m2 * rect[2])
        });
    }
    Dense::Line(m1, m2, plic_alpha(m1, m2, f), f)
}

/// Below this F a cell's dense part is a speck (`speck`).
pub const SPECK: f64 = F_MIN;

/// A speck's dense part: the square of area F centred at its centroid (kept inside the cell),
/// as the slab {y₀ ≤ Y ≤ y₁} of the columns [x₀, x₁].
fn speck(f: f64, moments: [f64; 2]) -> Dense {
    let side = f.sqrt();
    let centre = |m: f64| (m / f + 0.5).clamp(0.5 * side, 1.0 - 0.5 * side);
    let (cx, cy) = (centre(moments[0]), centre(moments[1]));
    Dense::Slab(0.0, 1.0, cy - 0.5 * side, cy + 0.5 * side, [cx - 0.5 * side, cx + 0.5 * side, 0.0, 1.0])
}

/// What the 3 × 3 cells about a cell say of its dense part ([`shape_of`]).
struct Shape {
    /// The normal (n_x δx, n_y δy) across the cells' direction.
    normal: (f64, f64),
    /// Its two neighbours across hold less than [`FILM_RATIO`] of its F each.
    film: bool,
    /// The cells on one side of it along the direction hold less than [`FILM_RATIO`] of its F,
    /// and it is a film cell or no cell about it is full.
    end: bool,
}

/// The direction of the dense phase about cell k and whether the cell is a film cell or an end.
/// The direction is the major axis of the second moment of F over the 3 × 3 cells about their
/// centroid, the normal n its minor axis. The cell is a film cell when its two neighbours
/// across it (along n rounded to one of the eight lattice directions) each hold less than
/// [`FILM_RATIO`] of its F: no single line can then bound its dense part, which lies between
/// two. It is an end when the cells on one side of it along the direction (|τ·offset| > ½ h)
/// hold less than [`FILM_RATIO`] of its F together.
#[inline]
fn shape_of(fs: &[f64], moments: [f64; 2], k: usize, st: usize, dx: f64, dy: f64) -> Shape {
    let f = |di: isize, dj: isize| fs[(k as isize + dj * st as isize + di) as usize].clamp(0.0, 1.0);
    let pos = |di: isize, dj: isize| (di as f64 * dx, dj as f64 * dy);
    let (mut m0, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for dj in -1..=1isize {
        for di in -1..=1isize {
            let w = f(di, dj);
            let (px, py) = pos(di, dj);
            m0 += w;
            sx += w * px;
            sy += w * py;
        }
    }
    let (xb, yb) = (sx / m0, sy / m0);
    let (mut cxx, mut cyy, mut cxy) = (0.0, 0.0, 0.0);
    for dj in -1..=1isize {
        for di in -1..=1isize {
            let w = f(di, dj);
            let (px, py) = pos(di, dj);
            let (a, b) = (px - xb, py - yb);
            cxx += w * a * a;
            cyy += w * b * b;
            cxy += w * a * b;
        }
    }
    let half = 0.5 * (cxx + cyy);
    let spread = (0.25 * (cxx - cyy) * (cxx - cyy) + cxy * cxy).sqrt();
    let (nx, ny) = if spread <= 1e-12 * half {
        // no direction in F (an isolated speck, an even blot): across the larger moment
        if (moments[0] * dy).abs() > (moments[1] * dx).abs() {
            (1.0, 0.0)
        } else {
            (0.0, 1.0)
        }
    } else {
        // the eigenvector of the smaller eigenvalue half − spread
        let lmin = half - spread;
        let (a, b) = if cxx - lmin > cyy - lmin { (cxy, lmin - cxx) } else { (lmin - cyy, cxy) };
        let n = a.hypot(b);
        (a / n, b / n)
    };
    let (ri, rj) = (nx.round() as isize, ny.round() as isize);
    let fc = f(0, 0);
    let film = f(ri, rj) < FILM_RATIO * fc && f(-ri, -rj) < FILM_RATIO * fc;
    // the cells ahead and behind along the direction τ = (−n_y, n_x)
    let (mut ahead, mut behind) = (0.0, 0.0);
    let h = dx.min(dy);
    for dj in -1..=1isize {
        for di in -1..=1isize {
            let t = (-ny * di as f64 * dx + nx * dj as f64 * dy) / h;
            if t > 0.5 {
                ahead += f(di, dj);
            } else if t < -0.5 {
                behind += f(di, dj);
            }
        }
    }
    // an end of a film, or of a layer at most a cell thick (no full cell about it); a corner of
    // a thicker body keeps its line
    let full = (-1..=1isize).any(|dj| (-1..=1isize).any(|di| f(di, dj) >= 1.0 - F_MIN));
    let end = ahead.min(behind) < FILM_RATIO * fc && (film || !full);
    Shape { normal: (nx * dx, ny * dy), film, end }
}

/// A film cell's neighbours across it, and an end's cells on one side along it, hold less than
/// this share of its F (`shape_of`).
pub const FILM_RATIO: f64 = 0.5;

/// The slab {α_lo ≤ m·X ≤ α_hi} ∩ `rect` of area F whose first moment along m is the cell's
/// (`moments`, about the centre): the area A below it (a share of the rectangle's) found by
/// regula falsi ([`root_increasing`]; its moment grows with A); a moment beyond what a slab
/// reaches puts it against the rectangle's side. Returns (α_lo, α_hi).
fn slab_in(m1: f64, m2: f64, f: f64, moments: [f64; 2], rect: [f64; 4]) -> (f64, f64) {
    let [x0, x1, y0, y1] = rect;
    let (wx, wy) = (x1 - x0, y1 - y0);
    // in the rectangle's unit coordinates X' = (X − x₀)/w_x: the normal (m₁w_x, m₂w_y), the
    // share F/(w_x w_y), and α = α' + m₁x₀ + m₂y₀
    let (n1, n2, share, shift) = (m1 * wx, m2 * wy, (f / (wx * wy)).min(1.0), m1 * x0 + m2 * y0);
    let along = |alpha: f64| {
        let c = cut_moments(m1, m2, alpha, rect);
        m1 * c[1] + m2 * c[2]
    };
    let target = m1 * (moments[0] + 0.5 * f) + m2 * (moments[1] + 0.5 * f);
    let place = |a: f64| {
        let (lo, hi) = (plic_alpha(n1, n2, a) + shift, plic_alpha(n1, n2, a + share) + shift);
        (lo, hi, along(hi) - along(lo))
    };
    let a1 = (1.0 - share).max(0.0);
    let (lo0, hi0, g0) = place(0.0);
    if target <= g0 {
        return (lo0, hi0);
    }
    let (lo1, hi1, g1) = place(a1);
    if target >= g1 {
        return (lo1, hi1);
    }
    let a = root_increasing(|a| place(a).2 - target, 0.0, a1, g0 - target, g1 - target);
    let (lo, hi, _) = place(a);
    (lo, hi)
}

/// The root of g, increasing on [a, b] with g(a) = `ga` < 0 < `gb` = g(b), by regula falsi with
/// the Illinois halving (Dowell & Jarratt 1971, *BIT* 11): to [`ROOT_TOLERANCE`] of the bracket
/// or of g, in at most [`ROOT_ITERATIONS`] evaluations.
fn root_increasing(g: impl Fn(f64) -> f64, mut a: f64, mut b: f64, mut ga: f64, mut gb: f64) -> f64 {
    let scale = ga.abs().max(gb.abs());
    let mut side = 0i8;
    for _ in 0..ROOT_ITERATIONS {
        let x = (a * gb - b * ga) / (gb - ga);
        let gx = g(x);
        if gx.abs() <= ROOT_TOLERANCE * scale || b - a <= ROOT_TOLERANCE {
            return x;
        }
        if gx < 0.0 {
            a = x;
            ga = gx;
            if side == -1 {
                gb *= 0.5;
            }
            side = -1;
        } else {
            b = x;
            gb = gx;
            if side == 1 {
                ga *= 0.5;
            }
            side = 1;
        }
    }
    (a * gb - b * ga) / (gb - ga)
}

/// [`root_increasing`]'s relative tolerance.
const ROOT_TOLERANCE: f64 = 1e-9;

/// [`root_increasing`]'s evaluations at most (it converges superlinearly: 5–12 here).
const ROOT_ITERATIONS: usize = 60;

/// A dense part of area F bounded by the lines m·X = α_lo, α_hi that `fit` places in a
/// rectangle of the cell (a film's slab, [`slab_in`], or a half-plane), capped along the
/// lattice axis nearest the interface's direction where the cell ends the film (`end`) and its
/// moment along that axis lies beyond the uncapped part's: the part then fills [γ, 1] (or
/// [0, 1 − γ]) of the cell along the axis, γ ∈ [0, 1 − F] found by regula falsi so that the
/// moments agree.
fn capped(m1: f64, m2: f64, f: f64, moments: [f64; 2], end: bool, fit: impl Fn([f64; 4]) -> (f64, f64)) -> Dense {
    let unit = [0.0, 1.0, 0.0, 1.0];
    // the interface's direction (−m₂, m₁): nearer x when |m₂| ≥ |m₁|
    let ax = if m2.abs() >= m1.abs() { 0 } else { 1 };
    let target = moments[ax] / f + 0.5;
    let centroid = |lo: f64, hi: f64, rect: [f64; 4]| {
        let (a, b) = (cut_moments(m1, m2, hi, rect), cut_moments(m1, m2, lo, rect));
        let area = a[0] - b[0];
        if area > 0.0 {
            (a[1 + ax] - b[1 + ax]) / area
        } else {
            0.5 * (rect[2 * ax] + rect[2 * ax + 1])
        }
    };
    let (lo, hi) = fit(unit);
    let g0 = centroid(lo, hi, unit);
    if !end || (target - g0).abs() <= CAP_TOLERANCE {
        return Dense::Slab(m1, m2, lo, hi, unit);
    }
    let up = target > g0;
    let rect_of = |gamma: f64| {
        let mut r = unit;
        if up {
            r[2 * ax] = gamma;
        } else {
            r[2 * ax + 1] = 1.0 - gamma;
        }
        r
    };
    // the centroid along the axis moves towards the kept side as γ grows
    let reach = |gamma: f64| {
        let r = rect_of(gamma);
        let (lo, hi) = fit(r);
        (lo, hi, r, centroid(lo, hi, r))
    };
    // the centroid's distance past the target, towards the kept side: increasing in γ
    let sign = if up { 1.0 } else { -1.0 };
    let g_hi = (1.0 - f).max(0.0);
    let last = reach(g_hi);
    if sign * (last.3 - target) <= 0.0 {
        return Dense::Slab(m1, m2, last.0, last.1, last.2);
    }
    let gamma = root_increasing(|g| sign * (reach(g).3 - target), 0.0, g_hi, sign * (g0 - target), sign * (last.3 - target));
    let (lo, hi, r, _) = reach(gamma);
    Dense::Slab(m1, m2, lo, hi, r)
}

/// An end whose centroid along the axis lies within this (cell units) of its uncapped part's
/// stays uncapped.
const CAP_TOLERANCE: f64 = 1e-9;

/// The area and first moments [A, ∫X dA, ∫Y dA] of {a X + b Y ≤ α} ∩ [x₀, x₁] × [y₀, y₁]
/// (cell units; `rect` = [x₀, x₁, y₀, y₁]): the rectangle clipped by the half-plane
/// (Sutherland–Hodgman, at most five vertices) and the shoelace sums.
pub fn cut_moments(a: f64, b: f64, alpha: f64, rect: [f64; 4]) -> [f64; 3] {
    let [x0, x1, y0, y1] = rect;
    let corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
    let mut poly = [(0.0, 0.0); 6];
    let mut n = 0;
    for e in 0..4 {
        let (p, q) = (corners[e], corners[(e + 1) % 4]);
        let (dp, dq) = (alpha - a * p.0 - b * p.1, alpha - a * q.0 - b * q.1);
        if dp >= 0.0 {
            poly[n] = p;
            n += 1;
        }
        if (dp >= 0.0) != (dq >= 0.0) {
            let t = dp / (dp - dq);
            poly[n] = (p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1));
            n += 1;
        }
    }
    if n < 3 {
        return [0.0; 3];
    }
    let (mut a2, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for e in 0..n {
        let (p, q) = (poly[e], poly[(e + 1) % n]);
        let cross = p.0 * q.1 - q.0 * p.1;
        a2 += cross;
        sx += (p.0 + q.0) * cross;
        sy += (p.1 + q.1) * cross;
    }
    [0.5 * a2, sx / 6.0, sy / 6.0]
}

/// The moments about the cell's centre, F(X̄ − ½, Ȳ − ½), of a dense part of area F whose
/// shape's area and first moments are `c` ([`cut_moments`]); zero where the shape is empty.
#[inline]
fn centred_moments(f: f64, c: [f64; 3]) -> [f64; 2] {
    if c[0] > 0.0 {
        [f * (c[1] / c[0] - 0.5), f * (c[2] / c[0] - 0.5)]
    } else {
        [0.0; 2]
    }
}

/// The dense area that crosses a face in a step of Courant number `c` from the upwind cell whose
/// dense part is `d`, and its first moments [∫ξ dA, ∫η dA] in the upwind cell's coordinates
/// (ξ along the sweep, η across): signed area (> 0 towards the higher index), moments.
#[inline]
fn swept(c: f64, d: Dense, axis: Axis) -> (f64, [f64; 2]) {
    if c == 0.0 {
        return (0.0, [0.0; 2]);
    }
    let w = c.abs();
    // the strip, along the sweep: ξ ∈ [1 − w, 1] for c > 0, [0, w] for c < 0
    let (s0, s1) = if c > 0.0 { (1.0 - w, 1.0) } else { (0.0, w) };
    let rect = match axis {
        Axis::X => [s0, s1, 0.0, 1.0],
        Axis::Y => [0.0, 1.0, s0, s1],
    };
    let order = |m: [f64; 3]| match axis {
        Axis::X => [m[1], m[2]],
        Axis::Y => [m[2], m[1]],
    };
    let (vol, mom) = match d {
        Dense::Uniform(f) => {
            let vol = f * w;
            (vol, [vol * 0.5 * (s0 + s1), vol * 0.5])
        }
        Dense::Line(m1, m2, alpha, f) => {
            let vol = match axis {
                Axis::X => swept_volume(c, f, m1, m2).abs(),
                Axis::Y => swept_volume(c, f, m2, m1).abs(),
            };
            let cut = cut_moments(m1, m2, alpha, rect);
            let m = order(cut);
            if cut[0] > 0.0 {
                (vol, [vol * m[0] / cut[0], vol * m[1] / cut[0]])
            } else {
                (vol, [vol * 0.5 * (s0 + s1), vol * 0.5])
            }
        }
        Dense::Slab(m1, m2, lo, hi, r) => {
            let rect = [rect[0].max(r[0]), rect[1].min(r[1]), rect[2].max(r[2]), rect[3].min(r[3])];
            if rect[0] >= rect[1] || rect[2] >= rect[3] {
                return (0.0, [0.0; 2]);
            }
            let (a, b) = (cut_moments(m1, m2, hi, rect), cut_moments(m1, m2, lo, rect));
            let vol = (a[0] - b[0]).max(0.0);
            let m = order([0.0, a[1] - b[1], a[2] - b[2]]);
            (vol, m)
        }
    };
    if c > 0.0 {
        (vol, mom)
    } else {
        (-vol, mom)
    }
}

/// One sweep along `axis` from `src` (F, M_x, M_y) into `out` (their ghosts filled): F' = F −
/// (flux differences) + c (Courant differences), c = H(Fⁿ − ½) with Fⁿ the source's F
/// (`c_from_out` false) or `out`'s before it is written (true), and the moments of the parts
/// that stay (carried by the linear velocity between the cell's faces) and of those that come
/// in (carried by their face's velocity). Returns the sweep's part of the budget.
#[allow(clippy::too_many_arguments)]
fn sweep(
    out: [&mut Field; 3],
    src: [&Field; 3],
    c_from_out: bool,
    rec: &[f64],
    u: &Field,
    v: &Field,
    grid: &Grid,
    dt: f64,
    axis: Axis,
    exec: Exec,
) -> VolumeBudget {
    let (nx, ny, st) = (grid.nx, grid.ny, src[0].stride());
    let (ss, mxs, mys) = (src[0].slice(), src[1].slice(), src[2].slice());
    let (us, vs) = (u.slice(), v.slice());
    let (ust, vst) = (u.stride(), v.stride());
    let (cx, cy) = (dt / grid.dx, dt / grid.dy);
    // the piece through the face between cells kl (low) and kh (high) with Courant number c
    let piece = move |c: f64, kl: usize, kh: usize| -> (f64, [f64; 2]) {
        if c == 0.0 {
            return (0.0, [0.0; 2]);
        }
        let k = if c > 0.0 { kl } else { kh };
        let f = ss[k];
        // a pure cell's part is read from F (its reconstruction is not written)
        let d = if f <= 0.0 || f >= 1.0 { Dense::Uniform(f) } else { read_rec(rec, k, st) };
        swept(c, d, axis)
    };
    // the Courant number of face `i` (x) or `j` (y) of row j
    let courant = move |i: usize, j: usize| -> f64 {
        match axis {
            Axis::X => us[(j + HALO) * ust + i + HALO] * cx,
            Axis::Y => vs[(j + HALO) * vst + i + HALO] * cy,
        }
    };
    let cells = grid.cells();
    // the divergence term Σ c (C_hi − C_lo) of the budget, c from Fⁿ
    let fnow = if c_from_out { out[0].slice() } else { ss };
    let divergence = exec.sum_rows(ny, cells, |j| {
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
    });
    let [fo, mxo, myo] = out;
    exec.for_each_row3(fo.slice_mut(), mxo.slice_mut(), myo.slice_mut(), st, |r, frow, mxrow, myrow| {
        if r < HALO || r >= ny + HALO {
            return;
        }
        let j = r - HALO;
        let mut lo = match axis {
            Axis::X => piece(courant(0, j), r * st + HALO - 1, r * st + HALO),
            Axis::Y => (0.0, [0.0; 2]),
        };
        for i in 0..nx {
            let k = r * st + i + HALO;
            let fc = ss[k];
            let fn_ = if c_from_out { frow[i + HALO] } else { fc };
            let c = if fn_ > 0.5 { 1.0 } else { 0.0 };
            let (clo, chi) = match axis {
                Axis::X => (courant(i, j), courant(i + 1, j)),
                Axis::Y => (courant(i, j), courant(i, j + 1)),
            };
            let hi = match axis {
                Axis::X => piece(chi, k, k + 1),
                Axis::Y => {
                    lo = piece(clo, k - st, k);
                    piece(chi, k, k + st)
                }
            };
            let dv = c * (chi - clo);
            let fnew = fc - (hi.0 - lo.0) + dv;
            if fnew == 0.0 || fnew == 1.0 {
                // a pure cell: no moments
                frow[i + HALO] = fnew;
                mxrow[i + HALO] = 0.0;
                myrow[i + HALO] = 0.0;
                lo = hi;
                continue;
            }
            // moments: (ξ, η) the own cell's coordinates along and across the sweep
            let (mxi, meta) = match axis {
                Axis::X => (mxs[k], mys[k]),
                Axis::Y => (mys[k], mxs[k]),
            };
            let (mut a, mut pxi, mut peta) = (fc, mxi + 0.5 * fc, meta + 0.5 * fc);
            if chi > 0.0 {
                a -= hi.0;
                pxi -= hi.1[0];
                peta -= hi.1[1];
            }
            if clo < 0.0 {
                a += lo.0;
                pxi -= lo.1[0];
                peta -= lo.1[1];
            }
            // what stays moves with the velocity linear between the faces: ξ → ξ + C_lo + (C_hi − C_lo) ξ
            pxi = (1.0 + chi - clo) * pxi + clo * a;
            if clo > 0.0 {
                a += lo.0;
                pxi += lo.1[0] + lo.0 * (clo - 1.0);
                peta += lo.1[1];
            }
            if chi < 0.0 {
                a -= hi.0;
                pxi += hi.1[0] + (-hi.0) * (1.0 + chi);
                peta += hi.1[1];
            }
            if dv != 0.0 {
                let (cxi, ceta) = if a > 0.0 { (pxi / a, peta / a) } else { (0.5, 0.5) };
                pxi += dv * cxi;
                peta += dv * ceta;
            }
            // a dense part of area F has its centroid within (1 − F)/2 of the centre on each axis
            let reach = 0.5 * fnew * (1.0 - fnew);
            let (mxi, meta) =
                if fnew > 0.0 && fnew < 1.0 { ((pxi - 0.5 * fnew).clamp(-reach, reach), (peta - 0.5 * fnew).clamp(-reach, reach)) } else { (0.0, 0.0) };
            let (mx, my) = match axis {
                Axis::X => (mxi, meta),
                Axis::Y => (meta, mxi),
            };
            frow[i + HALO] = fnew;
            mxrow[i + HALO] = mx;
            myrow[i + HALO] = my;
            lo = hi;
        }
    });
    for fld in [fo, mxo, myo] {
        fld.extrapolate_ghosts_constant();
    }
    let flux = |c: f64, kl: usize, kh: usize| piece(c, kl, kh).0;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Area and moments of the region `d` in the unit cell, from its own clipping.
    fn region(d: Dense) -> [f64; 3] {
        match d {
            Dense::Slab(m1, m2, lo, hi, r) => {
                let (a, b) = (cut_moments(m1, m2, hi, r), cut_moments(m1, m2, lo, r));
                [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
            }
            Dense::Line(m1, m2, alpha, _) => cut_moments(m1, m2, alpha, [0.0, 1.0, 0.0, 1.0]),
            Dense::Uniform(f) => [f, 0.5 * f, 0.5 * f],
        }
    }

    #[test]
    fn cut_moments_are_those_of_the_clipped_polygon() {
        // below X + Y = ½: the triangle (0, 0), (½, 0), (0, ½): area ⅛, centroid (⅙, ⅙)
        let c = cut_moments(1.0, 1.0, 0.5, [0.0, 1.0, 0.0, 1.0]);
        assert!((c[0] - 0.125).abs() < 1e-16 && (c[1] - 0.125 / 6.0).abs() < 1e-16 && (c[2] - 0.125 / 6.0).abs() < 1e-16, "{c:?}");
        // Y ≤ 0.3 in [0.2, 0.6] × [0, 1]: area 0.12, centroid (0.4, 0.15)
        let c = cut_moments(0.0, 1.0, 0.3, [0.2, 0.6, 0.0, 1.0]);
        assert!((c[0] - 0.12).abs() < 1e-15 && (c[1] - 0.048).abs() < 1e-15 && (c[2] - 0.018).abs() < 1e-15, "{c:?}");
        // the area agrees with the closed form of plic_area for any line
        for &(a, b) in &[(0.3, 0.7), (-0.2, 0.9), (0.8, -0.4)] {
            for k in 1..10 {
                let f = k as f64 / 10.0;
                let c = cut_moments(a, b, plic_alpha(a, b, f), [0.0, 1.0, 0.0, 1.0]);
                assert!((c[0] - f).abs() < 1e-14, "({a}, {b}), F = {f}: {}", c[0]);
            }
        }
    }

    /// A film cell's slab, capped or not, has the cell's area and first moments (round-off, and
    /// the root finder's tolerance for the centroid).
    #[test]
    fn a_films_slab_has_the_cells_area_and_moments() {
        for &(nx, ny) in &[(0.0, 1.0), (0.6, 0.8), (-0.28, 0.96), (1.0, 0.0)] {
            for &(f, cx, cy) in &[(0.3, 0.4, 0.55), (0.1, 0.8, 0.5), (0.05, 0.3, 0.7), (0.45, 0.5, 0.45)] {
                let moments = [f * (cx - 0.5), f * (cy - 0.5)];
                // the film's part: a slab, capped where the centroid along the film asks for it
                let d = capped(nx, ny, f, moments, true, |rect| slab_in(nx, ny, f, moments, rect));
                let r = region(d);
                assert!((r[0] - f).abs() < 1e-12, "area {} against {f}", r[0]);
                // each of these centroids lies within a capped slab's reach: matched
                assert!((r[1] / r[0] - cx).hypot(r[2] / r[0] - cy) < 1e-6, "({nx}, {ny}), F = {f}, centroid ({cx}, {cy}): {d:?}");
            }
        }
    }

    /// A film ½ cell thick lying in one row: its cells are film cells, their slabs the film's.
    #[test]
    fn a_film_in_one_row_is_rebuilt_as_its_slab() {
        let st = 7;
        let mut fs = vec![0.0; st * 5];
        let mut ms = [vec![0.0; st * 5], vec![0.0; st * 5]];
        // row 2 holds Y ∈ [0.2, 0.7] across columns 1..6
        for i in 1..6 {
            fs[2 * st + i] = 0.5;
            ms[1][2 * st + i] = 0.5 * (0.45 - 0.5);
        }
        let k = 2 * st + 3;
        let shape = shape_of(&fs, [ms[0][k], ms[1][k]], k, st, 1.0, 1.0);
        assert!(shape.film && !shape.end);
        assert!(shape.normal.0.abs() < 1e-15 && (shape.normal.1.abs() - 1.0).abs() < 1e-15);
        let ps = vec![0.0; st * 5];
        let d = reconstruct(&fs, [&ms[0], &ms[1]], &ps, k, st, PlicNormal::LevelSet, 1.0, 1.0);
        match d {
            Dense::Slab(m1, m2, lo, hi, rect) => {
                assert_eq!(rect, [0.0, 1.0, 0.0, 1.0]);
                // the slab's sides at Y = 0.2 and 0.7
                let (a, b) = if m2 > 0.0 { (lo / m2, hi / m2) } else { (hi / m2, lo / m2) };
                assert!(m1.abs() < 1e-15 && (a - 0.2).abs() < 1e-9 && (b - 0.7).abs() < 1e-9, "{d:?}");
            }
            _ => panic!("{d:?}"),
        }
        // the film's last cell is an end: capped along x
        let k = 2 * st + 5;
        ms[0][k] = 0.5 * (0.3 - 0.5);
        let shape = shape_of(&fs, [ms[0][k], ms[1][k]], k, st, 1.0, 1.0);
        assert!(shape.film && shape.end);
        let d = reconstruct(&fs, [&ms[0], &ms[1]], &ps, k, st, PlicNormal::LevelSet, 1.0, 1.0);
        let r = region(d);
        assert!((r[0] - 0.5).abs() < 1e-12 && (r[1] / r[0] - 0.3).abs() < 1e-8 && (r[2] / r[0] - 0.45).abs() < 1e-8, "{d:?} {r:?}");
    }
}
