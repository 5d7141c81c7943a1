//! Standard level-set transport benchmarks (docs/reference-data.md, "Level-set transport"), run end to end with the
//! production transport and redistancing.
//!
//! - Zalesak (1979, J. Comput. Phys. 31) slotted disk: \[0,100\]², disk centre (50, 75), radius 15,
//!   slot width 5, slot top y = 85, solid rotation u = (π/314)(50 − y), v = (π/314)(x − 50); one
//!   revolution at t = 628 returns the exact initial shape, of area 582.207 (closed form in
//!   [`Shape::area`]).
//! - Rider & Kothe (1998, J. Comput. Phys. 141) single vortex: circle of radius 0.15 at
//!   (0.5, 0.75) in \[0,1\]², u = −sin²(πx) sin(2πy) cos(πt/T), v = sin²(πy) sin(2πx) cos(πt/T);
//!   the flow reverses, and at t = T the exact solution is the initial circle.
//!
//! Velocities are sampled at the MAC faces (u on x-faces, v on y-faces), as the flow solver will
//! provide them. The time step is uniform, δt = T / ⌈T · rate / cfl⌉ with rate =
//! max(|u_c|/dx + |v_c|/dy) (the vortex's rate is largest at t = 0), so that the run ends exactly
//! at T. For the vortex each Runge–Kutta stage sees the velocity at its own time.
//!
//! Metrics: the dense-phase area against the exact area, measured with the bicubic-refined
//! estimate ([`dense_area_refined`], 8 × 8 sub-cells per cut cell: its own error on the initial
//! shapes is below 10⁻⁴ relative, against 7·10⁻⁴ for the second-order [`super::dense_area`] on
//! the 100² disk), and the area of the symmetric difference with the exact final shape (8 × 8
//! bilinear samples per cell, [`symmetric_difference_area`]), both relative to the exact area.

use super::diagnostics::{dense_area_refined, symmetric_difference_area};
use super::redistance::{RedistanceSettings, Redistancer};
use super::shapes::{init_signed_distance, Shape};
use super::transport::{max_transport_rate, LevelSetTransport};
use super::vof::{InterfaceTransport, PlicNormal, VolumeFraction};
use super::weno5::WenoWeights;
use crate::error::{check_positive, Error, Result};
use crate::exec::Exec;
use crate::grid::{Field, Grid, Location};
use std::f64::consts::PI;

/// Sub-samples per cell side used for the symmetric-difference metric.
pub const SYMDIFF_SUB: usize = 8;

/// Sub-cells per side of the refined area estimate ([`dense_area_refined`]).
pub const AREA_SUB: usize = 8;

/// The outcome of a level-set benchmark.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelSetMetrics {
    /// Cells per side.
    pub n: usize,
    /// Time steps taken.
    pub steps: usize,
    /// Time step.
    pub dt: f64,
    /// Final time (= the period).
    pub final_time: f64,
    /// Redistancing calls made.
    pub redistance_calls: usize,
    /// Exact area of the shape.
    pub area_exact: f64,
    /// Discrete area of the initial Φ.
    pub area_initial: f64,
    /// Discrete area of the final Φ.
    pub area_final: f64,
    /// (area_final − area_exact) / area_exact.
    pub area_rel_error: f64,
    /// (area_final − area_initial) / area_initial: the transport's own mass change.
    pub area_rel_change: f64,
    /// |{Φ_final > 0} Δ exact shape|.
    pub symdiff_area: f64,
    /// symdiff_area / area_exact.
    pub symdiff_rel: f64,
    /// The same for the initial Φ (the representation error of the grid).
    pub symdiff_initial_rel: f64,
    /// With `interface_transport = "clsvof"`: (Σ F_final − Σ F_initial) / Σ F_initial, the
    /// transported volume's own change (None with the level set alone).
    pub volume_rel_change: Option<f64>,
}

/// How a benchmark is run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaseOptions {
    /// Redistance every this many steps (`None`: never).
    pub redistance_every: Option<usize>,
    /// Transport Courant number δt · max(|u_c|/dx + |v_c|/dy).
    pub cfl: f64,
    /// WENO weights of the transport.
    pub weights: WenoWeights,
    /// Redistancing parameters.
    pub redistance: RedistanceSettings,
    /// The level set alone, or with the volume fraction of [`super::vof`] (Φ rebuilt from F
    /// after each step).
    pub interface: InterfaceTransport,
    /// The PLIC normals' source with [`InterfaceTransport::Clsvof`].
    pub plic_normal: PlicNormal,
}

impl CaseOptions {
    /// The defaults of the production code with the given frequency and Courant number.
    pub fn new(redistance_every: Option<usize>, cfl: f64) -> Self {
        CaseOptions {
            redistance_every,
            cfl,
            weights: WenoWeights::JiangShu,
            redistance: RedistanceSettings::default(),
            interface: InterfaceTransport::LevelSet,
            plic_normal: PlicNormal::default(),
        }
    }
}

fn check_run(n: usize, opts: &CaseOptions) -> Result<()> {
    if !(8..=8192).contains(&n) {
        return Err(Error::param("n", n, "an integer in [8, 8192]"));
    }
    if !(opts.cfl.is_finite() && opts.cfl > 0.0 && opts.cfl <= 1.4) {
        return Err(Error::param("cfl", opts.cfl, "a number in (0, 1.4]"));
    }
    if opts.redistance_every == Some(0) {
        return Err(Error::param("redistance_every", 0, "None or an integer >= 1"));
    }
    opts.redistance.validate()
}

/// Fills a face field from f(x, y) at its points.
fn fill_faces(f: &mut Field, grid: &Grid, vel: impl Fn(f64, f64) -> f64) {
    for j in 0..f.ny {
        for i in 0..f.nx {
            let (x, y) = grid.coord(f.loc, i as isize, j as isize);
            f.set(i, j, vel(x, y));
        }
    }
}

/// Runs a transport benchmark: shape, velocity shape (u, v at t-independent sample), time
/// modulation g(t) multiplying both components, period.
#[allow(clippy::too_many_arguments)]
fn run_case(
    grid: &Grid,
    shape: &Shape,
    area_exact: f64,
    u_of: impl Fn(f64, f64) -> f64,
    v_of: impl Fn(f64, f64) -> f64,
    modulation: impl Fn(f64) -> f64,
    period: f64,
    opts: &CaseOptions,
    exec: Exec,
) -> Result<LevelSetMetrics> {
    let mut phi = Field::zeros(grid, Location::Centre);
    init_signed_distance(shape, grid, &mut phi)?;
    let mut u0 = Field::zeros(grid, Location::XFace);
    let mut v0 = Field::zeros(grid, Location::YFace);
    fill_faces(&mut u0, grid, &u_of);
    fill_faces(&mut v0, grid, &v_of);
    let rate = max_transport_rate(&u0, &v0, grid, exec)?;
    let steps = ((period * rate / opts.cfl).ceil() as usize).max(1);
    let dt = period / steps as f64;

    let exact = |x: f64, y: f64| shape.contains(x, y);
    let area_initial = dense_area_refined(&phi, grid, AREA_SUB, exec);
    let symdiff_initial = symmetric_difference_area(&phi, grid, exact, SYMDIFF_SUB, exec);

    let mut transport = LevelSetTransport::with_weights(grid, opts.weights);
    let mut redistancer = Redistancer::new(grid, opts.redistance)?;
    let mut redistance_calls = 0;
    let mut vof = (opts.interface == InterfaceTransport::Clsvof).then(|| {
        let mut vof = VolumeFraction::new(grid, opts.plic_normal);
        vof.set_from_level_set(&mut phi, grid);
        vof
    });
    let volume_initial = vof.as_ref().map(|v| v.volume(grid, exec));
    // Stage velocities (tⁿ, tⁿ + δt, tⁿ + δt/2): the shapes scaled by g(t).
    let mut us = [u0.clone(), u0.clone(), u0.clone()];
    let mut vs = [v0.clone(), v0.clone(), v0.clone()];
    for n in 0..steps {
        let t = n as f64 * dt;
        for (s, ts) in [t, t + dt, t + 0.5 * dt].into_iter().enumerate() {
            let g = modulation(ts);
            us[s].slice_mut().iter_mut().zip(u0.slice()).for_each(|(a, b)| *a = g * b);
            vs[s].slice_mut().iter_mut().zip(v0.slice()).for_each(|(a, b)| *a = g * b);
        }
        // F with the mid-step velocity, the normals from Φⁿ; the split order alternates
        if let Some(vof) = vof.as_mut() {
            vof.transport(&mut phi, &us[2], &vs[2], grid, dt, n % 2 == 0, exec)?;
        }
        transport.advect_stages(&mut phi, [(&us[0], &vs[0]), (&us[1], &vs[1]), (&us[2], &vs[2])], grid, dt, exec)?;
        if let Some(k) = opts.redistance_every {
            if (n + 1) % k == 0 {
                redistancer.redistance(&mut phi, grid, exec)?;
                redistance_calls += 1;
            }
        }
        if let Some(vof) = vof.as_mut() {
            vof.rebuild_level_set(&mut phi, grid, exec);
        }
    }
    let volume_rel_change = match (vof.as_ref(), volume_initial) {
        (Some(v), Some(v0)) => Some((v.volume(grid, exec) - v0) / v0),
        _ => None,
    };
    let area_final = dense_area_refined(&phi, grid, AREA_SUB, exec);
    let symdiff_area = symmetric_difference_area(&phi, grid, exact, SYMDIFF_SUB, exec);
    Ok(LevelSetMetrics {
        n: grid.nx,
        steps,
        dt,
        final_time: period,
        redistance_calls,
        area_exact,
        area_initial,
        area_final,
        area_rel_error: (area_final - area_exact) / area_exact,
        area_rel_change: (area_final - area_initial) / area_initial,
        symdiff_area,
        symdiff_rel: symdiff_area / area_exact,
        symdiff_initial_rel: symdiff_initial / area_exact,
        volume_rel_change,
    })
}

/// Zalesak's slotted disk.
pub fn zalesak_shape() -> Shape {
    Shape::SlottedDisk { xc: 50.0, yc: 75.0, radius: 15.0, slot_width: 5.0, slot_top: 85.0 }
}

/// One revolution of Zalesak's slotted disk on an n × n grid of \[0,100\]²; redistancing every
/// `redistance_every` steps (None: never), transport Courant number `cfl`.
pub fn zalesak(n: usize, redistance_every: Option<usize>, cfl: f64, exec: Exec) -> Result<LevelSetMetrics> {
    zalesak_with(n, &CaseOptions::new(redistance_every, cfl), exec)
}

/// [`zalesak`] with all options.
pub fn zalesak_with(n: usize, opts: &CaseOptions, exec: Exec) -> Result<LevelSetMetrics> {
    check_run(n, opts)?;
    let grid = Grid::new(n, n, 100.0, 100.0)?;
    let shape = zalesak_shape();
    let area = shape.area().expect("closed form");
    let w = PI / 314.0;
    run_case(&grid, &shape, area, |_, y| w * (50.0 - y), |x, _| w * (x - 50.0), |_| 1.0, 628.0, opts, exec)
}

/// Rider–Kothe single vortex of period `period` (T) on an n × n grid of \[0,1\]², evaluated at
/// t = T against the initial circle.
pub fn single_vortex(n: usize, period: f64, redistance_every: Option<usize>, cfl: f64, exec: Exec) -> Result<LevelSetMetrics> {
    single_vortex_with(n, period, &CaseOptions::new(redistance_every, cfl), exec)
}

/// [`single_vortex`] with all options.
pub fn single_vortex_with(n: usize, period: f64, opts: &CaseOptions, exec: Exec) -> Result<LevelSetMetrics> {
    check_run(n, opts)?;
    check_positive("period", period)?;
    let grid = Grid::new(n, n, 1.0, 1.0)?;
    let shape = Shape::Circle { xc: 0.5, yc: 0.75, radius: 0.15 };
    let area = shape.area().expect("closed form");
    run_case(
        &grid,
        &shape,
        area,
        |x, y| -(PI * x).sin().powi(2) * (2.0 * PI * y).sin(),
        |x, y| (PI * y).sin().powi(2) * (2.0 * PI * x).sin(),
        |t| (PI * t / period).cos(),
        period,
        opts,
        exec,
    )
}
