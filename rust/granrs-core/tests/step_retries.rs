//! Rejected steps (`TimeConfig::step_retries`, time_stepping/clock.rs): a step whose Picard
//! iteration does not converge, or whose CFL number ends above `cfl_abort`, is undone and retaken
//! with δt halved.

use granrs_core::models::{StateEntry, TwoPhaseModel};
use granrs_core::time_stepping::{StepInfo, DT_CEILING_RECOVERY};
use granrs_core::Error;

#[path = "common/channel.rs"]
mod channel;
use channel::bingham_channel;

/// Bingham plane Poiseuille flow started from rest by the body force G = 1 (channel 0 < y < 2,
/// ρ = 1, μ = 0.01, τ_y = 0.2, outflow sides), adaptive δt growing 2× per step, and a constant
/// r = 0.5 above the contraction bound of the larger steps (rτk ≤ 2(1 − θ) holds for
/// δt ≲ 0.04 here, k = 2S/(a₀ρ/δt + 4μS)): the Picard iteration slows as δt grows.
fn accelerating_channel(cap: usize, retries: usize, fixed_dt: Option<f64>) -> TwoPhaseModel {
    let mut cfg = bingham_channel(cap, retries, fixed_dt);
    cfg.time.cfl = 1.0;
    cfg.time.max_growth = 2.0;
    TwoPhaseModel::new(cfg).unwrap()
}

/// Steps `a` until a step is retaken (at most `max` steps, `each` sees every step): that step's
/// index and its report. The ceiling it leaves is half the rejected δt, grown once by the
/// recovery factor.
fn first_retaken_step(a: &mut TwoPhaseModel, max: usize, mut each: impl FnMut(usize, &StepInfo)) -> (usize, StepInfo) {
    for n in 0..max {
        let s = a.step().unwrap();
        each(n, &s);
        if s.retries > 0 {
            assert!((a.dt_ceiling - s.dt * DT_CEILING_RECOVERY).abs() < 1e-15 * s.dt);
            return (n, s);
        }
    }
    panic!("no step was retaken in {max} steps");
}

/// Steps `b` (a model without retries) `n` times, then the state before its step n + 1.
fn state_after(b: &mut TwoPhaseModel, n: usize) -> Vec<StateEntry> {
    for _ in 0..n {
        b.step().unwrap();
    }
    b.checkpoint()
}

/// Given the halved step `s.dt` from the state `before`, the model `c` without retries takes
/// exactly the step `a` retook: the same δt, u, v, p, Σ and clock, bit for bit.
fn assert_takes_the_retaken_step(mut c: TwoPhaseModel, before: &[StateEntry], s: &StepInfo, a: &TwoPhaseModel) {
    c.restore(before).unwrap();
    c.dt_ceiling = s.dt;
    let sc = c.step().unwrap();
    assert_eq!(sc.dt.to_bits(), s.dt.to_bits());
    assert_eq!(c.u.slice(), a.u.slice());
    assert_eq!(c.v.slice(), a.v.slice());
    assert_eq!(c.p.slice(), a.p.slice());
    assert_eq!(c.plastic_tensor().unwrap().1.slice(), a.plastic_tensor().unwrap().1.slice());
    assert_eq!(c.time.to_bits(), a.time.to_bits());
}

/// A step that fails only at the larger δt is retaken at half of it, and the retaken step is
/// bit for bit the step a model without retries takes when given that δt.
#[test]
fn a_rejected_step_is_retaken_with_half_the_step() {
    // without a cap the 4th step (δt = 0.251) needs 96 iterations, the others 19–34: a cap of 60
    // rejects it, and the retaken step at δt = 0.125 converges
    let mut a = accelerating_channel(60, 3, None);
    let mut dts = Vec::new();
    let (n, s) = first_retaken_step(&mut a, 8, |_, s| dts.push(s.dt));
    assert_eq!(s.retries, 1);
    assert!(s.picard_iterations <= 60);
    assert!(s.dt < 0.6 * 2.0 * dts[n - 1], "δt {} after {}", s.dt, dts[n - 1]);
    // the same history without retries: the same steps, then that step fails at the full δt
    let mut b = accelerating_channel(60, 0, None);
    let before = state_after(&mut b, n);
    match b.step() {
        Err(Error::Simulation { what, .. }) => assert!(what.starts_with("Picard iteration") && !what.contains("retaken"), "{what}"),
        other => panic!("expected the Picard failure, got {other:?}"),
    }
    // given the halved step, a model without retries takes exactly the retaken step
    assert_takes_the_retaken_step(accelerating_channel(60, 0, None), &before, &s, &a);
}

/// When every attempt fails, the error says how often the step was retaken and the model is left
/// at its last accepted step; a fixed δt is never retaken.
#[test]
fn a_step_that_fails_at_every_step_size_is_reported_and_undone() {
    let mut m = accelerating_channel(2, 2, None);
    match m.step() {
        Err(Error::Simulation { what, step, .. }) => {
            assert_eq!(step, 1);
            assert!(what.contains("after 2 iterations") && what.ends_with("(the step was retaken 2 times with δt halved each time)"), "{what}");
        }
        other => panic!("expected the Picard failure, got {other:?}"),
    }
    assert_eq!((m.step_count, m.time, m.dt_prev), (0, 0.0, None));
    assert!(m.u.slice().iter().all(|&x| x == 0.0), "the failed step was not undone");
    let mut f = accelerating_channel(2, 2, Some(0.05));
    match f.step() {
        Err(Error::Simulation { what, .. }) => assert!(what.contains("after 2 iterations") && !what.contains("retaken"), "{what}"),
        other => panic!("expected the Picard failure, got {other:?}"),
    }
}

/// The channel with a Picard cap it always meets, an adaptive δt at C_cfl = 1 growing 2× per step
/// and the guard `cfl_abort` = `guard`. The flow accelerates from rest through each step: the CFL
/// number after the step is 0.01, 0.06, 0.28, 0.995 in the first four steps, and 0.95–0.99 after.
fn guarded_channel(guard: f64, retries: usize) -> TwoPhaseModel {
    let mut cfg = bingham_channel(1000, retries, None);
    cfg.time.cfl = 1.0;
    cfg.time.max_growth = 2.0;
    cfg.time.cfl_abort = guard;
    TwoPhaseModel::new(cfg).unwrap()
}

/// A step whose CFL number ends above `cfl_abort` is retaken with δt halved, like a Picard
/// failure: every accepted step keeps the guard, the retaken step is the step a model without
/// retries takes at that δt, and without retries the same step stops the run with the CFL error.
#[test]
fn a_step_past_the_cfl_guard_is_retaken_with_half_the_step() {
    // the 4th step ends at CFL 0.995 (guard lifted): a guard of 0.98 refuses it
    let guard = 0.98;
    let mut a = guarded_channel(guard, 3);
    let (n, s) = first_retaken_step(&mut a, 20, |n, s| assert!(s.cfl <= guard, "step {n}: CFL {} above the guard", s.cfl));
    let mut b = guarded_channel(guard, 0);
    let before = state_after(&mut b, n);
    match b.step() {
        Err(Error::Simulation { what, location, .. }) => {
            assert!(what.starts_with("CFL number") && what.contains(&format!("cfl_abort = {guard}")) && !what.contains("retaken"), "{what}");
            assert!(location.is_some());
        }
        other => panic!("expected the CFL error, got {other:?}"),
    }
    assert_eq!(b.step_count as usize, n, "the refused step was not undone");
    assert_takes_the_retaken_step(guarded_channel(guard, 0), &before, &s, &a);
    // a guard no halving meets: reported with its retries, the model at its last accepted step
    let mut d = guarded_channel(1e-6, 2);
    match d.step() {
        Err(Error::Simulation { what, step, .. }) => {
            assert_eq!(step, 1);
            assert!(what.starts_with("CFL number") && what.ends_with("(the step was retaken 2 times with δt halved each time)"), "{what}");
        }
        other => panic!("expected the CFL error, got {other:?}"),
    }
    assert_eq!((d.step_count, d.time), (0, 0.0));
}
