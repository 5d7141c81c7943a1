//! Active region of the two-phase model (`ModelConfig::active_region`, models/active_region.rs).
//!
//! 1. A window as large as the domain is the whole-domain step: the state transfer in and out
//!    of the window (built at the first step, rebuilt after a checkpoint restore) loses nothing,
//!    so the results are bit for bit those of the plain model.
//! 2. A granular column collapsing under air with Coulomb walls: the window grows with the
//!    front and shrinks as the column falls, the dense phase never comes within band/2 cells of
//!    its sides, and the dense area is conserved.
//! 3. Configurations a window cannot serve are refused with the parameter named.

use granrs_core::error::Error;
use granrs_core::grid::{BoundaryConditions, Grid, Side, VelocityBc};
use granrs_core::models::{ActiveRegion, ModelConfig, PressureGauge, TwoPhaseModel};

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
    let mut win = column(nx, ny, Some(ActiveRegion { band: 1000, align: 8 }));
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
    let mut m = column(nx, ny, Some(ActiveRegion { band, align: 4 }));
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
fn a_window_is_refused_where_it_cannot_stand_in_for_the_domain() {
    let grid = Grid::new(32, 16, 2.0, 1.0).unwrap();
    let ar = Some(ActiveRegion { band: 4, align: 4 });
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
    cfg.active_region = Some(ActiveRegion { band: 1, align: 4 });
    assert_eq!(named(cfg.clone()), "active_region.band");
    cfg.active_region = Some(ActiveRegion { band: 4, align: 0 });
    assert_eq!(named(cfg), "active_region.align");
}
