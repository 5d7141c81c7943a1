//! Navier–Stokes core: analytic solutions and identities.

use granrs_core::grid::{BoundaryConditions, Field, Grid, Location, Side, VelocityBc};
use granrs_core::models::{Material, ModelConfig, TwoPhaseModel};
use std::f64::consts::PI;

/// Taylor–Green vortex in the unit square with free-slip walls (exact: the walls are symmetry
/// lines of the periodic vortex): u = sin πx cos πy e^{−2π²νt}, v = −cos πx sin πy e^{−2π²νt},
/// p = ρ/4 (cos 2πx + cos 2πy) e^{−4π²νt}. Returns the relative L2 error of (u, v) at t_end.
fn taylor_green_error(n: usize, threads: usize) -> f64 {
    let nu = 0.01;
    let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
    let mut cfg = ModelConfig::single_phase(grid.clone(), BoundaryConditions::uniform(VelocityBc::FreeSlip), Material { density: 1.0, viscosity: nu });
    let h = 1.0 / n as f64;
    cfg.time.fixed_dt = Some(0.25 * h);
    cfg.threads = threads;
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    m.u = Field::from_fn(&grid, Location::XFace, |x, y| (PI * x).sin() * (PI * y).cos());
    m.v = Field::from_fn(&grid, Location::YFace, |x, y| -(PI * x).cos() * (PI * y).sin());
    m.p = Field::from_fn(&grid, Location::Centre, |x, y| 0.25 * ((2.0 * PI * x).cos() + (2.0 * PI * y).cos()));
    m.fields_changed();
    let t_end = 0.5;
    let steps = (t_end / (0.25 * h)).round() as usize;
    for _ in 0..steps {
        m.step().unwrap();
    }
    let decay = (-2.0 * PI * PI * nu * m.time).exp();
    let (mut e2, mut n2) = (0.0, 0.0);
    for j in 0..n {
        for i in 0..=n {
            let (x, y) = grid.coord(Location::XFace, i as isize, j as isize);
            let ex = (PI * x).sin() * (PI * y).cos() * decay;
            e2 += (m.u.at(i as isize, j as isize) - ex).powi(2);
            n2 += ex * ex;
        }
    }
    for j in 0..=n {
        for i in 0..n {
            let (x, y) = grid.coord(Location::YFace, i as isize, j as isize);
            let ex = -(PI * x).cos() * (PI * y).sin() * decay;
            e2 += (m.v.at(i as isize, j as isize) - ex).powi(2);
            n2 += ex * ex;
        }
    }
    (e2 / n2).sqrt()
}

#[test]
fn taylor_green_second_order() {
    let e: Vec<f64> = [32, 64, 128].iter().map(|&n| taylor_green_error(n, 1)).collect();
    let o1 = (e[0] / e[1]).log2();
    let o2 = (e[1] / e[2]).log2();
    println!("Taylor-Green L2 errors {e:?}, orders {o1:.3} {o2:.3}");
    // second-order space and time (δt ∝ h): order 2 expected; 1.9 leaves room for the
    // first-order start-up step.
    assert!(o1 >= 1.9 && o2 >= 1.9, "orders {o1} {o2}");
}

#[test]
fn hydrostatic_two_density_layer_stays_at_rest() {
    // fluid of density 1450 under one of density 1, interface at mid-cell (y = 0.5 + h/2)
    let n = 32;
    let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
    let mut cfg = ModelConfig::single_phase(grid.clone(), BoundaryConditions::uniform(VelocityBc::NoSlip), Material { density: 1450.0, viscosity: 0.1 });
    cfg.light = Some(Material { density: 1.0, viscosity: 2e-5 });
    cfg.gravity = [0.0, -9.81];
    cfg.transport_interface = false;
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    let h = 1.0 / n as f64;
    m.phi = Field::from_fn(&grid, Location::Centre, |_, y| 0.5 + 0.5 * h - y);
    m.fields_changed();
    m.initialise_pressure().unwrap();
    let mut worst: f64 = 0.0;
    for _ in 0..1000 {
        let info = m.step().unwrap();
        worst = worst.max(info.max_speed);
    }
    println!("hydrostatic: max speed over 1000 steps {worst:.3e}, final {:.3e}, t = {}", m.last.max_speed, m.time);
    // round-off level: |g| δt ε_machine ρ-ratio ≈ 1e-12; 1e-8 is the required bound
    assert!(worst < 1e-8, "max speed {worst}");
}

/// Air at rest under gravity in a box whose right side is open (outflow) at the air's own
/// hydrostatic pressure, p_b(y) = ρ g (L_y − y) (`BoundaryConditions::with_outlet_pressure`,
/// the open side of an active window): the linear pressure's discrete gradient balances ρg to
/// round-off on every face, the boundary face included, so nothing moves. With the default
/// p_b = 0 the same box drains through the open side (the ghost pressure jumps by 2ρg(L_y − y)).
fn air_at_rest_beside_an_open_side(outlet: bool) -> f64 {
    let (n, rho, g) = (16, 1.2, 9.81);
    let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
    let h = 1.0 / n as f64;
    let mut bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Right, VelocityBc::Outflow);
    if outlet {
        // k-th cell centre along the side at y = (k + ½) h
        bc = bc.with_outlet_pressure(Side::Right, rho * g * (1.0 - 0.5 * h), -rho * g * h);
    }
    let mut cfg = ModelConfig::single_phase(grid.clone(), bc, Material { density: rho, viscosity: 1.8e-5 });
    cfg.gravity = [0.0, -g];
    cfg.time.fixed_dt = Some(1e-3);
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    m.p = Field::from_fn(&grid, Location::Centre, |_, y| rho * g * (1.0 - y));
    m.fields_changed();
    let mut worst: f64 = 0.0;
    for _ in 0..50 {
        worst = worst.max(m.step().unwrap().max_speed);
    }
    worst
}

#[test]
fn an_open_side_at_the_hydrostatic_pressure_keeps_the_air_at_rest() {
    let at_rest = air_at_rest_beside_an_open_side(true);
    let drained = air_at_rest_beside_an_open_side(false);
    println!("open side: max speed {at_rest:.3e} with the hydrostatic outlet pressure, {drained:.3e} with p_b = 0");
    // round-off: g δt ε ≈ 1e-18 per step over 50 steps (measured 6e-16); the p_b = 0 box is
    // pushed by a pressure jump of up to 2ρgL_y = 24 Pa at the side and falls out of it at
    // speeds of order g t = 0.5 m/s (measured 0.98 m/s after 50 steps)
    assert!(at_rest < 1e-10, "max speed {at_rest}");
    assert!(drained > 1e-3, "max speed {drained}");
    // a boundary pressure that is not finite is refused, naming the side
    let bad = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Right, VelocityBc::Outflow).with_outlet_pressure(Side::Right, f64::NAN, 0.0);
    match bad.validate(1.0, 1.0) {
        Err(granrs_core::Error::InvalidParameter { name, .. }) => assert_eq!(name, "bc.right.outlet_pressure"),
        other => panic!("accepted or wrong error: {other:?}"),
    }
}

/// Plug flow through a vertical channel (free-slip sides, no gravity) whose bottom takes the
/// fluid out (`in_at_top`: prescribed normal velocity −V) or puts it in (+V), and whose top is
/// open at p_b = 0, with or without backflow stabilisation. Returns the mean and the spread of
/// the interior pressure after 20 steps. Exact (Bernoulli from the ambient fluid at rest at
/// p_b): where fluid enters through the stabilised top its static pressure is p_b − ½ρV², so
/// the whole uniform stream sits at −½ρV²; without stabilisation, or where fluid leaves, at p_b.
fn plug_flow_pressure(in_at_top: bool, backflow: bool) -> (f64, f64) {
    let (rho, speed) = (1.2, 0.7);
    let grid = Grid::new(8, 32, 0.25, 1.0).unwrap();
    let normal = if in_at_top { -speed } else { speed };
    let mut bc = BoundaryConditions::uniform(VelocityBc::FreeSlip)
        .with(Side::Bottom, VelocityBc::Velocity { normal, tangential: 0.0 })
        .with(Side::Top, VelocityBc::Outflow);
    if backflow {
        bc = bc.with_backflow_stabilisation(Side::Top);
    }
    let mut cfg = ModelConfig::single_phase(grid.clone(), bc, Material { density: rho, viscosity: 1.8e-5 });
    cfg.time.fixed_dt = Some(1e-3);
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    m.v = Field::from_fn(&grid, Location::YFace, |_, _| normal);
    m.fields_changed();
    for _ in 0..20 {
        m.step().unwrap();
    }
    let p: Vec<f64> = m.p.interior().iter().copied().collect();
    let mean = p.iter().sum::<f64>() / p.len() as f64;
    let spread = p.iter().map(|x| (x - mean).abs()).fold(0.0, f64::max);
    (mean, spread)
}

#[test]
fn backflow_stabilisation_gives_entering_fluid_the_bernoulli_pressure() {
    let q = 0.5 * 1.2 * 0.7 * 0.7; // ½ρV² = 0.294 Pa
    let (entering, spread_e) = plug_flow_pressure(true, true);
    let (plain, spread_p) = plug_flow_pressure(true, false);
    let (leaving, spread_l) = plug_flow_pressure(false, true);
    println!("interior pressure: entering {entering:.6} (±{spread_e:.1e}), plain {plain:.2e} (±{spread_p:.1e}), leaving {leaving:.2e} (±{spread_l:.1e}); −½ρV² = {:.6}", -q);
    // a uniform stream has no convection or viscous force: the only pressure is the boundary's,
    // exact up to the pressure solve's stopping tolerance (measured: 6e-11 relative in the
    // mean, 5e-9 in the spread; the solve stops at a relative residual of 1e-8)
    assert!((entering + q).abs() < 1e-6 * q && spread_e < 1e-6 * q, "entering: {entering} ± {spread_e}, expected {}", -q);
    assert!(plain.abs() < 1e-10 * q, "plain outflow side: {plain}");
    assert!(leaving.abs() < 1e-10 * q, "fluid leaving a stabilised side: {leaving}");
}

/// Stokes lid-driven cavity (unit box, lid speed 1, η = ρ = 1, no convection) with the
/// standard or the rotational pressure update (projection/mod.rs).
fn stokes_cavity(dt: f64, rotational: bool) -> TwoPhaseModel {
    let grid = Grid::new(32, 32, 1.0, 1.0).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(granrs_core::grid::Side::Top, VelocityBc::Velocity { normal: 0.0, tangential: 1.0 });
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1.0, viscosity: 1.0 });
    cfg.convection = false;
    cfg.time.fixed_dt = Some(dt);
    cfg.time.cfl_abort = 100.0;
    cfg.rotational_pressure = rotational;
    TwoPhaseModel::new(cfg).unwrap()
}

/// Steps `n` times; returns max |Δu| of the last step.
fn last_change(m: &mut TwoPhaseModel, n: usize) -> f64 {
    let mut d = 0.0;
    for _ in 0..n {
        let before = m.u.clone();
        m.step().unwrap();
        d = m.u.slice().iter().zip(before.slice()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    }
    d
}

#[test]
fn rotational_pressure_update_reaches_the_stokes_steady_state() {
    // ηδt/(a₀ρh²) = 34 at δt = 0.05, h = 1/32: the standard update damps the grid-scale pressure
    // modes of the lid corners by ~ηk²/(a₀ρ/δt + ηk²) ≈ 0.997 per step (projection/mod.rs), so
    // after 100 steps the velocity still moves by 1.7e-4 per step (measured); the rotational
    // update is at round-off (measured 4e-12 per step).
    let mut rot = stokes_cavity(0.05, true);
    let mut std = stokes_cavity(0.05, false);
    let (d_rot, d_std) = (last_change(&mut rot, 100), last_change(&mut std, 100));
    println!("max |Δu| of step 100: rotational {d_rot:.2e}, standard {d_std:.2e}");
    assert!(d_rot < 1e-10, "rotational form not steady: {d_rot:e}");
    assert!(d_std > 1e-5, "the standard form's slow mode is gone ({d_std:e}): revisit this test");
    // the same steady state: the standard form at δt = 0.01 (ηδt/(a₀ρh²) = 7) after 400 steps,
    // whose last unit of time changed u by 2.6e-5 and decays by ~4x per unit (measured), so it
    // is within ~1e-5 of its steady state
    let mut fine = stokes_cavity(0.01, false);
    last_change(&mut fine, 400);
    let diff = rot.u.slice().iter().zip(fine.u.slice()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    println!("rotational (δt = 0.05) vs standard (δt = 0.01) steady u: {diff:.2e}");
    assert!(diff < 1e-4, "steady states differ by {diff:e}");
}

/// The energy budget (diagnostics/energy.rs) of the Stokes Taylor–Green vortex above (convection
/// off, so the spatial operators conserve exactly what they should: the MAC viscous operator's
/// dissipation is the discrete Σ 2ν D:D by summation by parts): the kinetic energy falls by the
/// viscous work, up to the time integration, whose share (the residual) falls at second order in
/// δt (BDF2, trapezoidal rates); the decay itself matches the exact e^{−4π²νt} to O(h²).
/// Serial and parallel budgets agree bit for bit.
fn stokes_taylor_green_budget(n: usize, dt: f64, threads: usize) -> granrs_core::diagnostics::EnergyBudget {
    let nu = 0.01;
    let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
    let mut cfg = ModelConfig::single_phase(grid.clone(), BoundaryConditions::uniform(VelocityBc::FreeSlip), Material { density: 1.0, viscosity: nu });
    cfg.time.fixed_dt = Some(dt);
    cfg.convection = false;
    cfg.time.cfl_abort = 100.0; // no convection: the CFL number limits nothing
    cfg.threads = threads;
    cfg.pressure_solver.rtol = 1e-12;
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    m.u = Field::from_fn(&grid, Location::XFace, |x, y| (PI * x).sin() * (PI * y).cos());
    m.v = Field::from_fn(&grid, Location::YFace, |x, y| -(PI * x).cos() * (PI * y).sin());
    m.fields_changed();
    while m.time < 1.0 - 1e-9 {
        m.step().unwrap();
    }
    m.energy_budget()
}

#[test]
fn energy_budget_of_the_stokes_taylor_green_vortex() {
    let n = 64;
    let (a, b) = (stokes_taylor_green_budget(n, 0.02, 1), stokes_taylor_green_budget(n, 0.01, 1));
    println!("{a:?}\n{b:?}");
    // E_k(0) = ½ ρ ∫ (sin²πx cos²πy + cos²πx sin²πy) = ¼ on the unit square
    assert!((b.kinetic_initial / 0.25 - 1.0).abs() < 1e-3, "{}", b.kinetic_initial);
    let exact = 0.25 * (-4.0 * PI * PI * 0.01 * 1.0f64).exp();
    assert!((b.kinetic / exact - 1.0).abs() < 2e-3, "E_k {} exact {exact}", b.kinetic);
    let loss = b.kinetic_initial - b.kinetic;
    // measured 1.8e-5 of the loss at δt = 0.01
    assert!(b.residual.abs() < 1e-4 * loss, "residual {} of the loss {loss}", b.residual);
    let ratio = a.residual / b.residual;
    println!("residual ratio δt = 0.02 / 0.01: {ratio:.2}");
    assert!(ratio > 3.0 && ratio < 5.0, "second order in δt: ratio {ratio}");
    let c = stokes_taylor_green_budget(n, 0.01, 2);
    assert_eq!(b.residual.to_bits(), c.residual.to_bits());
    assert_eq!(b.viscous_work.to_bits(), c.viscous_work.to_bits());
}
