//! A step that fails leaves the model at its last accepted state, bit for bit, and a blow-up is
//! reported with its step, time and cell (models/step.rs, stage 7).

use granrs_core::grid::{BoundaryConditions, Field, Grid, Location, VelocityBc};
use granrs_core::models::{Material, ModelConfig, TwoPhaseModel};
use granrs_core::time_stepping::SPEED_BOUND;
use granrs_core::Error;

#[path = "common/channel.rs"]
mod channel;
use channel::bingham_channel;

/// The checkpoint entries as bit patterns (NaN marks "no previous step" and compares equal).
fn bits(m: &TwoPhaseModel) -> Vec<(String, Vec<u64>)> {
    m.checkpoint().into_iter().map(|(n, d)| (n, d.iter().map(|x| x.to_bits()).collect())).collect()
}

/// The Bingham channel of tests/step_retries.rs (common/channel.rs) with a Picard cap of 60; the
/// test lowers the cap so that no later step meets it.
fn channel(fixed_dt: Option<f64>, retries: usize) -> TwoPhaseModel {
    TwoPhaseModel::new(bingham_channel(60, retries, fixed_dt)).unwrap()
}

#[test]
fn a_failed_step_leaves_the_last_accepted_state_bit_for_bit() {
    for (fixed_dt, retries) in [(Some(0.05), 0), (None, 0), (None, 2)] {
        let mut m = channel(fixed_dt, retries);
        // three accepted steps, then the cap is lowered so that every later step fails
        for _ in 0..3 {
            m.step().unwrap();
        }
        let before = bits(&m);
        // the same state in a model whose Picard cap (2 iterations) no step meets
        let mut cfg = m.config().clone();
        cfg.rheology.picard_max_iterations = 2;
        let mut f = TwoPhaseModel::new(cfg).unwrap();
        f.restore(&m.checkpoint()).unwrap();
        assert_eq!(bits(&f), before);
        let first = f.step().expect_err("a cap of 2 Picard iterations fails");
        assert!(matches!(first, Error::Simulation { step: 4, .. }), "{first:?}");
        assert_eq!(bits(&f), before, "dt {fixed_dt:?}, retries {retries}: the failed step left the state changed");
        // trying again starts from the restored state: without retries it fails exactly as before
        // (with retries the δt ceiling the rejections left makes the next try smaller)
        let second = f.step().expect_err("fails again");
        if retries == 0 {
            assert_eq!(first, second);
        }
        assert_eq!(bits(&f), before);
    }
}

/// A Taylor–Green vortex of amplitude U in a free-slip unit box under gravity: far above the
/// speed bound when U ≫ SPEED_BOUND √(2|g|(Lx + Ly)).
fn vortex(amplitude: f64) -> TwoPhaseModel {
    let n = 16;
    let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::FreeSlip);
    let mut cfg = ModelConfig::single_phase(grid.clone(), bc, Material { density: 1.0, viscosity: 1e-6 });
    cfg.gravity = [0.0, -9.81];
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    let pi = std::f64::consts::PI;
    m.u.assign(&Field::from_fn(&grid, Location::XFace, |x, y| amplitude * (pi * x).sin() * (pi * y).cos()));
    m.v.assign(&Field::from_fn(&grid, Location::YFace, |x, y| -amplitude * (pi * x).cos() * (pi * y).sin()));
    m.u_prev.assign(&m.u);
    m.v_prev.assign(&m.v);
    m.fields_changed();
    m
}

#[test]
fn a_collapsing_step_is_a_blow_up_naming_its_cell() {
    // reference speed √(2 · 9.81 · 2) = 6.26 m/s, bound 626 m/s
    let u_ref = (2.0f64 * 9.81 * 2.0).sqrt();
    // below the bound: steps are taken
    let mut slow = vortex(0.5 * SPEED_BOUND * u_ref);
    for _ in 0..3 {
        slow.step().unwrap();
    }
    // above it: the first step is refused, the state kept
    let mut fast = vortex(2.0 * SPEED_BOUND * u_ref);
    let before = bits(&fast);
    match fast.step() {
        Err(Error::Simulation { what, step, time, location: Some((i, j)) }) => {
            assert!(what.contains("the time step collapsed"), "{what}");
            assert_eq!(step, 1);
            assert!(time > 0.0);
            // the fastest faces of the vortex: u on the line x = 1/2 (face i = 8) in the first or
            // last row of cells, where |cos(πy)| is largest
            assert!(i == 8 && (j == 0 || j == 15), "cell ({i}, {j})");
        }
        other => panic!("expected a blow-up, got {other:?}"),
    }
    assert_eq!(bits(&fast), before);
}
