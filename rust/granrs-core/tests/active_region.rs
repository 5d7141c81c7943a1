//! Active region of the two-phase model (`ModelConfig::active_region`, models/active_region.rs).
//!
//! 1. A window as large as the domain is the whole-domain step: the state transfer in and out
//!    of the window (built at the first step, rebuilt after a checkpoint restore) loses nothing,
//!    so the results are bit for bit those of the plain model.
//! 2. A granular column collapsing under air with Coulomb walls: the window grows with the
//!    front and shrinks as the column falls, the dense phase never comes within band/2 cells of
//!    its sides, and the dense area is conserved.
//! 3. Configurations a window cannot serve are refused with the parameter named.
//!    `advance`, which copies the window's state into the whole-domain fields once when it
//!    returns (and before a rebuild), leaves the state of as many calls of `step` bit for bit,
//!    through the window's growths and shrinks.
//! 4. A window with an open right side (outflow at the air's hydrostatic pressure) lets the air
//!    the front pushes leave, and follows the whole-domain step far more closely than a window
//!    of walls; so does a window whose top is open too (with backflow stabilisation).

use granrs_core::error::Error;
use granrs_core::grid::{BoundaryConditions, Grid, Side, VelocityBc};
use granrs_core::models::{ActiveRegion, ModelConfig, PressureGauge, TwoPhaseModel, WindowSides};

mod common;
use common::{column_config, released_column, AIR};

/// The column case in miniature (tests/common), with the mass correction.
fn column(nx: usize, ny: usize, active: Option<ActiveRegion>) -> TwoPhaseModel {
    let mut cfg = column_config(nx, ny);
    cfg.mass_correction = true;
    cfg.active_region = active;
    released_column(cfg)
}

#[test]
fn a_window_as_large_as_the_domain_is_the_whole_domain_step_bit_for_bit() {
    let (nx, ny) = (48, 16);
    let mut plain = column(nx, ny, None);
    let mut win = column(nx, ny, Some(ActiveRegion { band: 1000, align: 8, sides: WindowSides::Walls }));
    for k in 0..30 {
        let a = plain.step().unwrap();
        let b = win.step().unwrap();
        assert_eq!(a.dt.to_bits(), b.dt.to_bits(), "step {k}");
        assert_eq!(a.picard_iterations, b.picard_iterations, "step {k}");
        if k == 14 {
            // a restore drops the window; the next step rebuilds it from the restored state
            let state = win.checkpoint();
            win.restore(&state).unwrap();
            assert_eq!(win.active_window(), None);
        }
    }
    assert_eq!(win.active_window(), Some((nx, ny)));
    // interiors (the ghost layers are refilled by every stage that reads them)
    for (a, b, name) in [(&plain.u, &win.u, "u"), (&plain.v, &win.v, "v"), (&plain.p, &win.p, "p"), (&plain.phi, &win.phi, "phi")] {
        assert!(a.interior() == b.interior(), "{name}");
    }
    assert!(plain.plastic_tensor().unwrap().0.interior() == win.plastic_tensor().unwrap().0.interior());
    assert_eq!(plain.time.to_bits(), win.time.to_bits());
    assert_eq!(plain.step_count, win.step_count);
}

#[test]
fn the_window_follows_the_collapse_and_keeps_its_band() {
    let (nx, ny, band) = (128, 32, 4);
    let mut m = column(nx, ny, Some(ActiveRegion { band, align: 4, sides: WindowSides::Walls }));
    let area0 = m.dense_area();
    let mut sizes = Vec::new();
    for _ in 0..400 {
        m.step().unwrap();
        let (wx, wy) = m.active_window().unwrap();
        assert_eq!((wx % 4, wy % 4), (0, 0), "sizes are multiples of align");
        // the support of the dense phase (Φ > −3ε) is at least `band` cells inside the window's
        // right and top sides when a step starts; a step moves the interface by less than a
        // cell, and the redistancing can move the support's far edge by a few more
        let support = -3.0 * 1.5 * m.grid().h();
        let (mut imax, mut jmax) = (0usize, 0usize);
        for j in 0..ny {
            for i in 0..nx {
                if m.phi.at(i as isize, j as isize) > support {
                    imax = imax.max(i + 1);
                    jmax = jmax.max(j + 1);
                }
            }
        }
        assert!(wx == nx || imax + band / 2 <= wx, "front {imax} too close to the window's side {wx}");
        assert!(wy == ny || jmax + band / 2 <= wy, "top {jmax} too close to the window's lid {wy}");
        if sizes.last() != Some(&(wx, wy)) {
            sizes.push((wx, wy));
        }
        if m.time > 0.5 {
            break;
        }
    }
    // the column (7 × 14 cells at the start) spreads: the window grew along x and shrank along y
    let (first, last) = (sizes[0], *sizes.last().unwrap());
    assert!(last.0 > first.0 && last.1 < first.1, "window sizes {sizes:?}");
    assert!(last.0 < nx, "the window never needed the whole channel: {sizes:?}");
    // mass correction on the window: the dense area is the initial one (the secant method's
    // tolerance, 1e-10 relative, doc of `mass_correction`)
    assert!(((m.dense_area() - area0) / area0).abs() < 1e-8, "area {} vs {}", m.dense_area(), area0);
}

#[test]
fn advance_copies_the_window_back_once_and_leaves_the_state_of_as_many_steps() {
    let (nx, ny) = (128, 32);
    let ar = Some(ActiveRegion { band: 4, align: 4, sides: WindowSides::Walls });
    let (mut stepped, mut advanced) = (column(nx, ny, ar), column(nx, ny, ar));
    let mut windows = Vec::new();
    for _ in 0..120 {
        stepped.step().unwrap();
        if windows.last() != stepped.active_window().as_ref() {
            windows.push(stepped.active_window().unwrap());
        }
    }
    assert!(windows.len() >= 3, "the window must be rebuilt within the steps: {windows:?}");
    // 120 steps in calls of 50, 1 and 69: the copy happens at each return and each rebuild
    for n in [50, 1, 69] {
        let (log, err) = advanced.advance(None, Some(n));
        assert!(err.is_none() && log.len() == n as usize);
    }
    assert_eq!(advanced.active_window(), stepped.active_window());
    let pairs = [
        (&stepped.u, &advanced.u),
        (&stepped.v, &advanced.v),
        (&stepped.p, &advanced.p),
        (&stepped.phi, &advanced.phi),
        (&stepped.u_prev, &advanced.u_prev),
        (&stepped.v_prev, &advanced.v_prev),
    ];
    for (k, (a, b)) in pairs.into_iter().enumerate() {
        assert!(a.interior() == b.interior(), "field {k} differs");
    }
    assert!(stepped.plastic_tensor().unwrap().0.interior() == advanced.plastic_tensor().unwrap().0.interior());
    assert_eq!(stepped.time.to_bits(), advanced.time.to_bits());
    assert_eq!(stepped.step_count, advanced.step_count);
    // landing on a time: the last step is shortened to it
    let t = advanced.time + 0.01;
    let (_, err) = advanced.advance(Some(t), None);
    assert!(err.is_none());
    assert!((advanced.time - t).abs() <= 1e-12 * t, "time {} vs {t}", advanced.time);
}

#[test]
fn a_window_is_refused_where_it_cannot_stand_in_for_the_domain() {
    let grid = Grid::new(32, 16, 2.0, 1.0).unwrap();
    let ar = Some(ActiveRegion { band: 4, align: 4, sides: WindowSides::Walls });
    let named = |cfg: ModelConfig| match TwoPhaseModel::new(cfg) {
        Err(Error::InvalidParameter { name, .. }) => name,
        Err(e) => panic!("wrong error {e}"),
        Ok(_) => panic!("accepted"),
    };
    // single phase
    let mut cfg = ModelConfig::single_phase(grid.clone(), BoundaryConditions::uniform(VelocityBc::FreeSlip), AIR);
    cfg.active_region = ar;
    assert_eq!(named(cfg.clone()), "active_region");
    // an open right side
    cfg.light = Some(AIR);
    cfg.bc = cfg.bc.with(Side::Right, VelocityBc::Outflow);
    assert_eq!(named(cfg.clone()), "active_region");
    // the mean gauge
    cfg.bc = cfg.bc.with(Side::Right, VelocityBc::FreeSlip);
    cfg.pressure_gauge = PressureGauge::Mean;
    assert_eq!(named(cfg.clone()), "active_region");
    // a band below 2 cells
    cfg.pressure_gauge = PressureGauge::Top;
    cfg.active_region = Some(ActiveRegion { band: 1, align: 4, sides: WindowSides::Walls });
    assert_eq!(named(cfg.clone()), "active_region.band");
    cfg.active_region = Some(ActiveRegion { band: 4, align: 0, sides: WindowSides::Walls });
    assert_eq!(named(cfg.clone()), "active_region.align");
    // open sides on the granular-only model, which has no air to let through them
    cfg.free_surface = true;
    for sides in [WindowSides::OpenRight, WindowSides::OpenRightTop] {
        cfg.active_region = Some(ActiveRegion { band: 4, align: 4, sides });
        assert_eq!(named(cfg.clone()), "active_region_sides");
    }
}

/// One step from the same state of a collapsing column, on the whole domain and on a window of
/// `band` cells with the given `sides`: the largest differences from the whole-domain step of
/// the velocity over the window (relative to the largest speed) and of the pressure in the
/// dense phase (Pa), and the largest air speeds through the window's right and top sides. With
/// an open top the window must be lower than the domain (asserted).
fn one_step_on_a_window(band: usize, sides: WindowSides) -> (f64, f64, f64, f64) {
    let (nx, ny) = (128, 32);
    let fixed = |ar: Option<ActiveRegion>| {
        let mut cfg = column_config(nx, ny);
        cfg.time.fixed_dt = Some(2e-4);
        cfg.active_region = ar;
        released_column(cfg)
    };
    let mut whole = fixed(None);
    while whole.time < 0.25 {
        whole.step().unwrap();
    }
    let state = whole.checkpoint();
    let mut win = fixed(Some(ActiveRegion { band, align: 4, sides }));
    win.restore(&state).unwrap();
    whole.step().unwrap();
    win.step().unwrap();
    let (wx, wy) = win.active_window().unwrap();
    assert!(wx < nx, "the window is narrower than the channel");
    let (mut du, mut umax, mut dp): (f64, f64, f64) = (0.0, 0.0, 0.0);
    for j in 0..wy as isize {
        for i in 0..wx as isize {
            for (a, b) in [(&whole.u, &win.u), (&whole.v, &win.v)] {
                du = du.max((a.at(i, j) - b.at(i, j)).abs());
                umax = umax.max(a.at(i, j).abs());
            }
            if whole.phi.at(i, j) > 0.0 {
                dp = dp.max((whole.p.at(i, j) - win.p.at(i, j)).abs());
            }
        }
    }
    let through = (0..wy).map(|j| win.u.at(wx as isize, j as isize).abs()).fold(0.0, f64::max);
    let through_top = (0..wx).map(|i| win.v.at(i as isize, wy as isize).abs()).fold(0.0, f64::max);
    if sides.top_open() {
        assert!(wy < ny, "the window is as high as the domain: its top is not inside it");
    }
    (du / umax, dp, through, through_top)
}

#[test]
fn an_open_right_side_lets_the_air_out_and_follows_the_whole_domain() {
    // measured: velocity 5.1e-3 (walls) against 4.1e-6 (open) of the largest speed, pressure in
    // the grains 10.8 Pa against 0.016 Pa
    let band = 8;
    let (du_w, dp_w, through_w, _) = one_step_on_a_window(band, WindowSides::Walls);
    let (du_o, dp_o, through_o, _) = one_step_on_a_window(band, WindowSides::OpenRight);
    println!(
        "band {band}: velocity difference {du_w:.2e} (walls) / {du_o:.2e} (open) of the largest speed; pressure in the grains {dp_w:.3} / {dp_o:.3} Pa; air through the side {through_w:.1e} / {through_o:.3} m/s"
    );
    // a wall is a wall; the open side passes the air the front pushes
    assert!(through_w == 0.0, "flow through a wall: {through_w}");
    assert!(through_o > 1e-3, "no air left the open window: {through_o} m/s");
    // the open window is the whole-domain step to far better than the walls: at least 100×
    // closer in velocity and in the grains' pressure, and within 1e-4 of the basal pressure
    // ρ_s g H = 2.8 kPa of the 0.2 m column (the yield stress's scale)
    assert!(du_o * 100.0 < du_w, "velocity: open {du_o:.2e}, walls {du_w:.2e}");
    assert!(dp_o * 100.0 < dp_w, "pressure: open {dp_o:.3} Pa, walls {dp_w:.3} Pa");
    assert!(dp_o < 1e-4 * 1450.0 * 9.81 * 0.2, "pressure in the grains off by {dp_o} Pa");
}

#[test]
fn an_open_top_with_backflow_stabilisation_follows_the_whole_domain() {
    // the window's right and top sides open, the top with backflow stabilisation (air enters
    // through it above the collapsing column). Measured: velocity 1.8e-5 of the largest speed
    // (walls 2.4e-2), pressure in the grains 0.024 Pa (walls 74 Pa), air through the top
    // 0.057 m/s.
    // Band 4: the window (support + 2 bands, rows rounded to 4) is then 28 of the 32 rows, so
    // its top lies inside the domain
    let band = 4;
    let (du_w, dp_w, _, top_w) = one_step_on_a_window(band, WindowSides::Walls);
    let (du_o, dp_o, _, top_o) = one_step_on_a_window(band, WindowSides::OpenRightTop);
    println!("band {band}, open right and top: velocity difference {du_o:.2e} (walls {du_w:.2e}); pressure in the grains {dp_o:.3} Pa (walls {dp_w:.3}); air through the top {top_o:.3} m/s (walls {top_w:.1e})");
    assert!(top_w == 0.0, "flow through a wall: {top_w}");
    assert!(top_o > 1e-3, "no air crossed the open top: {top_o} m/s");
    assert!(du_o * 100.0 < du_w, "velocity: open {du_o:.2e}, walls {du_w:.2e}");
    assert!(dp_o * 100.0 < dp_w, "pressure: open {dp_o:.3} Pa, walls {dp_w:.3} Pa");
    assert!(dp_o < 1e-4 * 1450.0 * 9.81 * 0.2, "pressure in the grains off by {dp_o} Pa");
}

#[test]
fn a_checkpoint_keeps_the_window_size_and_checks_it() {
    let ar = Some(ActiveRegion { band: 2, align: 4, sides: WindowSides::OpenRightTop });
    let mut m = column(64, 16, ar);
    let fresh = m.checkpoint();
    let entry = |s: &[(String, Vec<f64>)]| s.iter().find(|(n, _)| n == "active_window").map(|(_, d)| d.clone());
    assert_eq!(entry(&fresh), Some(vec![0.0, 0.0]), "no window before the first step");
    for _ in 0..10 {
        m.step().unwrap();
    }
    let (wx, wy) = m.active_window().unwrap();
    let state = m.checkpoint();
    assert_eq!(entry(&state), Some(vec![wx as f64, wy as f64]));
    // restored: the next step runs on the window of the checkpoint
    let mut r = column(64, 16, ar);
    r.restore(&state).unwrap();
    r.step().unwrap();
    m.step().unwrap();
    assert_eq!(r.active_window(), m.active_window());
    // a checkpoint without the entry is accepted (the window is rebuilt from the dense phase)
    let without: Vec<_> = state.iter().filter(|(n, _)| n != "active_window").cloned().collect();
    column(64, 16, ar).restore(&without).unwrap();
    // sizes that are not whole numbers of cells within the grid are refused, naming the entry
    for bad in [[3.5, 8.0], [1.0, 8.0], [128.0, 8.0], [8.0, 17.0]] {
        let mut s = state.clone();
        s.iter_mut().find(|(n, _)| n == "active_window").unwrap().1 = bad.to_vec();
        match column(64, 16, ar).restore(&s) {
            Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "active_window", "{bad:?}"),
            other => panic!("{bad:?}: {other:?}"),
        }
    }
}
