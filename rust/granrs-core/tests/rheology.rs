//! Rheology: bi-projection (plastic projection + Picard), Coulomb walls, regularised laws.

use granrs_core::grid::{BoundaryConditions, Field, Grid, Location, Side, VelocityBc};
use granrs_core::models::{Material, ModelConfig, TwoPhaseModel};
use granrs_core::rheology::{RheologyConfig, RheologyLaw};

/// Bingham plane Poiseuille flow (validation-data §3): channel 0 < y < 2 (half-width h = 1),
/// body force G = 1 along x, μ = ρ = 1, no-slip walls, outflow sides (p = 0, x-invariant flow).
fn poiseuille(n: usize, tau_y: f64, theta: f64) -> (TwoPhaseModel, f64) {
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
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    let mut change = f64::INFINITY;
    for _ in 0..400 {
        let before = m.u.clone();
        let info = m.step().unwrap();
        change = (0..n).map(|j| (m.u.at(2, j as isize) - before.at(2, j as isize)).abs()).fold(0.0, f64::max);
        if m.step_count % 20 == 0 {
            println!("step {} picard {} inc {:.2e} change {:.2e}", m.step_count, info.picard_iterations, info.picard_increment, change);
        }
        if change < 1e-13 {
            break;
        }
    }
    (m, change)
}

fn exact_poiseuille(y: f64, tau_y: f64) -> f64 {
    let eta = (y - 1.0).abs();
    let e0 = tau_y;
    if eta <= e0 {
        0.5 * (1.0 - e0).powi(2)
    } else {
        0.5 * ((1.0 - eta * eta) - 2.0 * e0 * (1.0 - eta))
    }
}

#[test]
fn poiseuille_bingham_plug() {
    for n in [16, 32, 64] {
        let (m, change) = poiseuille(n, 0.25, 0.5);
        let g = m.grid().clone();
        let (mut e2, mut n2, mut umax) = (0.0, 0.0, 0.0f64);
        for j in 0..n {
            let y = g.yc(j as isize);
            let ex = exact_poiseuille(y, 0.25);
            let u = m.u.at(2, j as isize);
            e2 += (u - ex).powi(2);
            n2 += ex * ex;
            umax = umax.max(u);
        }
        println!("n = {n}: steps {} change {change:.2e} u_max {umax:.6} (exact 0.28125) l2 {:.3e}", m.step_count, (e2 / n2).sqrt());
    }
}

#[test]
fn dbg_newtonian_outflow_channel() {
    let n = 16;
    let dy = 2.0 / n as f64;
    let grid = Grid::new(4, n, 4.0 * dy, 2.0).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Left, VelocityBc::Outflow).with(Side::Right, VelocityBc::Outflow);
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1.0, viscosity: 1.0 });
    cfg.gravity = [1.0, 0.0];
    cfg.time.fixed_dt = Some(0.5);
    cfg.time.cfl_abort = 100.0;
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    for _ in 0..5 {
        let info = m.step();
        println!("{:?}", info.map(|i| (i.viscous, i.max_speed)));
    }
}
