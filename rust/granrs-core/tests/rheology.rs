//! Rheology: laws, the plastic projection and its Picard iteration (bi-projection, Chupin & Dubois
//! 2016), Coulomb walls, parameter errors.

use granrs_core::grid::{BoundaryConditions, Grid, Side, VelocityBc};
use granrs_core::models::{Material, ModelConfig, TwoPhaseModel};
use granrs_core::rheology::plastic::unit_ball_scale;
use granrs_core::rheology::{RheologyConfig, RheologyLaw, SigmaLocation, YieldTreatment};
use granrs_core::walls::side::SideWalls;
use granrs_core::Error;

/// Bingham plane Poiseuille flow (validation-data §3): channel 0 < y < 2 (half-width h = 1),
/// body force G = 1 along x, μ = ρ = 1, no-slip walls, outflow sides (p = 0, x-invariant flow).
fn poiseuille(n: usize, tau_y: f64, theta: f64) -> TwoPhaseModel {
    poiseuille_with(n, tau_y, theta, SigmaLocation::Staggered)
}

fn poiseuille_with(n: usize, tau_y: f64, theta: f64, location: SigmaLocation) -> TwoPhaseModel {
    let dy = 2.0 / n as f64;
    let grid = Grid::new(4, n, 4.0 * dy, 2.0).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Left, VelocityBc::Outflow).with(Side::Right, VelocityBc::Outflow);
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1.0, viscosity: 1.0 });
    cfg.gravity = [1.0, 0.0];
    cfg.time.fixed_dt = Some(0.5);
    cfg.time.cfl_abort = 100.0;
    cfg.rheology = RheologyConfig::new(RheologyLaw::Bingham { yield_stress: tau_y });
    cfg.rheology.theta = theta;
    cfg.rheology.picard_tol = 1e-11;
    cfg.rheology.sigma_location = location;
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    for _ in 0..400 {
        let before = m.u.clone();
        m.step().unwrap();
        let change = (0..n).map(|j| (m.u.at(2, j as isize) - before.at(2, j as isize)).abs()).fold(0.0, f64::max);
        if change < 1e-10 {
            break;
        }
    }
    m
}

fn exact_poiseuille(y: f64, tau_y: f64) -> f64 {
    let eta = (y - 1.0).abs();
    if eta <= tau_y {
        0.5 * (1.0 - tau_y).powi(2)
    } else {
        0.5 * ((1.0 - eta * eta) - 2.0 * tau_y * (1.0 - eta))
    }
}

#[test]
fn poiseuille_plug_exact_and_second_order() {
    let tau_y = 0.25;
    let mut errors = Vec::new();
    for n in [16, 32, 64] {
        let m = poiseuille(n, tau_y, 0.5);
        let g = m.grid().clone();
        let (mut e2, mut n2, mut umax) = (0.0, 0.0, 0.0f64);
        let (mut plug_min, mut plug_max) = (f64::INFINITY, f64::NEG_INFINITY);
        for j in 0..n {
            let y = g.yc(j as isize);
            let ex = exact_poiseuille(y, tau_y);
            let u = m.u.at(2, j as isize);
            e2 += (u - ex).powi(2);
            n2 += ex * ex;
            umax = umax.max(u);
            if (y - 1.0).abs() < tau_y {
                plug_min = plug_min.min(u);
                plug_max = plug_max.max(u);
            }
        }
        let l2 = (e2 / n2).sqrt();
        println!("n = {n}: steps {} u_plug {umax:.12} (exact 0.28125) spread {:.1e} l2 {l2:.3e}", m.step_count, plug_max - plug_min);
        // exact plug velocity to the Picard tolerance; rigid plug
        assert!((umax - 0.28125).abs() < 1e-6 && plug_max - plug_min < 1e-9);
        errors.push(l2);
    }
    let orders: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    println!("orders {orders:?}");
    // required: l2 <= 1 % at n = 64, second order
    assert!(errors[2] <= 0.01 && orders.iter().all(|&o| o >= 1.9));
}

/// `SigmaLocation::Centres` (the paper's Figure 3): D_xy is averaged from the nodes to the centres,
/// so the yield surface is smeared over a cell and the plug is rigid only in the average of two
/// node rows. Printed: the plug speed and the l2 error against the exact profile at n = 16, 32, 64.
#[test]
fn centred_plastic_tensor_converges_to_the_bingham_poiseuille_profile() {
    let tau_y = 0.25;
    let mut errors = Vec::new();
    for n in [16, 32, 64] {
        let m = poiseuille_with(n, tau_y, 0.5, SigmaLocation::Centres);
        let g = m.grid().clone();
        let (mut e2, mut n2, mut umax) = (0.0, 0.0, 0.0f64);
        for j in 0..n {
            let ex = exact_poiseuille(g.yc(j as isize), tau_y);
            let u = m.u.at(2, j as isize);
            e2 += (u - ex).powi(2);
            n2 += ex * ex;
            umax = umax.max(u);
        }
        let l2 = (e2 / n2).sqrt();
        println!("centres, n = {n}: steps {} u_plug {umax:.9} (exact 0.28125) l2 {l2:.3e}", m.step_count);
        errors.push((l2, (umax - 0.28125).abs()));
    }
    let orders: Vec<f64> = errors.windows(2).map(|w| (w[0].0 / w[1].0).log2()).collect();
    println!("orders {orders:?}");
    // measured: the staggered layout's l2 errors (7.46e-3, 1.87e-3, 4.66e-4) to three digits, and
    // the plug speed within 2e-6 of exact; but the stress settles slowly (166 steps at n = 16, the
    // 400-step cap at 32 and 64, against 29 staggered): the cell-averaged D_xy leaves the zig-zag
    // of D_xy between node rows to the viscosity alone. Bounds: the required 1 % at n = 64, second
    // order, the plug within 1e-5 (the cap's residual, 5× the measured).
    assert!(errors[2].0 <= 0.01 && orders.iter().all(|&o| o >= 1.9), "{errors:?} {orders:?}");
    assert!(errors.iter().all(|e| e.1 < 1e-5), "plug speeds {errors:?}");
}

#[test]
fn unit_ball_projection() {
    assert_eq!(unit_ball_scale(0.3, 0.4), 1.0);
    let s = unit_ball_scale(3.0, 4.0);
    assert!((s - 0.2).abs() < 1e-15);
    // |Σ|² = Σ_xx² + Σ_xy² is the paper's √(½ Σ λ_ij²) for a symmetric traceless tensor
    let (xx, xy) = (0.6_f64, 0.8_f64);
    let paper = (0.5 * (xx * xx + xy * xy + xy * xy + xx * xx)).sqrt();
    assert!((paper - 1.0).abs() < 1e-15);
}

#[test]
fn laws_in_simple_shear() {
    let dp = RheologyLaw::DruckerPrager { friction_angle: 27.0 };
    assert!((dp.yield_stress(1000.0) - 27f64.to_radians().tan() * 1000.0).abs() < 1e-9);
    assert_eq!(dp.yield_stress(-5.0), 0.0);
    // μ(I): in simple shear u'(y) = γ̇, |D| = γ̇/2, I = γ̇ d √(ρ_s/p); total shear stress
    // η γ̇ + μ_s p must equal μ(I) p
    let (mu_s, mu_2, i0, d, rho_s) = (0.38, 0.64, 0.3, 1e-3, 2500.0);
    let law = RheologyLaw::MuI { mu_s, mu_2, i0, grain_diameter: d, grain_density: rho_s };
    let (p, gd) = (800.0, 12.0);
    let i = gd * d * (rho_s / p).sqrt();
    let mu_i = mu_s + (mu_2 - mu_s) / (i0 / i + 1.0);
    let stress = law.extra_viscosity(gd / 2.0, p) * gd + law.yield_stress(p);
    assert!((stress / (mu_i * p) - 1.0).abs() < 1e-12);
    // Papanastasiou: η + τ m/2 at rest, η + τ/(2|D|) at large rates
    let pap = YieldTreatment::Papanastasiou { m: 100.0 };
    assert!((pap.regularised_viscosity(2.0, 0.0, 1.0) - 100.0).abs() < 1e-12);
    assert!((pap.regularised_viscosity(2.0, 10.0, 1.0) - 0.1).abs() < 1e-12);
    let bv = YieldTreatment::BiViscous { yield_viscosity: 50.0 };
    assert_eq!(bv.regularised_viscosity(2.0, 0.0, 1.0), 49.0);
}

fn cfg_with(f: impl Fn(&mut RheologyConfig)) -> Result<TwoPhaseModel, Error> {
    let grid = Grid::new(8, 8, 1.0, 1.0).unwrap();
    let mut cfg = ModelConfig::single_phase(grid, BoundaryConditions::uniform(VelocityBc::NoSlip), Material { density: 1.0, viscosity: 1.0 });
    cfg.rheology = RheologyConfig::new(RheologyLaw::Bingham { yield_stress: 1.0 });
    f(&mut cfg.rheology);
    TwoPhaseModel::new(cfg)
}

#[test]
fn bad_parameters_name_themselves() {
    let name = |r: Result<TwoPhaseModel, Error>| match r {
        Err(Error::InvalidParameter { name, .. }) => name,
        Err(e) => panic!("unexpected error {e}"),
        Ok(_) => panic!("accepted"),
    };
    assert_eq!(name(cfg_with(|c| c.theta = 1.0)), "theta");
    assert_eq!(name(cfg_with(|c| c.r = Some(-1.0))), "r");
    assert_eq!(name(cfg_with(|c| c.law = RheologyLaw::Bingham { yield_stress: -1.0 })), "yield_stress");
    assert_eq!(name(cfg_with(|c| c.law = RheologyLaw::DruckerPrager { friction_angle: 90.0 })), "friction_angle");
    assert_eq!(name(cfg_with(|c| c.wall_friction_angle = Some(f64::NAN))), "wall_friction_angle");
    assert_eq!(name(cfg_with(|c| c.law = RheologyLaw::MuI { mu_s: 0.5, mu_2: 0.4, i0: 0.3, grain_diameter: 1e-3, grain_density: 2500.0 })), "mu_2");
    assert_eq!(name(cfg_with(|c| c.treatment = YieldTreatment::Papanastasiou { m: 0.0 })), "regularisation");
    assert_eq!(name(cfg_with(|c| c.picard_max_iterations = 0)), "picard_max_iterations");
}

/// Bingham cavity (Stokes) with a given θ: fitted geometric ratio of the Picard increments of the
/// third step.
fn cavity_ratio(theta: f64) -> f64 {
    let mut m = bingham_cavity(32, 0.05, theta, 0, false, 1);
    for _ in 0..3 {
        m.step().unwrap();
    }
    let h: Vec<(f64, f64)> = m.picard_history().iter().enumerate().filter(|(k, &x)| *k >= 3 && x > 1e-11).map(|(k, &x)| (k as f64, x.ln())).collect();
    let tail = &h[h.len() / 2..];
    let n = tail.len() as f64;
    let (sx, sy) = tail.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
    let (mx, my) = (sx / n, sy / n);
    let slope = tail.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / tail.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    slope.exp()
}

#[test]
fn picard_ratio_is_one_minus_theta() {
    for theta in [0.25, 0.5, 0.75] {
        let r = cavity_ratio(theta);
        println!("theta {theta}: ratio {r:.3} (1 - theta = {})", 1.0 - theta);
        // paper §3.1: ratio 1 − θ (measured 0.718, 0.454, 0.249)
        assert!((r - (1.0 - theta)).abs() <= 0.1, "theta {theta}: ratio {r}");
    }
}

#[test]
fn picard_cap_is_a_simulation_error() {
    let grid = Grid::new(16, 16, 1.0, 1.0).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Top, VelocityBc::Velocity { normal: 0.0, tangential: 1.0 });
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1.0, viscosity: 1.0 });
    cfg.time.fixed_dt = Some(0.05);
    cfg.rheology = RheologyConfig::new(RheologyLaw::Bingham { yield_stress: 5.0 });
    cfg.rheology.picard_max_iterations = 2;
    cfg.rheology.picard_tol = 1e-12;
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    match m.step() {
        Err(Error::Simulation { what, .. }) => assert!(what.starts_with("Picard iteration of the plastic projection did not converge: increment")),
        other => panic!("expected a Picard error, got {other:?}"),
    }
}

/// A single-phase D-P layer (H = 0.1 m, 32 cells, α = 27°, φρ_s = 1450, η_s = 0.1) on a slope of
/// `slope` degrees, periodic along it, on a Coulomb base α_b = 15° with `top` above, δt = `dt`.
fn sliding_layer(slope: f64, top: VelocityBc, dt: f64) -> ModelConfig {
    let n = 32;
    let h = 0.1;
    let grid = Grid::new(4, n, 4.0 * 8.0 * h / n as f64, h).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::FullyDeveloped).with(Side::Bottom, VelocityBc::Coulomb).with(Side::Top, top);
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1450.0, viscosity: 0.1 });
    let s = slope.to_radians();
    cfg.gravity = [9.81 * s.sin(), -9.81 * s.cos()];
    cfg.convection = false;
    cfg.time.fixed_dt = Some(dt);
    cfg.time.cfl_abort = 100.0;
    cfg.pressure_solver.rtol = 1e-12;
    cfg.pressure_solver.max_iterations = 50000;
    cfg.rheology = RheologyConfig::new(RheologyLaw::DruckerPrager { friction_angle: 27.0 });
    cfg.rheology.wall_friction_angle = Some(15.0);
    cfg
}

/// The mean acceleration of a `sliding_layer`-type model over its steps 100–200 (after the
/// start-up of the relaxed plastic stress), from the depth-mean of u in one column.
fn layer_acceleration(m: &mut TwoPhaseModel) -> f64 {
    let n = m.grid().ny;
    let mean = |m: &TwoPhaseModel| (0..n).map(|j| m.u.at(2, j as isize)).sum::<f64>() / n as f64;
    for _ in 0..100 {
        m.step().unwrap();
    }
    let (t0, u0) = (m.time, mean(m));
    for _ in 0..100 {
        m.step().unwrap();
    }
    (mean(m) - u0) / (m.time - t0)
}

#[test]
fn sliding_layer_on_coulomb_base_accelerates_at_the_friction_rate() {
    // the layer above on a 30° slope under an open top: a = g (sin θ − tan α_b cos θ)
    let s = 30f64.to_radians();
    let mut m = TwoPhaseModel::new(sliding_layer(30.0, VelocityBc::Outflow, 1e-3)).unwrap();
    m.initialise_pressure().unwrap();
    let a = layer_acceleration(&mut m);
    let exact = 9.81 * (s.sin() - 15f64.to_radians().tan() * s.cos());
    println!("acceleration {a:.5} exact {exact:.5}");
    assert!((a / exact - 1.0).abs() < 0.02);
}

/// Checkpoint and restart (models/checkpoint.rs): a Bingham cavity (Σ is state) continued from a
/// restored checkpoint equals the uninterrupted run bit for bit; a checkpoint of another
/// configuration is refused with the entry named.
#[test]
fn restart_from_a_checkpoint_is_bit_identical() {
    let build = || {
        let grid = Grid::new(16, 16, 1.0, 1.0).unwrap();
        let bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Top, VelocityBc::Velocity { normal: 0.0, tangential: 1.0 });
        let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1.0, viscosity: 0.05 });
        cfg.rheology = RheologyConfig::new(RheologyLaw::Bingham { yield_stress: 0.5 });
        cfg.rheology.picard_tol = 1e-8;
        TwoPhaseModel::new(cfg).unwrap()
    };
    let mut a = build();
    for _ in 0..5 {
        a.step().unwrap();
    }
    let state = a.checkpoint();
    for _ in 0..5 {
        a.step().unwrap();
    }
    let mut b = build();
    b.restore(&state).unwrap();
    assert_eq!(b.step_count, 5);
    for _ in 0..5 {
        b.step().unwrap();
    }
    assert_eq!(a.u.slice(), b.u.slice());
    assert_eq!(a.v.slice(), b.v.slice());
    assert_eq!(a.p.slice(), b.p.slice());
    assert_eq!(a.plastic_tensor().unwrap().0.slice(), b.plastic_tensor().unwrap().0.slice());
    assert_eq!(a.time.to_bits(), b.time.to_bits());
    // a Newtonian model has no Σ: the entry is refused by name
    let grid = Grid::new(16, 16, 1.0, 1.0).unwrap();
    let mut c =
        TwoPhaseModel::new(ModelConfig::single_phase(grid, BoundaryConditions::uniform(VelocityBc::NoSlip), Material { density: 1.0, viscosity: 0.05 }))
            .unwrap();
    match c.restore(&state) {
        Err(Error::InvalidParameter { value, .. }) => assert!(value.starts_with("sigma"), "{value}"),
        other => panic!("accepted a foreign checkpoint: {other:?}"),
    }
}

/// A D-P granular phase (φρ_s = 1450, η_s = 0.1, α = 27°) under `light` with vertical gravity,
/// δt = 1 ms, Picard tolerance 1e-6.
fn dp_layer_under_air(grid: Grid, bc: BoundaryConditions, light: Material) -> ModelConfig {
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1450.0, viscosity: 0.1 });
    cfg.light = Some(light);
    cfg.gravity = [0.0, -9.81];
    cfg.time.fixed_dt = Some(1e-3);
    cfg.rheology = RheologyConfig::new(RheologyLaw::DruckerPrager { friction_angle: 27.0 });
    cfg.rheology.picard_tol = 1e-6;
    cfg
}

/// The pressure gauge (`ModelConfig::pressure_gauge`): in a closed box with a pressure-dependent
/// yield stress, `Auto` resolves to `Top` and the air under the lid sits at p = 0 (to round-off),
/// so that a heavy layer's pressure at depth d is its weight ρ g d, not ρ g d − ⟨p⟩; with `Mean`
/// the domain mean is 0 and the air is at −⟨p⟩ < 0. Velocities do not depend on the gauge.
#[test]
fn pressure_gauge_puts_the_air_at_zero_under_a_closed_lid() {
    use granrs_core::levelset::Shape;
    use granrs_core::models::PressureGauge;
    let build = |gauge: PressureGauge| {
        let grid = Grid::new(32, 16, 1.0, 0.5).unwrap();
        let bc = BoundaryConditions::uniform(VelocityBc::FreeSlip);
        let mut cfg = dp_layer_under_air(grid, bc, Material { density: 1.2, viscosity: 1.8e-5 });
        cfg.pressure_gauge = gauge;
        let mut m = TwoPhaseModel::new(cfg).unwrap();
        // a flat layer 0.2 m deep with its surface in mid-cell
        m.set_shape(&Shape::Rectangle { x0: -1.0, x1: 2.0, y0: -1.0, y1: 0.2 + 1.0 / 64.0 }).unwrap();
        m.initialise_pressure().unwrap();
        for _ in 0..3 {
            m.step().unwrap();
        }
        m
    };
    let top_mean = |m: &TwoPhaseModel| (0..32).map(|i| m.p.at(i, 15)).sum::<f64>() / 32.0;
    let all_mean = |m: &TwoPhaseModel| (0..16).flat_map(|j| (0..32).map(move |i| (i, j))).map(|(i, j)| m.p.at(i, j)).sum::<f64>() / 512.0;
    let top = build(PressureGauge::Auto);
    let mean = build(PressureGauge::Mean);
    assert_eq!(top.config().resolved_pressure_gauge(), Some(PressureGauge::Top));
    assert!(top_mean(&top).abs() < 1e-9, "top-row mean {}", top_mean(&top));
    // bottom cell centre at depth 0.2156 − 0.0156: ρ g d ≈ 2845 Pa (+ the air column, 3 Pa)
    let expect = 1450.0 * 9.81 * (0.2 + 1.0 / 64.0 - 1.0 / 64.0) + 1.2 * 9.81 * 0.3;
    assert!((top.p.at(16, 0) / expect - 1.0).abs() < 0.02, "bottom p {} vs {}", top.p.at(16, 0), expect);
    assert!(all_mean(&mean).abs() < 1e-9 * expect);
    assert!(mean.p.at(16, 15) < -500.0, "zero-mean gauge: air at {}", mean.p.at(16, 15));
    // a layer at rest stays at rest either way: the pressures differ by a constant
    let shift = top.p.at(0, 0) - mean.p.at(0, 0);
    for j in 0..16 {
        for i in 0..32 {
            assert!((top.p.at(i, j) - mean.p.at(i, j) - shift).abs() < 1e-9 * expect);
            assert!((top.u.at(i, j) - mean.u.at(i, j)).abs() < 1e-8);
        }
    }
}

const BAND_LAYER_NY: usize = 32;
const BAND_LAYER_H: f64 = 0.08 / BAND_LAYER_NY as f64;

/// A D-P layer `depth` cells deep under air in a 4 × 32 box of h = 2.5 mm (fully developed
/// sides, Coulomb base at 15°, free-slip lid), `configure` applied to its configuration, the
/// pressure initialised: the layer of the band tests.
fn band_layer(depth: f64, configure: impl Fn(&mut ModelConfig)) -> TwoPhaseModel {
    use granrs_core::levelset::Shape;
    let (nx, ny, h) = (4, BAND_LAYER_NY, BAND_LAYER_H);
    let grid = Grid::new(nx, ny, nx as f64 * h, ny as f64 * h).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::FullyDeveloped).with(Side::Bottom, VelocityBc::Coulomb).with(Side::Top, VelocityBc::FreeSlip);
    let mut cfg = dp_layer_under_air(grid, bc, Material { density: 1.0, viscosity: 2e-5 });
    cfg.rheology.wall_friction_angle = Some(15.0);
    configure(&mut cfg);
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    m.set_shape(&Shape::Rectangle { x0: -1.0, x1: 1.0, y0: -1.0, y1: depth * h }).unwrap();
    m.initialise_pressure().unwrap();
    m
}

/// Where the smoothed jump of the yield stress and the basal friction sits
/// (`RheologyConfig::interface_yield`). A flat D-P layer (α = 27°, α_b = 15°) under air, its
/// surface in mid-cell. With `GranularSide` every cell with Φ > 0 has the full Coulomb ratio
/// τ = tan(α) p⁺ (and the base τ_b = tan(α_b) p_wall⁺ under the layer); with the paper's H_ε(Φ)
/// the cells of the band 0 < Φ < ε have a smaller ratio (at the first cell below the surface,
/// Φ = 0.66 h = 0.44 ε: H_ε = 0.876), and the yield stress of both forms vanishes where
/// Φ < −2ε (pure air).
#[test]
fn interface_yield_sets_the_coulomb_ratio_of_the_band() {
    use granrs_core::rheology::InterfaceYield;
    let (ny, h) = (BAND_LAYER_NY, BAND_LAYER_H);
    let build = |iy: InterfaceYield| {
        let mut m = band_layer(4.16, |cfg| cfg.rheology.interface_yield = iy);
        m.step().unwrap();
        m
    };
    let (tan_a, tan_b, eps) = (27f64.to_radians().tan(), 15f64.to_radians().tan(), 1.5 * h);
    // smallest τ/(tan α p⁺) over cells with Φ > 0, largest τ where Φ < −2ε, τ_b/(tan α_b p_wall)
    let ratios = |m: &TwoPhaseModel| -> (f64, f64, f64) {
        let tau = m.yield_stress().unwrap();
        let (mut min_in, mut max_air) = (f64::INFINITY, 0.0f64);
        for j in 0..ny as isize {
            let (phi, p, t) = (m.phi.at(1, j), m.p.at(1, j), tau.at(1, j));
            if phi > 0.0 && p > 0.0 {
                min_in = min_in.min(t / (tan_a * p));
            }
            if phi < -2.0 * eps {
                max_air = max_air.max(t.abs());
            }
        }
        let (_, tau_b) = m.wall_friction(Side::Bottom).unwrap();
        let p_wall = 1.5 * m.p.at(1, 0) - 0.5 * m.p.at(1, 1);
        (min_in, max_air, tau_b[2] / (tan_b * p_wall))
    };
    let (paper_in, paper_air, paper_b) = ratios(&build(InterfaceYield::Paper));
    let (side_in, side_air, side_b) = ratios(&build(InterfaceYield::GranularSide));
    println!(
        "min τ/(tan α p) where Φ > 0: paper {paper_in:.4}, granular-side {side_in:.4}; air τ {paper_air:.1e} / {side_air:.1e}; base {paper_b:.4} / {side_b:.4}"
    );
    // τ was set from p^n, compared here with p^{n+1}: a layer at rest changes p by ~1e-12
    assert!((side_in - 1.0).abs() < 1e-9, "granular-side ratio {side_in}");
    // H_ε(0.44 ε) = 0.876 at the first cell under the surface
    assert!((paper_in - 0.876).abs() < 1e-3, "paper ratio {paper_in}");
    assert_eq!(paper_air, 0.0);
    assert_eq!(side_air, 0.0);
    assert!((side_b - 1.0).abs() < 1e-9 && (paper_b - 1.0).abs() < 1e-9, "base {paper_b} {side_b}");
}

/// `ModelConfig::ambient_hydrostatic`: between the open (fully developed) sides of a box whose
/// gravity is tilted by 20°, nothing can balance the air's weight along x, and the air falls
/// freely (u = g sin θ t); with the ambient hydrostatic pressure removed from p (body force
/// (ρ − ρ_f) g) it stays at rest. A heavy Newtonian layer at the bottom, no-slip base.
/// A box 0.2 m high of `nx` × `ny` square cells on a 20° slope: fully developed sides, no-slip
/// base, `top` above; gravity tilted by the slope.
fn slope_box(nx: usize, ny: usize, top: VelocityBc) -> (Grid, BoundaryConditions, [f64; 2]) {
    let ly = 0.2;
    let grid = Grid::new(nx, ny, nx as f64 * ly / ny as f64, ly).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::FullyDeveloped).with(Side::Bottom, VelocityBc::NoSlip).with(Side::Top, top);
    let th = 20f64.to_radians();
    (grid, bc, [9.81 * th.sin(), -9.81 * th.cos()])
}

#[test]
fn ambient_hydrostatic_keeps_the_air_at_rest_between_open_sides() {
    use granrs_core::levelset::Shape;
    let run = |ambient: bool| -> f64 {
        let ny = 16;
        let (grid, bc, gravity) = slope_box(4, ny, VelocityBc::FreeSlip);
        let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1450.0, viscosity: 1e3 });
        cfg.light = Some(Material { density: 1.0, viscosity: 2e-5 });
        cfg.gravity = gravity;
        cfg.convection = false;
        cfg.time.fixed_dt = Some(1e-3);
        cfg.ambient_hydrostatic = ambient;
        let mut m = TwoPhaseModel::new(cfg).unwrap();
        m.set_shape(&Shape::Rectangle { x0: -1.0, x1: 1.0, y0: -1.0, y1: 0.05 }).unwrap();
        m.initialise_pressure().unwrap();
        for _ in 0..100 {
            m.step().unwrap();
        }
        // the largest air speed (top rows, Φ < 0)
        (ny as isize - 4..ny as isize).map(|j| m.u.at(1, j).abs()).fold(0.0, f64::max)
    };
    let free = run(false);
    let ambient = run(true);
    println!("air speed after 0.1 s: {free:.4} m/s without, {ambient:.2e} m/s with the ambient reference");
    // free fall: g sin θ t = 0.3355 m/s at t = 0.1 s (the air's viscosity changes it by < 1e-4)
    assert!((free / (9.81 * 20f64.to_radians().sin() * 0.1) - 1.0).abs() < 0.01, "free fall {free}");
    assert!(ambient < 1e-6, "ambient {ambient}");
}

/// `balance_plastic_stress` (rheology/rest.rs) on a D-P layer 0.1 m deep on a 20° slope under
/// air (α = 27°, ambient hydrostatic reference, x-invariant: 2 columns between fully developed
/// sides). The Coulomb ratio it needs is tan 20° / tan 27° = 0.714 (to the discretisation), so
/// with the band at full strength (`DensitySupport`) nothing is clamped and the layer stays at
/// rest to round-off over 200 steps (0.2 s); with the paper's band H_ε(Φ) the top of the band
/// needs tan θ / H_ε > 1, is clamped, and slides; from Σ = 0 the layer first falls freely at
/// g sin θ while eq. (12) builds Σ up, less with proximal restarts of its anchor.
#[test]
fn balanced_plastic_stress_holds_a_layer_on_a_slope_at_rest() {
    use granrs_core::levelset::Shape;
    use granrs_core::rheology::InterfaceYield;
    let th = 20f64.to_radians();
    let run_r = |iy: InterfaceYield, balance: bool, restarts: usize| {
        let (grid, bc, gravity) = slope_box(2, 32, VelocityBc::Outflow);
        let mut cfg = dp_layer_under_air(grid, bc, Material { density: 1.0, viscosity: 2e-5 });
        cfg.gravity = gravity;
        cfg.ambient_hydrostatic = true;
        cfg.rheology.theta = 0.8;
        cfg.rheology.interface_yield = iy;
        cfg.rheology.proximal_restarts = restarts;
        cfg.rheology.picard_max_iterations = 20_000;
        let mut m = TwoPhaseModel::new(cfg).unwrap();
        m.set_shape(&Shape::Rectangle { x0: -1.0, x1: 1.0, y0: -1.0, y1: 0.1 }).unwrap();
        m.initialise_pressure().unwrap();
        let rep = if balance { Some(m.balance_plastic_stress().unwrap()) } else { None };
        let mut vmax = 0.0f64;
        for _ in 0..200 {
            vmax = vmax.max(m.step().unwrap().max_speed);
        }
        (rep, vmax)
    };
    let run = |iy: InterfaceYield, balance: bool| run_r(iy, balance, 0);
    let bound = th.tan() / 27f64.to_radians().tan();
    let (rep, rest) = run(InterfaceYield::DensitySupport, true);
    let rep = rep.unwrap();
    println!("density-support: ratio {:.4} (bound {bound:.4}), clamped {}, max speed {rest:.2e}", rep.max_ratio, rep.clamped);
    // the ratio is the continuum tan θ / tan α within the 3 % of ρ_u vs ρ_v sampling at the base
    assert!((rep.max_ratio / bound - 1.0).abs() < 0.05 && rep.clamped == 0, "{rep:?}");
    assert!(rep.x_residual < 1e-6, "{rep:?}");
    assert!(rest < 1e-10, "layer moved: {rest:e}");
    let (paper, slide) = run(InterfaceYield::Paper, true);
    let paper = paper.unwrap();
    println!("paper band: ratio {:.4}, clamped {}, max speed {slide:.2e}", paper.max_ratio, paper.clamped);
    assert!(paper.max_ratio > 1.0 && paper.clamped > 0, "{paper:?}");
    assert!(slide > 1e-4, "paper band held: {slide:e}");
    let (_, fall) = run(InterfaceYield::DensitySupport, false);
    println!("from Σ = 0: max speed {fall:.3} m/s (free fall {:.3})", 9.81 * th.sin() * 0.2);
    assert!(fall > 0.1, "from Σ = 0: {fall}");
    // proximal restarts of the anchor approach eq. (11) from Σ = 0, slowly (measured 0.37 / 0.12
    // / 0.036 m/s with 10 / 100 / 1000 restarts per step)
    let (_, r10) = run_r(InterfaceYield::DensitySupport, false, 10);
    let (_, r100) = run_r(InterfaceYield::DensitySupport, false, 100);
    println!("from Σ = 0 with 10 / 100 proximal restarts: {r10:.3} / {r100:.3} m/s");
    assert!(r100 < 0.5 * r10 && r10 < 0.7 * fall, "restarts: {fall} {r10} {r100}");
}

/// `balance_plastic_stress` needs a projected yield stress: a Newtonian model names `rheology`.
#[test]
fn balance_plastic_stress_rejects_a_law_without_yield_stress() {
    let grid = Grid::new(4, 4, 1.0, 1.0).unwrap();
    let cfg = ModelConfig::single_phase(grid, BoundaryConditions::uniform(VelocityBc::NoSlip), Material { density: 1.0, viscosity: 1.0 });
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    match m.balance_plastic_stress() {
        Err(Error::InvalidParameter { name, allowed, .. }) => {
            assert_eq!(name, "rheology");
            assert!(allowed.contains("projection"), "{allowed}");
        }
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
}

/// The wall normal stress of eq. (8) (`WallNormalStress::Total`, −σ_n = p − T_nn): in a uniform
/// extension u = a x (D_xx = a = −D_yy) with a uniform pressure P, viscosity η and plastic
/// stress τΣ_xx = S, T_xx = 2ηa + S is uniform, so the base (T_nn = T_yy = −T_xx) carries
/// −σ_n = P + T_xx and the back wall (T_nn = T_xx) carries P − T_xx; with `Pressure` both carry
/// P. The fields are linear, so the walls' linear extrapolation is exact (round-off bound).
#[test]
fn total_wall_normal_stress_adds_the_normal_deviatoric_stress() {
    use granrs_core::grid::{Field, Location};
    use granrs_core::rheology::InterfaceYield;
    use granrs_core::walls::{CoulombWalls, NormalStress};
    let grid = Grid::new(8, 6, 0.8, 0.6).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::FreeSlip).with(Side::Left, VelocityBc::Coulomb).with(Side::Bottom, VelocityBc::Coulomb);
    let (p0, eta, a, sxx, tau) = (300.0, 0.1, 50.0, 0.4, 100.0);
    let p = Field::from_fn(&grid, Location::Centre, |_, _| p0);
    let phi = Field::from_fn(&grid, Location::Centre, |_, _| 1.0);
    let u = Field::from_fn(&grid, Location::XFace, |x, _| a * x);
    let eta_c = Field::from_fn(&grid, Location::Centre, |_, _| eta);
    let tau_c = Field::from_fn(&grid, Location::Centre, |_, _| tau);
    let sigma = Field::from_fn(&grid, Location::Centre, |_, _| sxx);
    let tan_b = 15f64.to_radians().tan();
    let txx = 2.0 * eta * a + tau * sxx;
    for (total, base, back) in [(false, p0, p0), (true, p0 + txx, p0 - txx)] {
        let mut walls = CoulombWalls::new(&grid, &bc, true);
        let tnn = total.then_some(NormalStress { u: &u, eta_c: &eta_c, plastic: Some((&tau_c, &sigma)), dx: grid.dx });
        walls.set_friction(&p, 0.0, tnn, &phi, tan_b, None, InterfaceYield::Paper, &grid);
        for (side, expected) in [(Side::Bottom, base), (Side::Left, back)] {
            let (_, tau_b) = walls.side(side).unwrap();
            // the unknown tangential faces (the corner faces are fixed by the other wall)
            for &t in &tau_b[1..tau_b.len() - 1] {
                assert!((t - tan_b * expected).abs() < 1e-12 * tan_b * expected, "{side:?} total={total}: {t} vs {}", tan_b * expected);
            }
        }
    }
}

/// The creeping Bingham cavity of the validation (unit box, lid speed 1, η = ρ = 1, Bn = 5).
fn bingham_cavity(n: usize, dt: f64, theta: f64, anderson: usize, rotational: bool, threads: usize) -> TwoPhaseModel {
    let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Top, VelocityBc::Velocity { normal: 0.0, tangential: 1.0 });
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1.0, viscosity: 1.0 });
    cfg.convection = false;
    cfg.time.fixed_dt = Some(dt);
    cfg.time.cfl_abort = 100.0;
    cfg.rotational_pressure = rotational;
    cfg.threads = threads;
    cfg.rheology = RheologyConfig::new(RheologyLaw::Bingham { yield_stress: 5.0 });
    cfg.rheology.theta = theta;
    cfg.rheology.picard_tol = 1e-11;
    cfg.rheology.picard_max_iterations = 5000;
    cfg.rheology.anderson_depth = anderson;
    TwoPhaseModel::new(cfg).unwrap()
}

fn max_diff(a: &granrs_core::grid::Field, b: &granrs_core::grid::Field) -> f64 {
    a.slice().iter().zip(b.slice()).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn anderson_acceleration_keeps_the_fixed_point_with_fewer_iterations() {
    // rheology/anderson.rs: same fixed point of eq. (12), fewer predictor solves. θ = 0.25: the
    // plain iteration contracts like 0.75 per iteration (picard_ratio_is_one_minus_theta), so at
    // the tolerance 1e-11 each Σ is within 1e-11/0.25 = 4e-11 of the fixed point, and the
    // velocities of the two runs must agree far below 1e-8 after three steps (measured 1.5e-12,
    // with 77 Anderson against 225 plain iterations).
    let (mut plain, mut aa) = (bingham_cavity(32, 0.05, 0.25, 0, false, 1), bingham_cavity(32, 0.05, 0.25, 5, false, 1));
    let (mut it_plain, mut it_aa) = (0, 0);
    for _ in 0..3 {
        it_plain += plain.step().unwrap().picard_iterations;
        it_aa += aa.step().unwrap().picard_iterations;
    }
    let du = max_diff(&plain.u, &aa.u).max(max_diff(&plain.v, &aa.v));
    println!("Picard iterations over 3 steps: plain {it_plain}, Anderson(5) {it_aa}; max |Δu| {du:.2e}");
    assert!(du < 1e-8, "Anderson changed the solution by {du:e}");
    assert!((it_aa as f64) < 0.6 * it_plain as f64, "Anderson {it_aa} vs plain {it_plain} iterations");
}

#[test]
fn anderson_acceleration_is_thread_independent() {
    // the mixing's reductions are serial, and the Picard map is (serial == parallel)
    let (mut one, mut two) = (bingham_cavity(24, 0.05, 0.25, 5, true, 1), bingham_cavity(24, 0.05, 0.25, 5, true, 2));
    for _ in 0..3 {
        let (a, b) = (one.step().unwrap(), two.step().unwrap());
        assert_eq!(a.picard_iterations, b.picard_iterations);
    }
    assert_eq!(max_diff(&one.u, &two.u), 0.0);
    assert_eq!(max_diff(&one.p, &two.p), 0.0);
}

#[test]
fn anderson_depth_out_of_range_is_named() {
    let mut m = RheologyConfig::new(RheologyLaw::Bingham { yield_stress: 1.0 });
    m.anderson_depth = granrs_core::rheology::anderson::MAX_ANDERSON_DEPTH + 1;
    match m.validate() {
        Err(Error::InvalidParameter { name, allowed, .. }) => {
            assert_eq!(name, "anderson_depth");
            assert!(allowed.contains("[0, 20]"), "{allowed}");
        }
        other => panic!("expected an anderson_depth error, got {other:?}"),
    }
}

/// The layer of `sliding_layer` on a 20° slope (between α_b = 15° and α = 27°), started from
/// the balanced plastic tensor, sliding on its Coulomb base for 0.2 s with the step `dt`: its
/// energy budget.
fn sliding_layer_budget(dt: f64) -> granrs_core::diagnostics::EnergyBudget {
    let mut cfg = sliding_layer(20.0, VelocityBc::FreeSlip, dt);
    cfg.rheology.picard_tol = 1e-8;
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    m.initialise_pressure().unwrap();
    m.balance_plastic_stress().unwrap();
    while m.time < 0.2 - 1e-9 {
        m.step().unwrap();
    }
    m.energy_budget()
}

/// The energy budget (diagnostics/energy.rs) closes on the sliding layer: the work of gravity
/// goes into kinetic energy, basal friction and the plastic stress. The stress balanced at rest
/// must relax to the sliding state, and the θ-relaxed Picard fixed point does it like an elastic
/// body (docs/validation.md): it gives energy back (a negative plastic work), and the relaxation
/// rings at a frequency ∝ 1/δt, so the residual does not fall with δt here (measured 3.6e-4 and
/// 7.2e-4 of W_g at δt = 1 and 0.5 ms; the smooth Stokes vortex shows the second order). A wrong
/// sign or scale of any term would leave a residual of the size of that term (friction: 80 % of
/// W_g).
#[test]
fn energy_budget_of_a_sliding_layer_closes() {
    for dt in [1e-3, 5e-4] {
        let x = sliding_layer_budget(dt);
        println!("{x:?}");
        let wall: f64 = x.wall_work.iter().sum();
        assert!(x.gravity_work > 0.0 && wall > 0.5 * x.gravity_work, "friction takes most of gravity's work: {x:?}");
        assert!(x.plastic_negative_work < 0.0, "the relaxed stress gives energy back");
        assert!(x.residual.abs() < 2e-3 * x.gravity_work, "residual {} of W_g {}", x.residual, x.gravity_work);
    }
}

/// `YieldPressure::SurfaceAir`: the yield stress and the base's friction read p − p_s, p_s the
/// mean air pressure just outside the band, so a uniform shift of pⁿ (another gauge) leaves τ
/// and τ_b unchanged to round-off; with the paper's `Absolute` they move by tan(α) × the shift
/// where the material is wholly granular. The layer of `interface_yield_sets_the_coulomb_ratio_of_the_band`.
#[test]
fn surface_air_yield_pressure_does_not_depend_on_the_gauge() {
    use granrs_core::rheology::YieldPressure;
    let (nx, ny) = (4, BAND_LAYER_NY);
    let ly = ny as f64 * BAND_LAYER_H;
    let shift = 50.0; // Pa, against p ≈ 1450 × 9.81 × 0.02 ≈ 280 Pa at the base
    let run = |yp: YieldPressure, c: f64| {
        let mut m = band_layer(8.3, |cfg| cfg.rheology.yield_pressure = yp);
        for j in 0..ny {
            for i in 0..nx {
                let v = m.p.at(i as isize, j as isize) + c;
                m.p.set(i, j, v);
            }
        }
        m.step().unwrap();
        let tau: Vec<f64> = (0..ny as isize).map(|j| m.yield_stress().unwrap().at(1, j)).collect();
        let (_, tau_b) = m.wall_friction(Side::Bottom).unwrap();
        (tau, tau_b[2], m.phi.at(1, 0))
    };
    let tan_a = 27f64.to_radians().tan();
    let (t0, b0, _) = run(YieldPressure::SurfaceAir, 0.0);
    let (t1, b1, _) = run(YieldPressure::SurfaceAir, shift);
    let scale = t0.iter().fold(0.0f64, |a, &b| a.max(b));
    let diff = t0.iter().zip(&t1).map(|(a, b)| (a - b).abs()).fold(0.0f64, f64::max);
    println!("surface-air: max |Δτ| = {diff:.2e} Pa of {scale:.1} Pa; τ_b {b0:.6} / {b1:.6}");
    assert!(diff < 1e-9 * scale, "τ moved by {diff} Pa under a {shift} Pa gauge shift");
    assert!((b0 - b1).abs() < 1e-9 * b0, "τ_b {b0} against {b1}");
    // the paper's form: τ at the base moves by tan α × 50 Pa = 25.5 Pa
    let (a0, ab0, _) = run(YieldPressure::Absolute, 0.0);
    let (a1, ab1, _) = run(YieldPressure::Absolute, shift);
    assert!(((a1[0] - a0[0]) - tan_a * shift).abs() < 1e-6 * scale, "absolute: Δτ at the base {}", a1[0] - a0[0]);
    assert!(ab1 > ab0 + 0.2 * shift, "absolute: τ_b {ab0} → {ab1}");
    // under the top gauge the air under the lid is at p = 0 and at the surface at its own weight
    // above (ρ_f g × at most ly = 0.78 Pa): both forms differ by at most tan α times that
    let d = t0.iter().zip(&a0).map(|(a, b)| (a - b).abs()).fold(0.0f64, f64::max);
    assert!(d > 0.0 && d < tan_a * 1.0 * 9.81 * ly, "surface-air and absolute differ by {d} Pa at the top gauge");
}

/// `RheologyConfig::r_neighbourhood`: the neighbourhood of the default local r sets how soft the
/// relaxed fixed point of eq. (12) is under the free surface. A D-P layer 4.2 cells deep
/// (h = 2.5 mm) slides at 0.5 m/s on the Coulomb base (α_b = 15°) under air, δt = 1 ms. A rigid
/// block stops at t_s = v₀/(g tan α_b) = 0.190 s (the plastic layer, whose rows are held by the
/// yield stress, stops with its base). With w = 2 every granular cell is within two cells of an
/// air face, takes its k (~1600 times the bulk value) and a 1600 times smaller r: Σ builds up by
/// only (r/θ)D per step, and the rows under the surface keep sliding (measured: 0.128 m/s at
/// 0.27 s, a quarter of v₀). With w = 0 the whole layer stops with its base (4.0e-3 m/s, under
/// 1 % of v₀: what is left is the elastic ringing of the relaxed fixed point).
#[test]
fn r_neighbourhood_sets_how_soft_the_band_under_the_surface_is() {
    let depth = 4.2;
    let run = |w: usize| -> (f64, f64) {
        let mut m = band_layer(depth, |cfg| {
            cfg.rheology.theta = 0.8;
            cfg.rheology.picard_tol = 1e-6;
            cfg.rheology.r_neighbourhood = w;
        });
        let (nxu, ny) = (m.u.nx, m.u.ny);
        for j in 0..ny {
            if (j as f64 + 0.5) < depth {
                for i in 0..nxu {
                    m.u.set(i, j, 0.5);
                }
            }
        }
        for _ in 0..270 {
            m.step().unwrap();
        }
        // the largest speed of the granular rows (Φ > 0 at the cell centre), base row apart
        let (mut base, mut rest) = (0.0f64, 0.0f64);
        for j in 0..ny {
            if m.phi.at(1, j as isize) > 0.0 {
                let s = m.u.at(1, j as isize).abs();
                if j == 0 {
                    base = s
                } else {
                    rest = rest.max(s)
                }
            }
        }
        (base, rest)
    };
    let (base2, rows2) = run(2);
    let (base0, rows0) = run(0);
    println!("at t = 0.27 s: w = 2: base row {base2:.3e}, rows above {rows2:.3e} m/s; w = 0: {base0:.3e}, {rows0:.3e} m/s");
    // the analytic block stops at 0.19 s: by 0.27 s the base row is at rest either way
    assert!(base0 < 0.01 && base2 < 0.01, "base rows {base0} {base2}");
    // w = 2: the rows under the surface slide on, 80 ms after the base stopped (0.128 m/s)
    assert!(rows2 > 0.05, "w = 2 rows {rows2}");
    // w = 0: the layer stops as one body, to the ringing (4.0e-3 m/s); 0.02 is 4 % of v₀,
    // and 6 times below the w = 2 rows
    assert!(rows0 < 0.02, "w = 0 rows {rows0}");
}

#[test]
fn r_neighbourhood_out_of_range_is_named() {
    let mut r = RheologyConfig::new(RheologyLaw::DruckerPrager { friction_angle: 27.0 });
    r.r_neighbourhood = granrs_core::rheology::plastic::MAX_R_NEIGHBOURHOOD + 1;
    match r.validate() {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "r_neighbourhood"),
        other => panic!("expected an r_neighbourhood error, got {other:?}"),
    }
}

/// `SigmaLocation::Centres`: Σ_xy at centres travels in the checkpoint (a restart is bit
/// identical), two threads give the serial answer bit for bit, and the combinations it does not
/// support are refused by name.
#[test]
fn centred_plastic_tensor_restarts_and_threads_exactly() {
    let build = |threads: usize| {
        let mut cfg = bingham_cavity(16, 0.05, 0.5, 0, false, threads).config().clone();
        cfg.rheology.sigma_location = SigmaLocation::Centres;
        cfg.rheology.picard_tol = 1e-9;
        TwoPhaseModel::new(cfg).unwrap()
    };
    let (mut a, mut two) = (build(1), build(2));
    for _ in 0..4 {
        let (x, y) = (a.step().unwrap(), two.step().unwrap());
        assert_eq!(x.picard_iterations, y.picard_iterations);
    }
    assert_eq!(max_diff(&a.u, &two.u), 0.0);
    let state = a.checkpoint();
    assert!(state.iter().any(|(n, _)| n == "sigma_xy_centre"));
    let mut b = build(1);
    b.restore(&state).unwrap();
    for _ in 0..4 {
        a.step().unwrap();
        b.step().unwrap();
    }
    assert_eq!(a.u.slice(), b.u.slice());
    assert_eq!(a.plastic_tensor().unwrap().1.slice(), b.plastic_tensor().unwrap().1.slice());
    // the nodal equivalent of Σ_xy carries the stress (the lid drags the yielded layer under it:
    // |Σ| = 1 there), and with a uniform yield stress it is the plain average of |Σ_xy,c| ≤ 1
    let (_, sxy) = a.plastic_tensor().unwrap();
    let largest = sxy.slice().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(largest > 0.5 && largest <= 1.0 + 1e-12, "largest nodal |Σ_xy| {largest}");
    let mut r = RheologyConfig::new(RheologyLaw::Bingham { yield_stress: 1.0 });
    r.sigma_location = SigmaLocation::Centres;
    r.anderson_depth = 3;
    match r.validate() {
        Err(Error::InvalidParameter { name, allowed, .. }) => {
            assert_eq!(name, "anderson_depth");
            assert!(allowed.contains("centres"), "{allowed}");
        }
        other => panic!("expected an anderson_depth error, got {other:?}"),
    }
    assert_eq!(SigmaLocation::from_name("centres"), Some(SigmaLocation::Centres));
    assert_eq!(SigmaLocation::from_name("nodes"), None);
}

/// The layer of `sliding_layer` (D-P, H = 0.1 m) in a channel W = 0.1 m whose side walls have
/// the friction angle α_w = 15° (`walls/side.rs`), on a frictionless base under an open top
/// (p = 0 there). The walls resist with (2/W) tan(α_w) ∫ p dy = tan(α_w) ρ g cos β H²/W per unit
/// length (p hydrostatic, and the midpoint sum of a linear p is exact), so the layer moves as one
/// block at a = g (sin β − tan(α_w) cos β H/W) when that is positive (β = 20°: 0.884 m/s²; the
/// internal shear this needs is at most 0.27 p, under tan 27° p), and holds otherwise (β = 10°).
fn side_wall_layer(slope: f64, threads: usize) -> TwoPhaseModel {
    let mut cfg = sliding_layer(slope, VelocityBc::Outflow, 1e-3);
    cfg.bc = cfg.bc.with(Side::Bottom, VelocityBc::FreeSlip);
    cfg.rheology.wall_friction_angle = None;
    cfg.rheology.side_walls = Some(SideWalls { width: 0.1, friction_angle: 15.0 });
    cfg.threads = threads;
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    m.initialise_pressure().unwrap();
    m
}

#[test]
fn side_walls_slow_a_sliding_layer_at_their_friction_rate_and_hold_it_below() {
    let n = 32;
    let s = 20f64.to_radians();
    let exact = 9.81 * (s.sin() - 15f64.to_radians().tan() * s.cos() * 0.1 / 0.1);
    let mut m = side_wall_layer(20.0, 1);
    let a = layer_acceleration(&mut m);
    let spread = (0..n).map(|j| m.u.at(2, j as isize)).fold(f64::NEG_INFINITY, f64::max) - (0..n).map(|j| m.u.at(2, j as isize)).fold(f64::INFINITY, f64::min);
    let b = m.energy_budget();
    println!("20°: acceleration {a:.5} exact {exact:.5}, spread of u over the depth {spread:.2e}; budget {b:?}");
    // the block's mean momentum balance is exact; 1 % allows the Picard tolerance (1e-9) and
    // the pressure solve (1e-12) with a margin of many orders
    assert!((a / exact - 1.0).abs() < 1e-2, "acceleration {a} against {exact}");
    // (u varies over the depth by 0.065 m/s at 0.2 s: the elastic ringing of the relaxed fixed
    // point of eq. (12) started from Σ = 0, as on the Coulomb base; measured, it reverses every
    // 0.05 s and is ten times smaller at δt = 0.1 ms. The block's mean motion does not see it.)
    // the walls' work is what the block does not gain: W_g − E_k, closed to the trapezoid's error
    assert!(b.side_wall_work > 0.0 && b.residual.abs() < 1e-3 * b.side_wall_work, "{b:?}");
    // below the walls' friction the layer holds
    let mut held = side_wall_layer(10.0, 1);
    for _ in 0..200 {
        held.step().unwrap();
    }
    let umax = held.u.max_abs();
    println!("10°: largest speed after 0.2 s {umax:.2e} m/s");
    assert!(umax < 1e-4, "the 10° layer slides at {umax}");
    // serial == parallel, and s travels in the checkpoint
    let (mut one, mut two) = (side_wall_layer(20.0, 1), side_wall_layer(20.0, 2));
    for _ in 0..5 {
        one.step().unwrap();
        two.step().unwrap();
    }
    assert_eq!(max_diff(&one.u, &two.u), 0.0);
    let state = one.checkpoint();
    assert!(state.iter().any(|(k, _)| k == "side_wall_s_u") && state.iter().any(|(k, _)| k == "side_wall_s_v"));
    // bad channels are named
    let mut r = RheologyConfig::new(RheologyLaw::DruckerPrager { friction_angle: 27.0 });
    r.side_walls = Some(SideWalls { width: 0.0, friction_angle: 15.0 });
    match r.validate() {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "side_walls.width"),
        other => panic!("expected a side_walls.width error, got {other:?}"),
    }
    r.side_walls = Some(SideWalls { width: 0.1, friction_angle: 90.0 });
    match r.validate() {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "side_walls.friction_angle"),
        other => panic!("expected a side_walls.friction_angle error, got {other:?}"),
    }
}
