//! Depth-averaged (Savage–Hutter) model: dam breaks against analytic solutions, conservation,
//! friction stopping a layer, well-balancing, errors.
//!
//! - Ritter (1892): frictionless dam break on a dry horizontal bed, h = (2c₀ − ξ)²/(9g),
//!   u = ⅔(ξ + c₀) for −c₀ ≤ ξ = (x − x₀)/t ≤ 2c₀ (c₀ = √(g h₀)); front at x₀ + 2c₀t.
//! - Mangeney, Heinrich & Roche (2000, Pure Appl. Geophys. 157, 1081–1096): the same with Coulomb
//!   friction tan δ on a horizontal bed: front x_f = x₀ + 2c₀t − ½ g tan δ t² (while it moves).
//!   Near the tip both solutions are h = (x_f − x)²/(9 g t²), so the point where h first falls to
//!   a threshold ε lies 3t√(gε) behind x_f: the tests compare the numerical threshold crossing
//!   with that analytic position.
//! - The depth-integrated pore pressure: the relaxation of m = ∫p_f dz/(ρ g) to ½ β_s h² at the
//!   rate 2κ/h² (exact for a layer at rest), and m/h carried with the flow, so that β = 2m/h²
//!   rises as a layer thins (the two-phase model's eq. (7d) integrated over the depth).

use granrs_core::models::depth_averaged::{active_earth_pressure, lateral_pressure};
use granrs_core::models::{DepthAveragedConfig, DepthAveragedModel, DepthAveragedPore, EarthPressure, PoreTransport};
use granrs_core::Error;

const G: f64 = 1.0;

/// Dam of depth h0 = 1 on [0, x0), dry beyond, channel [0, len], n cells, friction angle δ (deg).
fn dam(n: usize, len: f64, x0: f64, delta: f64) -> DepthAveragedModel {
    let mut cfg = DepthAveragedConfig::new(n, len);
    cfg.gravity = G;
    cfg.basal_friction_angle = delta;
    cfg.dry_depth = 1e-10;
    let mut m = DepthAveragedModel::new(cfg).unwrap();
    let h: Vec<f64> = (0..n).map(|i| if m.x(i) < x0 { 1.0 } else { 0.0 }).collect();
    m.set_state(&h, &vec![0.0; n], &vec![0.0; n]).unwrap();
    m
}

/// Ritter depth at x, t (h0 = 1, c0 = √g).
fn ritter(x: f64, t: f64, x0: f64) -> f64 {
    let c0 = G.sqrt();
    let xi = (x - x0) / t;
    if xi <= -c0 {
        1.0
    } else if xi >= 2.0 * c0 {
        0.0
    } else {
        (2.0 * c0 - xi).powi(2) / (9.0 * G)
    }
}

/// L1 error of the cell averages of h against Ritter (4-point Gauss average of the exact h).
fn ritter_l1(m: &DepthAveragedModel, x0: f64) -> f64 {
    let (gx, gw) = (
        [-0.861_136_311_594_053, -0.339_981_043_584_856, 0.339_981_043_584_856, 0.861_136_311_594_053],
        [0.347_854_845_137_454, 0.652_145_154_862_546, 0.652_145_154_862_546, 0.347_854_845_137_454],
    );
    let dx = m.dx();
    m.depth()
        .iter()
        .enumerate()
        .map(|(i, &h)| {
            let exact: f64 = (0..4).map(|k| 0.5 * gw[k] * ritter(m.x(i) + 0.5 * dx * gx[k], m.time, x0)).sum();
            (h - exact).abs() * dx
        })
        .sum()
}

#[test]
fn ritter_dam_break_profile_front_and_convergence_order() {
    // channel [0, 2], dam at x0 = 1, t = 0.4: the rarefaction's tail (x0 − c0 t = 0.6) never
    // reaches the wall and the front (x0 + 2 c0 t = 1.8) never reaches the far end
    let (x0, t) = (1.0, 0.4);
    let eps = 1e-2; // front read where h first falls to 1 % of h0
    let exact_front = x0 + 2.0 * G.sqrt() * t - 3.0 * t * (G * eps).sqrt(); // 1.68
    let (mut errors, mut lags) = (Vec::new(), Vec::new());
    for n in [200, 400, 800, 1600] {
        let mut m = dam(n, 2.0, x0, 0.0);
        m.advance(t, u64::MAX).unwrap();
        assert!((m.time - t).abs() < 1e-12);
        errors.push(ritter_l1(&m, x0));
        lags.push(exact_front - m.front(eps));
        println!(
            "n = {n}: L1(h) = {:.3e}, front lag at 1 % of h0 = {:.2e} ({:.2} cells)",
            errors.last().unwrap(),
            lags.last().unwrap(),
            lags.last().unwrap() / m.dx()
        );
    }
    let orders: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    let lag_orders: Vec<f64> = lags.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    println!("observed orders: L1(h) {orders:?}, front {lag_orders:?}");
    // Ritter's h has kinks at the rarefaction's tail and at the dry front (h ~ (x_f − x)² with
    // u finite there), where minmod-MUSCL is first order: the L1 order is 1, not 2 (measured
    // 1.00, 1.00, 1.00); the bound asks for ≥ 0.9.
    for p in &orders {
        assert!(*p > 0.9, "observed L1 order {p}");
    }
    // the numerical tip is thin and slow (u drops in the last wet cells): the 1 % front lags by
    // about 3 cells at n ≥ 800 and converges at first order (measured 1.25, 0.97, 1.00)
    assert!(lags[2] > 0.0 && lags[2] < 4.0 * 2.0 / 800.0 && lags[3] < 4.0 * 2.0 / 1600.0, "front lags {lags:?}");
    assert!(lag_orders[2] > 0.8, "front order {lag_orders:?}");
    // and the front approaches 2 c0 t: at n = 1600 the crossing of 1 % of h0 is within 0.12 + 4 Δx
    assert!(errors[3] < 1e-3, "L1 error at n = 1600: {}", errors[3]);
}

#[test]
fn coulomb_dam_break_front_matches_mangeney_heinrich_roche_2000() {
    // tan δ = tan 30° = 0.577, g = h0 = 1: the front decelerates at g tan δ; at t = 0.5 it is
    // 0.072 (29 cells at n = 1200) behind Ritter's. Channel [0, 3], dam at 1.5; the front is read
    // at 1 % of h0 as in the Ritter test, where the lag is ~3 cells at this Δx.
    let (x0, delta) = (1.5, 30.0_f64);
    let mu = delta.to_radians().tan();
    let mut m = dam(1200, 3.0, x0, delta);
    let eps = 1e-2;
    for t in [0.25, 0.5, 1.0] {
        m.advance(t, u64::MAX).unwrap();
        let xf = x0 + 2.0 * G.sqrt() * t - 0.5 * G * mu * t * t;
        let exact = xf - 3.0 * t * (G * eps).sqrt();
        let ritter_front = x0 + 2.0 * G.sqrt() * t - 3.0 * t * (G * eps).sqrt();
        let got = m.front(eps);
        println!("t = {t}: front(1e-2) = {got:.5}, Mangeney {exact:.5}, frictionless {ritter_front:.5}, dx = {:.5}", m.dx());
        assert!((got - exact).abs() < 3.0 * m.dx(), "t = {t}: front {got} vs {exact}");
        // and it is not the frictionless front: more than half the friction shift ½ g tan δ t²
        // (7 to 115 cells here) separates them
        assert!(ritter_front - got > 0.25 * G * mu * t * t);
    }
}

#[test]
fn mass_is_conserved_to_round_off() {
    // fluidised dam break with friction, pore-pressure supply and a bumpy bed, 2000 steps,
    // reflected at both walls: Σ h Δx changes only by the round-off of the flux differences
    // (~ n ε per step, relative 1e-16 each).
    let n = 400;
    let mut cfg = DepthAveragedConfig::new(n, 2.0);
    cfg.basal_friction_angle = 15.0;
    cfg.pore = Some(DepthAveragedPore { diffusivity: 0.035, supply_ratio: 0.9, supply_x_max: 0.3, transport: PoreTransport::DepthIntegrated });
    let mut m = DepthAveragedModel::new(cfg).unwrap();
    let h: Vec<f64> = (0..n).map(|i| if m.x(i) < 0.3 { 0.4 } else { 0.0 }).collect();
    let beta: Vec<f64> = (0..n).map(|i| if m.x(i) < 0.3 { 0.9 } else { 0.0 }).collect();
    let bed: Vec<f64> = (0..n).map(|i| 0.02 * (8.0 * m.x(i)).sin().powi(2)).collect();
    m.set_bed(&bed).unwrap();
    m.set_state(&h, &vec![0.0; n], &beta).unwrap();
    let m0 = m.mass();
    let mut worst = 0.0_f64;
    for _ in 0..2000 {
        m.step().unwrap();
        worst = worst.max((m.mass() - m0).abs() / m0);
    }
    println!("mass: largest relative change {worst:e} over 2000 steps, t = {:.3} s", m.time);
    assert!(worst < 1e-12, "relative mass change {worst:e}");
    assert!(m.front(1e-3) > 0.8, "the layer spread: front {}", m.front(1e-3));
}

#[test]
fn friction_stops_a_sliding_layer_exactly_and_it_stays_at_rest() {
    // a layer h = 0.1 m on [1, 2] of a 3 m channel sliding at u0 = 0.5 m/s, tan δ = 0.5,
    // g = 9.81: its uniform core decelerates at g tan δ (the pressure gradient vanishes there and
    // the SSP-RK2 friction projections add up to exactly Δt g h tan δ per step), so u = u0 −
    // g tan δ t until t_s = u0/(g tan δ) = 0.1019 s, then u = 0 exactly.
    let n = 600;
    let mut cfg = DepthAveragedConfig::new(n, 3.0);
    cfg.basal_friction_angle = 0.5_f64.atan().to_degrees();
    let mut m = DepthAveragedModel::new(cfg).unwrap();
    let inside = |x: f64| (1.0..2.0).contains(&x);
    let h: Vec<f64> = (0..n).map(|i| if inside(m.x(i)) { 0.1 } else { 0.0 }).collect();
    let u: Vec<f64> = (0..n).map(|i| if inside(m.x(i)) { 0.5 } else { 0.0 }).collect();
    m.set_state(&h, &u, &vec![0.0; n]).unwrap();
    let core = n / 2; // x = 1.5025
    let decel = 9.81 * 0.5;
    m.advance(0.05, u64::MAX).unwrap();
    let expected = 0.5 - decel * 0.05;
    println!("core u(0.05) = {:.15}, analytic {expected:.15}", m.velocity()[core]);
    assert!((m.velocity()[core] - expected).abs() < 1e-12);
    let t_s = 0.5 / decel;
    m.advance(t_s + 1e-3, u64::MAX).unwrap();
    assert_eq!(m.velocity()[core], 0.0, "the core stops exactly");
    // the edges spread until their slopes are held by friction; then everything is at rest
    let mut steps = 0;
    while m.max_speed() > 0.0 {
        m.step().unwrap();
        steps += 1;
        assert!(steps < 200_000, "the layer never stopped (t = {})", m.time);
    }
    println!("at rest at t = {:.4} s after {} more steps; front {:.4}", m.time, steps, m.front(1e-6));
    let h_rest = m.depth().to_vec();
    for _ in 0..500 {
        m.step().unwrap();
    }
    assert!(m.velocity().iter().all(|&v| v == 0.0), "stays at rest: u = 0 exactly");
    assert_eq!(m.depth(), &h_rest[..], "and the deposit does not creep");
}

#[test]
fn lake_at_rest_over_a_bump_with_a_dry_island_is_preserved() {
    // hydrostatic reconstruction: h + b = 0.5 over a bump reaching 0.7 (dry on top); u stays 0
    let n = 200;
    let mut m = DepthAveragedModel::new(DepthAveragedConfig::new(n, 1.0)).unwrap();
    let b: Vec<f64> = (0..n).map(|i| 0.7 * (-((m.x(i) - 0.5) / 0.1).powi(2)).exp()).collect();
    let h: Vec<f64> = b.iter().map(|&b| (0.5 - b).max(0.0)).collect();
    m.set_bed(&b).unwrap();
    m.set_state(&h, &vec![0.0; n], &vec![0.0; n]).unwrap();
    for _ in 0..500 {
        m.step().unwrap();
    }
    let dh = m.depth().iter().zip(&h).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    println!("lake at rest: max |u| = {:e}, max |dh| = {dh:e}", m.max_speed());
    assert!(m.max_speed() < 1e-12 && dh < 1e-12);
}

#[test]
fn depth_integrated_pore_pressure_relaxes_at_two_kappa_over_h_squared_to_the_supply() {
    // a uniform layer at rest (h = 0.1, β = 0.3) on a frictional bed, supply β_s = 0.9 on
    // x < 0.2: m = β h²/2 relaxes as m_eq + (m₀ − m_eq) e^{−2κt/h²} exactly (frozen h), with
    // m_eq = ½ β_s h² under the supply (β → 0.9 from below) and 0 elsewhere
    let n = 50;
    let mut cfg = DepthAveragedConfig::new(n, 1.0);
    cfg.basal_friction_angle = 15.0;
    cfg.pore = Some(DepthAveragedPore { diffusivity: 0.035, supply_ratio: 0.9, supply_x_max: 0.2, transport: PoreTransport::DepthIntegrated });
    let mut m = DepthAveragedModel::new(cfg).unwrap();
    m.set_state(&vec![0.1; n], &vec![0.0; n], &vec![0.3; n]).unwrap();
    m.advance(0.05, u64::MAX).unwrap();
    let decay = (-2.0 * 0.035 * 0.05 / 0.01_f64).exp();
    let beta = m.pore_ratio();
    println!("beta(0.05) = {} (analytic {}), under the supply {} (analytic {})", beta[n - 1], 0.3 * decay, beta[0], 0.9 + (0.3 - 0.9) * decay);
    assert!((beta[n - 1] - 0.3 * decay).abs() < 1e-12);
    assert!((beta[0] - (0.9 + (0.3 - 0.9) * decay)).abs() < 1e-12);
    assert_eq!(m.max_speed(), 0.0);
    // the steady state under the supply is β = β_s
    m.advance(5.0, u64::MAX).unwrap();
    assert!((m.pore_ratio()[0] - 0.9).abs() < 1e-12, "{}", m.pore_ratio()[0]);
}

#[test]
fn basal_ratio_transport_decays_at_the_slowest_mode_and_is_held_by_the_supply() {
    // PoreTransport::BasalRatio: hβ decays as exp(−t π²κ/(4h²)) exactly (frozen h); under the
    // supply β stays at β_s = 0.9
    let n = 50;
    let mut cfg = DepthAveragedConfig::new(n, 1.0);
    cfg.basal_friction_angle = 15.0;
    cfg.pore = Some(DepthAveragedPore { diffusivity: 0.035, supply_ratio: 0.9, supply_x_max: 0.2, transport: PoreTransport::BasalRatio });
    let mut m = DepthAveragedModel::new(cfg).unwrap();
    m.set_state(&vec![0.1; n], &vec![0.0; n], &vec![0.8; n]).unwrap();
    m.advance(0.05, u64::MAX).unwrap();
    let expected = 0.8 * (-0.05 * std::f64::consts::PI.powi(2) * 0.035 / (4.0 * 0.01)).exp();
    let beta = m.pore_ratio();
    assert!((beta[n - 1] - expected).abs() < 1e-12);
    assert_eq!(beta[0], 0.9);
    assert_eq!(m.max_speed(), 0.0);
}

#[test]
fn a_thinning_layer_carries_its_integrated_pore_pressure_and_its_basal_ratio_rises() {
    // frictionless dam break (h₀ = 0.4 m on x < 0.2) with β₀ = 0.9 and a negligible
    // diffusivity (κ = 1e-14: e^{−2κt/h²} > 1 − 1e-6 over 0.3 s where h > 0.1 mm): Σ m Δx is conserved
    // (the flux is conservative, the walls closed) and, m/h being carried, β = 2m/h² exceeds 1
    // where the layer has thinned below 0.9 h₀ (β = 0.9 h₀/h along a path)
    let n = 400;
    let mut cfg = DepthAveragedConfig::new(n, 2.0);
    cfg.pore = Some(DepthAveragedPore { diffusivity: 1e-14, supply_ratio: 0.9, supply_x_max: 0.0, transport: PoreTransport::DepthIntegrated });
    cfg.dry_depth = 1e-8;
    let mut m = DepthAveragedModel::new(cfg).unwrap();
    let h: Vec<f64> = (0..n).map(|i| if m.x(i) < 0.2 { 0.4 } else { 0.0 }).collect();
    let beta: Vec<f64> = (0..n).map(|i| if m.x(i) < 0.2 { 0.9 } else { 0.0 }).collect();
    m.set_state(&h, &vec![0.0; n], &beta).unwrap();
    let pm = |m: &DepthAveragedModel| -> f64 { m.depth().iter().zip(m.pore_ratio()).map(|(h, b)| 0.5 * b * h * h).sum::<f64>() * m.dx() };
    let p0 = pm(&m);
    m.advance(0.3, u64::MAX).unwrap();
    let rel = (pm(&m) - p0).abs() / p0;
    println!("integrated pore pressure: relative change {rel:e}");
    // measured 5.8e-8: the films thinner than h_dry, and those decaying at 2κ/h², lose their m
    assert!(rel < 1e-6, "{rel:e}");
    let (h, b) = (m.depth(), m.pore_ratio());
    let i = (0..n).find(|&i| h[i] > 0.01 && h[i] < 0.1).unwrap();
    println!("h = {}, beta = {} (0.9 h0/h = {})", h[i], b[i], 0.36 / h[i]);
    // m/h = 0.18 m starts uniform, and the upwind flux of a uniform s keeps it so: β = 0.36/h
    // to round-off
    assert!(b[i] > 1.0 && (b[i] * h[i] / 0.36 - 1.0).abs() < 1e-9, "{}", b[i] * h[i] / 0.36);
    // K = 1 where β ≥ 1 (no effective stress), k (1 − β) + β below
    assert_eq!(lateral_pressure(0.5, 1.7), 1.0);
    assert!((lateral_pressure(0.5, 0.9) - 0.95).abs() < 1e-15);
}

#[test]
fn parameters_are_validated_by_name() {
    let bad = |f: &dyn Fn(&mut DepthAveragedConfig), name: &str| {
        let mut cfg = DepthAveragedConfig::new(100, 1.0);
        f(&mut cfg);
        match DepthAveragedModel::new(cfg) {
            Err(Error::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
            Err(e) => panic!("{name}: wrong error {e}"),
            Ok(_) => panic!("{name}: accepted"),
        }
    };
    bad(&|c| c.cfl = 0.7, "cfl");
    bad(&|c| c.cells = 2, "cells");
    bad(&|c| c.length = -1.0, "length");
    bad(&|c| c.earth_pressure = EarthPressure::Constant(0.0), "earth_pressure");
    bad(&|c| c.earth_pressure = EarthPressure::SavageHutterActive { internal_friction_angle: -3.0 }, "internal_friction_angle");
    bad(&|c| c.basal_friction_angle = 95.0, "basal_friction_angle");
    bad(&|c| c.dry_depth = f64::NAN, "dry_depth");
    bad(
        &|c| c.pore = Some(DepthAveragedPore { diffusivity: 0.035, supply_ratio: 1.5, supply_x_max: 0.2, transport: PoreTransport::DepthIntegrated }),
        "supply_ratio",
    );
    let mut m = DepthAveragedModel::new(DepthAveragedConfig::new(10, 1.0)).unwrap();
    assert!(matches!(m.set_state(&[-1.0; 10], &[0.0; 10], &[0.0; 10]), Err(Error::InvalidParameter { ref name, .. }) if name == "h"));
    assert!(matches!(m.set_state(&[1.0; 9], &[0.0; 9], &[0.0; 9]), Err(Error::Shape { .. })));
}

#[test]
fn a_blow_up_is_reported_with_step_time_and_cell() {
    // a momentum flux h u² beyond f64's range (u = 1e160 in cell 3) turns into inf/NaN in the
    // first step: reported as Error::Simulation, not carried on
    let mut m = DepthAveragedModel::new(DepthAveragedConfig::new(10, 1.0)).unwrap();
    let mut u = vec![0.0; 10];
    u[3] = 1e160;
    m.set_state(&[1.0; 10], &u, &[0.0; 10]).unwrap();
    match m.step() {
        Err(Error::Simulation { step, location: Some((i, 0)), what, .. }) => {
            println!("{what} at cell {i}");
            assert_eq!(step, 1, "the first step");
            // two stages of a 5-cell stencil spread it at most 3 cells: the first bad cell is
            // within 3 of cell 3
            assert!(i <= 6 && what.contains("non-finite"));
        }
        other => panic!("expected a Simulation error, got {other:?}"),
    }
}

#[test]
fn savage_hutter_active_coefficient_limits_and_the_effective_stress_closure() {
    // δ = 0: Rankine's active coefficient (1 − sin φ)/(1 + sin φ) (1/3 at φ = 30°); δ = φ:
    // 2 sec²φ − 1 (1.5232 at 27°), and δ > φ clipped to φ; the paper's angles φ = 27°,
    // δ = 15°: 0.5464
    let t = |deg: f64| deg.to_radians().tan();
    assert!((active_earth_pressure(t(30.0), 0.0) - 1.0 / 3.0).abs() < 1e-14);
    let c27 = 27.0_f64.to_radians().cos().powi(2);
    assert!((active_earth_pressure(t(27.0), t(27.0)) - (2.0 / c27 - 1.0)).abs() < 1e-14);
    assert_eq!(active_earth_pressure(t(27.0), t(30.0)), active_earth_pressure(t(27.0), t(27.0)));
    let k = active_earth_pressure(t(27.0), t(15.0));
    let c2d = 15.0_f64.to_radians().cos().powi(2);
    assert!((k - (2.0 / c27 * (1.0 - (1.0 - c27 / c2d).sqrt()) - 1.0)).abs() < 1e-14 && (k - 0.5464).abs() < 1e-4);
    // in a model: k of the dry angles on the effective stress, K = k (1 − β) + β cell by cell
    let mut cfg = DepthAveragedConfig::new(10, 1.0);
    cfg.basal_friction_angle = 15.0;
    cfg.earth_pressure = EarthPressure::SavageHutterActive { internal_friction_angle: 27.0 };
    cfg.pore = Some(DepthAveragedPore { diffusivity: 0.035, supply_ratio: 0.9, supply_x_max: 0.0, transport: PoreTransport::DepthIntegrated });
    let mut m = DepthAveragedModel::new(cfg).unwrap();
    assert!((m.effective_earth_pressure() - k).abs() < 1e-15);
    let beta: Vec<f64> = (0..10).map(|i| i as f64 / 10.0).collect();
    m.set_state(&[0.1; 10], &[0.0; 10], &beta).unwrap();
    for (kc, b) in m.earth_pressure().zip(&beta) {
        assert!((kc - (k * (1.0 - b) + b)).abs() < 1e-14, "{kc} at beta {b}");
    }
}
