//! The granular-only model (`ModelConfig::free_surface`, projection/free_surface.rs): the light
//! phase is not resolved, the dense phase has a free surface at p = 0.
//!
//! 1. A layer at rest with its surface inside a cell: the ghost-fluid Dirichlet condition is
//!    exact for a linear pressure, so the initial pressure is the lithostatic ρ g (H − y) to the
//!    solver's tolerance (relative 1e-8), and the layer stays at rest (max speed < 1e-8, the
//!    bound of the two-phase heavy layer at rest).
//! 2. A collapsing D-P column: each granular cell is divergence-free after the projection, the
//!    velocity is extended EXTENSION_LAYERS faces into the air and is zero beyond, p = 0 in the
//!    air, and the column spreads; without mass correction its area drifts by less than 1 %.
//! 3. One thread and two give bit-identical states; an active window as large as the domain is
//!    the whole-domain step bit for bit (the pressure increment travels with the window).
//! 4. A single-phase configuration is refused, naming `free_surface`.

use granrs_core::error::Error;
use granrs_core::grid::{BoundaryConditions, Field, Grid, Location, VelocityBc};
use granrs_core::models::{ActiveRegion, ModelConfig, TwoPhaseModel, WindowSides};
use granrs_core::projection::free_surface::EXTENSION_LAYERS;

mod common;
use common::{column_config, released_column, AIR, BEADS};

/// The column case in miniature (tests/common) with the air not resolved (or resolved, for
/// comparison).
fn column(nx: usize, ny: usize, threads: usize, active: Option<ActiveRegion>) -> TwoPhaseModel {
    column_with(nx, ny, threads, active, true)
}

fn column_with(nx: usize, ny: usize, threads: usize, active: Option<ActiveRegion>, free_surface: bool) -> TwoPhaseModel {
    let mut cfg = column_config(nx, ny);
    cfg.free_surface = free_surface;
    cfg.threads = threads;
    cfg.active_region = active;
    released_column(cfg)
}

#[test]
fn a_layer_at_rest_has_the_lithostatic_pressure_and_stays_at_rest() {
    let n = 32;
    let h = 1.0 / n as f64;
    let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
    let mut cfg = ModelConfig::single_phase(grid.clone(), BoundaryConditions::uniform(VelocityBc::NoSlip), BEADS);
    cfg.light = Some(AIR);
    cfg.free_surface = true;
    cfg.gravity = [0.0, -9.81];
    cfg.time.fixed_dt = Some(1e-3);
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    // surface at 0.37 of a cell above the centre of row 15
    let top = 0.5 - 0.5 * h + 0.37 * h;
    m.phi = Field::from_fn(&grid, Location::Centre, |_, y| top - y);
    m.fields_changed();
    m.initialise_pressure().unwrap();
    let scale = BEADS.density * 9.81 * top;
    let mut worst_p: f64 = 0.0;
    for j in 0..n {
        let y = grid.yc(j as isize);
        for i in 0..n {
            let exact = if y < top { BEADS.density * 9.81 * (top - y) } else { 0.0 };
            worst_p = worst_p.max((m.p.at(i as isize, j as isize) - exact).abs() / scale);
        }
    }
    println!("free surface at rest: max |p - rho g (H - y)| / (rho g H) = {worst_p:.2e}");
    assert!(worst_p < 1e-8, "lithostatic pressure off by {worst_p:e} of rho g H");
    let mut worst: f64 = 0.0;
    for _ in 0..500 {
        worst = worst.max(m.step().unwrap().max_speed);
    }
    println!("free surface at rest: max speed over 500 steps {worst:.3e}");
    assert!(worst < 1e-8, "max speed {worst}");
}

#[test]
fn the_column_spreads_divergence_free_with_its_velocity_extended_into_the_air() {
    let (nx, ny) = (48, 16);
    let mut m = column(nx, ny, 1, None);
    let mut div_rel: f64 = 0.0;
    for _ in 0..40 {
        let info = m.step().unwrap();
        // |div u| over the granular cells against the velocity scale over a cell
        div_rel = div_rel.max(info.divergence * m.grid().h() / info.max_speed);
    }
    println!("free-surface column: t = {:.4} s, max |div u| h / max|u| = {div_rel:.2e}", m.time);
    // the solver's relative tolerance is 1e-8; the divergence left is of that order
    assert!(div_rel < 1e-6, "divergence {div_rel:e}");
    let (phi, u) = (&m.phi, &m.u);
    // front moved past the initial width (0.1 m = 10.7 cells)
    let front = (0..nx).rev().find(|&i| phi.at(i as isize, 0) > 0.0).unwrap();
    assert!(front as f64 + 1.0 > 0.1 / m.grid().dx + 1.0, "front at cell {front}");
    // p = 0 in the air; u on air faces: extended within EXTENSION_LAYERS, 0 beyond
    let mut extended = 0usize;
    for j in 0..ny as isize {
        for i in 0..nx as isize {
            if phi.at(i, j) <= 0.0 {
                assert_eq!(m.p.at(i, j), 0.0, "p in the air at ({i}, {j})");
            }
        }
        for i in 1..nx as isize {
            let granular_beside = phi.at(i - 1, j) > 0.0 || phi.at(i, j) > 0.0;
            if granular_beside {
                continue;
            }
            // distance in faces to the nearest face beside a granular cell (rows and columns)
            let near = (0..nx as isize + 1).any(|ii| {
                (0..ny as isize).any(|jj| {
                    let beside = (ii > 0 && phi.at(ii - 1, jj) > 0.0) || (ii < nx as isize && phi.at(ii, jj) > 0.0);
                    beside && ((ii - i).abs() + (jj - j).abs()) as usize <= EXTENSION_LAYERS
                })
            });
            if !near {
                assert_eq!(u.at(i, j), 0.0, "u beyond the extension band at face ({i}, {j})");
            } else if u.at(i, j) != 0.0 {
                extended += 1;
            }
        }
    }
    assert!(extended > 20, "only {extended} air faces carry an extended velocity");
}

/// Relative change of the dense area without mass correction after `t_end` seconds.
fn area_change(nx: usize, ny: usize, free_surface: bool, t_end: f64) -> f64 {
    let mut m = column_with(nx, ny, 1, None, free_surface);
    let a0 = m.dense_area();
    while m.time < t_end {
        m.step().unwrap();
    }
    (m.dense_area() - a0) / a0
}

#[test]
fn the_area_drift_without_mass_correction_stays_within_one_percent() {
    // The extension is not divergence-free in the air, so the level set's area drifts, as the
    // two-phase model's does (the column case runs with the mass correction). Without it, the
    // drift to t = 0.15 s stays within the 1 % required of the corrected runs, on
    // each grid (measured 0.34 / 0.41 / 0.26 %; the two-phase model 0.62 / 1.05 / -0.85 %).
    let t = 0.15;
    let e: Vec<f64> = [(48, 16), (96, 32), (192, 64)].iter().map(|&(nx, ny)| area_change(nx, ny, true, t)).collect();
    let tp: Vec<f64> = [(48, 16), (96, 32), (192, 64)].iter().map(|&(nx, ny)| area_change(nx, ny, false, t)).collect();
    println!("area change to t = {t} s, ny = 16/32/64: free surface {e:?}, two-phase {tp:?}");
    assert!(e.iter().all(|x| x.abs() < 0.01), "{e:?}");
}

#[test]
fn one_thread_and_two_and_a_full_window_agree_bit_for_bit() {
    // 128 × 32 cells: at least `PARALLEL_MIN_CELLS` (4096) cells and faces, so that every
    // row-parallel loop (the velocity extension's layers included) takes its parallel path
    let (nx, ny) = (128, 32);
    let mut a = column(nx, ny, 1, None);
    let mut b = column(nx, ny, 2, None);
    let mut c = column(nx, ny, 1, Some(ActiveRegion { band: 1000, align: 8, sides: WindowSides::Walls }));
    for k in 0..30 {
        let (ia, ib, ic) = (a.step().unwrap(), b.step().unwrap(), c.step().unwrap());
        assert_eq!(ia.dt.to_bits(), ib.dt.to_bits(), "step {k}");
        assert_eq!(ia.dt.to_bits(), ic.dt.to_bits(), "step {k}");
        assert_eq!(ia.picard_iterations, ib.picard_iterations, "step {k}");
        if k == 14 {
            // a restore drops the window; it is rebuilt (increment included) at the next step
            let state = c.checkpoint();
            c.restore(&state).unwrap();
        }
    }
    for (x, y, z, name) in [(&a.u, &b.u, &c.u, "u"), (&a.v, &b.v, &c.v, "v"), (&a.p, &b.p, &c.p, "p"), (&a.phi, &b.phi, &c.phi, "phi")] {
        assert!(x.interior() == y.interior(), "{name}: 1 thread != 2 threads");
        assert!(x.interior() == z.interior(), "{name}: whole domain != full window");
    }
}

#[test]
fn a_single_phase_free_surface_is_refused() {
    let grid = Grid::new(8, 8, 1.0, 1.0).unwrap();
    let mut cfg = ModelConfig::single_phase(grid, BoundaryConditions::uniform(VelocityBc::NoSlip), BEADS);
    cfg.free_surface = true;
    match TwoPhaseModel::new(cfg) {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "free_surface"),
        Err(e) => panic!("wrong error {e}"),
        Ok(_) => panic!("accepted"),
    }
}
