//! The adaptive step's rule (`TwoPhaseModel::cfl_dt`, time_stepping/clock.rs).
//!
//! 1. Without `cfl_light` the step is `stable_dt` with C_cfl at the largest speeds anywhere.
//! 2. With `cfl_light` the faces next to a cell with Φ > −LIGHT_CFL_BAND·h keep C_cfl and the
//!    light phase beyond them is held to `cfl_light` only: a fast face in the air far from the
//!    grains sets the step through `cfl_light`, the same speed within the band through C_cfl.
//!    The rule is the same on one thread and two.
//! 3. `cfl_light = cfl` is the plain rule: the same steps, bit for bit.
//! 4. A `cfl_light` above `cfl_abort` (every step at it would be rejected) is refused, naming it.

use granrs_core::error::Error;
use granrs_core::exec::Exec;
use granrs_core::models::TwoPhaseModel;
use granrs_core::time_stepping::{stable_dt, LIGHT_CFL_BAND};

mod common;
use common::{column_config, released_column};

const NX: usize = 48;
const NY: usize = 16;

/// The miniature column (0.1 m × 0.2 m of beads in a 1.35 m × 0.45 m channel, h = 28 mm) at
/// rest, with `cfl_light`.
fn column(cfl_light: Option<f64>) -> TwoPhaseModel {
    let mut cfg = column_config(NX, NY);
    cfg.time.cfl_light = cfl_light;
    released_column(cfg)
}

/// The step of the rule for the largest speeds (u, v) next to the grains and (u, v) anywhere.
fn rule(m: &TwoPhaseModel, cfl_light: Option<f64>, dense: (f64, f64), all: (f64, f64)) -> f64 {
    let (g, cfl) = (&m.config().grid, m.config().time.cfl);
    let step = |c: f64, (u, v): (f64, f64)| stable_dt(c, u, v, g.dx, g.dy, 9.81, 0.0);
    match cfl_light {
        None => step(cfl, all),
        Some(c) => step(cfl, dense).min(step(c, all)),
    }
}

#[test]
fn the_light_phase_away_from_the_grains_keeps_its_own_cfl_number() {
    let h = 0.45 / NY as f64;
    let band = -LIGHT_CFL_BAND * h;
    // Φ beside the column (x < 0.1 m below its top, y < 0.2 m) is minus the distance to its side
    let (beside, above) = (|i: usize| -((i as f64 + 0.5) * h - 0.1), |j: usize| -((j as f64 + 0.5) * h - 0.2));
    // the faces at the band's edge: only their inner cell lies within it
    assert!(beside(9) > band && beside(10) < band && above(12) > band && above(13) < band);
    for cfl_light in [None, Some(0.9)] {
        let mut m = column(cfl_light);
        m.u.set(2, 3, 0.3); // inside the grains
        m.v.set(1, 5, -0.2);
        m.u.set(40, 12, 2.0); // in the air, 1 m from the grains
        for exec in [Exec::SERIAL, Exec::with_threads(2)] {
            assert_eq!(m.cfl_dt(exec).to_bits(), rule(&m, cfl_light, (0.3, 0.2), (2.0, 0.2)).to_bits(), "{cfl_light:?}");
        }
        // u between cells 9 and 10 of row 3, v between rows 12 and 13 of column 1: within the
        // band by their inner cell; the next faces out lie beyond it
        m.u.set(10, 3, -1.0);
        m.u.set(11, 3, 1.5);
        m.v.set(1, 13, 0.8);
        m.v.set(1, 14, -1.2);
        for exec in [Exec::SERIAL, Exec::with_threads(2)] {
            assert_eq!(m.cfl_dt(exec).to_bits(), rule(&m, cfl_light, (1.0, 0.8), (2.0, 1.2)).to_bits(), "{cfl_light:?}");
        }
        if cfl_light.is_some() {
            // the air sets the step: 2 m/s at 0.9 against 1 m/s at 0.5
            assert!(m.cfl_dt(Exec::SERIAL) > rule(&m, None, (0.0, 0.0), (2.0, 1.2)) * 1.4);
        }
    }
}

#[test]
fn a_light_phase_cfl_number_equal_to_the_cfl_number_is_the_plain_rule_bit_for_bit() {
    let mut plain = column(None);
    let mut same = column(Some(plain.config().time.cfl));
    for k in 0..25 {
        let (a, b) = (plain.step().unwrap(), same.step().unwrap());
        assert_eq!(a.dt.to_bits(), b.dt.to_bits(), "step {k}");
    }
    assert!(plain.u.interior() == same.u.interior() && plain.phi.interior() == same.phi.interior());
}

#[test]
fn a_light_phase_cfl_number_above_the_abort_limit_is_refused() {
    let mut cfg = column_config(NX, NY);
    cfg.time.cfl_light = Some(1.5);
    match TwoPhaseModel::new(cfg) {
        Err(Error::InvalidParameter { name, allowed, .. }) => {
            assert_eq!(name, "time.cfl_light");
            assert!(allowed.contains("cfl_abort = 1"), "{allowed}");
        }
        other => panic!("expected InvalidParameter, got {:?}", other.err()),
    }
}
