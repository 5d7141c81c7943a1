//! Tests of the level-set room: WENO5 order, transport convergence, Zalesak's disk, the
//! Rider–Kothe vortex, redistancing that keeps the interface in place, exact initial shapes,
//! the smoothed Heaviside and material laws, and serial == parallel.
//!
//! Heavy cases: `cargo test --release -p granrs-core --test levelset`. The Zalesak and T = 8
//! vortex tables (`--ignored`, `make test-slow`) compare with the stored tables
//! `tests/ref/zalesak.ref` and `tests/ref/single_vortex_t8.ref`; `GRANRS_BLESS=1` writes them
//! instead: `GRANRS_BLESS=1 cargo test --release -p granrs-core --test levelset -- --ignored`.

use granrs_core::exec::build_pool;
use granrs_core::levelset::weno5::{weno5_minus, weno5_minus_with, weno5_plus, weno5_plus_with, window};
use granrs_core::levelset::*;
use granrs_core::{Error, Exec, Field, Grid, Location};
use std::f64::consts::PI;

#[path = "common/reftable.rs"]
mod reftable;
use reftable::{float, Column, Tol};

fn order(e_coarse: f64, e_fine: f64) -> f64 {
    (e_coarse / e_fine).log2()
}

// ---------------------------------------------------------------------------------------------
// WENO5 and transport
// ---------------------------------------------------------------------------------------------

/// Max error of the one-sided WENO5 derivatives of f(x) = exp(x) + sin(x)/2 on [0, 1]
/// (f' > 0 and f'' > 0 throughout: no critical point where WENO-JS weights lose order).
fn weno_error(n: usize, mapped: bool) -> f64 {
    let h = 1.0 / n as f64;
    let f = |x: f64| x.exp() + 0.5 * x.sin();
    let df = |x: f64| x.exp() + 0.5 * x.cos();
    let vals: Vec<f64> = (0..n + 7).map(|k| f((k as f64 - 3.0) * h)).collect();
    let mut err = 0.0f64;
    for k in 3..n + 4 {
        let w = window(&vals, k, 1);
        let x = (k as f64 - 3.0) * h;
        let (m, p) = if mapped { (weno5_minus_with::<true>(&w), weno5_plus_with::<true>(&w)) } else { (weno5_minus(&w), weno5_plus(&w)) };
        err = err.max((m / h - df(x)).abs()).max((p / h - df(x)).abs());
    }
    err
}

#[test]
fn weno5_derivative_is_fifth_order_on_smooth_data() {
    for mapped in [false, true] {
        let e: Vec<f64> = [20, 40, 80, 160].iter().map(|&n| weno_error(n, mapped)).collect();
        let orders: Vec<f64> = e.windows(2).map(|p| order(p[0], p[1])).collect();
        println!("WENO5 (mapped: {mapped}) max errors {e:?}, orders {orders:?}");
        // Jiang & Shu: 5th order where f' ≠ 0 (measured 5.00–5.01); 4.5 leaves room for the
        // nonlinear weights' O(h²) departure from the optimal ones.
        for o in &orders[1..] {
            assert!(*o >= 4.5, "observed WENO5 order {o:.2} < 4.5 ({orders:?})");
        }
    }
}

#[test]
fn weno5_of_constant_data_is_zero_not_nan() {
    let w = [2.5; 7];
    assert_eq!(weno5_minus(&w), 0.0);
    assert_eq!(weno5_plus(&w), 0.0);
    let tiny: [f64; 7] = std::array::from_fn(|k| 1e-200 * k as f64);
    assert!((weno5_minus(&tiny) - 1e-200).abs() < 1e-213);
}

/// L1 error (over a disk of radius 0.3 around the exact final centre) of a Gaussian advected by
/// the uniform flow (1, 0.5) for t = 0.3 on an n × n grid of [0,1]² at Courant number 0.8.
fn uniform_transport_error(n: usize) -> f64 {
    let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
    let (ux, vy, sigma) = (1.0, 0.5, 0.08);
    let bump = |x: f64, y: f64| (-((x - 0.35).powi(2) + (y - 0.35).powi(2)) / (sigma * sigma)).exp();
    let mut phi = Field::from_fn(&grid, Location::Centre, bump);
    let u = Field::from_fn(&grid, Location::XFace, |_, _| ux);
    let v = Field::from_fn(&grid, Location::YFace, |_, _| vy);
    let t_end = 0.3;
    let rate = max_transport_rate(&u, &v, &grid, Exec::SERIAL).unwrap();
    let steps = (t_end * rate / 0.8).ceil() as usize;
    let dt = t_end / steps as f64;
    let mut tr = LevelSetTransport::new(&grid);
    for _ in 0..steps {
        tr.advect(&mut phi, &u, &v, &grid, dt, Exec::SERIAL).unwrap();
    }
    let (xe, ye) = (0.35 + ux * t_end, 0.35 + vy * t_end);
    let mut err = 0.0;
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (grid.xc(i as isize), grid.yc(j as isize));
            if (x - xe).hypot(y - ye) < 0.3 {
                err += (phi.at(i as isize, j as isize) - bump(x - ux * t_end, y - vy * t_end)).abs() * grid.dx * grid.dy;
            }
        }
    }
    err
}

#[test]
fn transport_of_smooth_profile_converges_at_third_order() {
    let e: Vec<f64> = [50, 100, 200].iter().map(|&n| uniform_transport_error(n)).collect();
    let orders: Vec<f64> = e.windows(2).map(|p| order(p[0], p[1])).collect();
    println!("uniform transport L1 errors {e:?}, orders {orders:.2?}");
    // At fixed Courant number δt ∝ h: error = O(h⁵) + O(δt³), so the combined order tends to
    // 3 (RK3-limited) from above (measured 4.3 then 3.65 while the spatial error still counts).
    assert!(orders[1] >= 2.8, "transport order {:.2} < 2.8 ({e:?})", orders[1]);
}

#[test]
fn transport_rejects_bad_inputs() {
    let grid = Grid::new(16, 16, 1.0, 1.0).unwrap();
    let mut phi = Field::zeros(&grid, Location::Centre);
    let u = Field::zeros(&grid, Location::XFace);
    let v = Field::zeros(&grid, Location::YFace);
    let mut tr = LevelSetTransport::new(&grid);
    // u passed where v belongs
    assert!(matches!(tr.advect(&mut phi, &u, &u, &grid, 0.1, Exec::SERIAL), Err(Error::Shape { .. })));
    match tr.advect(&mut phi, &u, &v, &grid, f64::NAN, Exec::SERIAL) {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "dt"),
        other => panic!("expected a `dt` error, got {other:?}"),
    }
    assert_eq!(stable_dt(&u, &v, &grid, 0.5, Exec::SERIAL).unwrap(), f64::INFINITY);
}

// ---------------------------------------------------------------------------------------------
// Zalesak and Rider–Kothe
// ---------------------------------------------------------------------------------------------

#[test]
fn zalesak_exact_area_matches_reference_data() {
    // docs/reference-data.md, "Level-set transport": exact area 582.207.
    let a = validation::zalesak_shape().area().unwrap();
    assert!((a - 582.207).abs() < 5e-4, "slotted-disk area {a}");
}

#[test]
fn zalesak_one_revolution_without_redistancing() {
    let m = zalesak(100, None, 0.5, Exec::SERIAL).unwrap();
    println!("Zalesak 100², no redistancing: {m:#?}");
    // Acceptance numbers of the level-set room: 1 % area, 5 % symmetric difference (measured
    // −0.90 % and 3.1 %; the area is the bicubic-refined estimate, whose own error on the initial
    // disk is −2e-6; the second-order estimate would say −1.02 %, 0.066 % of it its own bias).
    assert!(m.area_rel_error.abs() <= 0.01, "area error {:.4}", m.area_rel_error);
    assert!(m.symdiff_rel <= 0.05, "symmetric difference {:.4}", m.symdiff_rel);
}

#[test]
fn zalesak_one_revolution_with_redistancing_every_10_steps() {
    let m = zalesak(100, Some(10), 0.5, Exec::SERIAL).unwrap();
    println!("Zalesak 100², redistancing every 10 steps: {m:#?}");
    // Acceptance number: 2 % area with redistancing (the paper's frequency); measured +1.43 %
    // (the 5-cell slot narrows: its flanks are re-sharpened into kinks that WENO then erodes).
    assert!(m.area_rel_error.abs() <= 0.02, "area error {:.4}", m.area_rel_error);
    assert!(m.redistance_calls == m.steps / 10);
}

#[test]
fn single_vortex_t2_conserves_area() {
    let m = single_vortex(128, 2.0, None, 0.5, Exec::SERIAL).unwrap();
    println!("single vortex 128², T = 2: {m:#?}");
    // Acceptance number: 1 % area at T = 2 on 128² (measured −0.02 %).
    assert!(m.area_rel_error.abs() <= 0.01, "area error {:.4}", m.area_rel_error);
}

/// Tolerance of the stored level-set tables' error measures: the cases are deterministic (fixed
/// steps, serial == parallel bit for bit, see `serial_and_parallel_give_identical_fields`), so a
/// run reproduces the stored digits exactly on the same build; 1e-9 relative leaves room only
/// for the last-digit rounding of libm's sin/cos between platforms. The absolute floor 1e-14
/// covers the area error, a difference of two areas each rounded to ~1e-16 relative.
const TABLE_TOL: Tol = Tol::Close { rel: 1e-9, abs: 1e-14 };

fn redistance_label(every: Option<usize>) -> String {
    every.map_or("none".to_string(), |k| format!("every{k}"))
}

/// Zalesak's disk (100², one revolution) for the combinations of weights, redistancing frequency
/// and interface treatment, compared with `tests/ref/zalesak.ref`. Six one-revolution runs:
/// 26 s in release on the 2-core VM, and the default tests already run the first two rows
/// (`zalesak_one_revolution_*`), hence `#[ignore]` (`make test-slow`). Regenerate the
/// table with `GRANRS_BLESS=1 cargo test --release -p granrs-core --test levelset -- --ignored
/// zalesak_table`.
#[test]
#[ignore]
fn zalesak_table() {
    let columns = [
        Column { name: "weights", tol: Tol::Label },
        Column { name: "redistance", tol: Tol::Label },
        Column { name: "interface", tol: Tol::Label },
        Column { name: "steps", tol: Tol::Exact },
        Column { name: "redistance_calls", tol: Tol::Exact },
        Column { name: "area_rel_error", tol: TABLE_TOL },
        Column { name: "symdiff_rel", tol: TABLE_TOL },
    ];
    let mut rows = Vec::new();
    for weights in [WenoWeights::JiangShu, WenoWeights::Mapped] {
        for (every, interface) in
            [(None, InterfaceTreatment::ClosestPoint), (Some(10), InterfaceTreatment::ClosestPoint), (Some(10), InterfaceTreatment::SubcellPde)]
        {
            let redistance = RedistanceSettings { interface, ..Default::default() };
            let opts = CaseOptions { weights, redistance, ..CaseOptions::new(every, 0.5) };
            let m = zalesak_with(100, &opts, Exec::SERIAL).unwrap();
            // docs/reference-data.md, "Level-set transport": exact area 582.207 (given to 3
            // decimals: half a unit of the last digit).
            assert!((m.area_exact - 582.207).abs() <= 5e-4, "slotted-disk exact area {}", m.area_exact);
            rows.push(vec![
                format!("{weights:?}"),
                redistance_label(every),
                format!("{interface:?}"),
                m.steps.to_string(),
                m.redistance_calls.to_string(),
                float(m.area_rel_error),
                float(m.symdiff_rel),
            ]);
        }
    }
    let header = [
        "Zalesak's slotted disk, 100 x 100 cells, one revolution (t = 628), Courant number 0.5 (tests/levelset.rs, zalesak_table).",
        "Labels and counts compared exactly, the errors to 1e-9 relative (+ 1e-14 absolute).",
        "Regenerate: GRANRS_BLESS=1 cargo test --release -p granrs-core --test levelset -- --ignored zalesak_table",
    ];
    reftable::check("zalesak", &header, &columns, &rows);
}

/// The T = 8 Rider–Kothe vortex errors on 64², 128², 256²: Jiang–Shu weights without and with
/// redistancing every 10 steps, and the mapped weights with redistancing, compared with
/// `tests/ref/single_vortex_t8.ref`. Nine runs, the 256² ones dominating: 587 s in release on
/// the 2-core VM (loaded by other jobs), hence `#[ignore]` (`make test-slow`). Regenerate the table with
/// `GRANRS_BLESS=1 cargo test --release -p granrs-core --test levelset -- --ignored
/// single_vortex_t8_table`.
#[test]
#[ignore]
fn single_vortex_t8_table() {
    let columns = [
        Column { name: "n", tol: Tol::Label },
        Column { name: "weights", tol: Tol::Label },
        Column { name: "redistance", tol: Tol::Label },
        Column { name: "steps", tol: Tol::Exact },
        Column { name: "area_rel_error", tol: TABLE_TOL },
        Column { name: "symdiff_rel", tol: TABLE_TOL },
        Column { name: "symdiff_initial_rel", tol: TABLE_TOL },
    ];
    let mut rows = Vec::new();
    for n in [64, 128, 256] {
        for (every, weights) in [(None, WenoWeights::JiangShu), (Some(10), WenoWeights::JiangShu), (Some(10), WenoWeights::Mapped)] {
            let opts = CaseOptions { weights, ..CaseOptions::new(every, 0.5) };
            let m = single_vortex_with(n, 8.0, &opts, Exec::SERIAL).unwrap();
            // docs/reference-data.md, "Level-set transport": at t = T the exact solution is the
            // initial circle, area π · 0.15² = 0.0706858 (given to 7 digits: half a unit of the
            // last one).
            assert!((m.area_exact - 0.0706858).abs() <= 5e-8, "vortex exact area {}", m.area_exact);
            rows.push(vec![
                n.to_string(),
                format!("{weights:?}"),
                redistance_label(every),
                m.steps.to_string(),
                float(m.area_rel_error),
                float(m.symdiff_rel),
                float(m.symdiff_initial_rel),
            ]);
        }
    }
    let header = [
        "Rider-Kothe single vortex, period T = 8, n x n cells, Courant number 0.5 (tests/levelset.rs, single_vortex_t8_table).",
        "Labels and counts compared exactly, the errors to 1e-9 relative (+ 1e-14 absolute).",
        "Regenerate: GRANRS_BLESS=1 cargo test --release -p granrs-core --test levelset -- --ignored single_vortex_t8_table",
    ];
    reftable::check("single_vortex_t8", &header, &columns, &rows);
}

// ---------------------------------------------------------------------------------------------
// Redistancing
// ---------------------------------------------------------------------------------------------

/// Distance from (x, y) to the ellipse (a cos t, b sin t): dense scan, then golden-section
/// refinement of the foot-point parameter around the best sample.
fn ellipse_distance(x: f64, y: f64, a: f64, b: f64) -> f64 {
    let dist = |t: f64| (x - a * t.cos()).hypot(y - b * t.sin());
    let dt = PI / 1800.0;
    let best = (0..3600).map(|k| k as f64 * dt).fold(0.0, |bt, t| if dist(t) < dist(bt) { t } else { bt });
    let (mut lo, mut hi) = (best - dt, best + dt);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..100 {
        let (t1, t2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if dist(t1) < dist(t2) {
            hi = t2;
        } else {
            lo = t1;
        }
    }
    dist(0.5 * (lo + hi))
}

#[test]
fn redistancing_stretched_ellipse_keeps_interface_and_gives_unit_gradient() {
    let (a, b) = (0.35, 0.1);
    let grid = Grid::with_origin(256, 128, -0.5, -0.25, 1.0, 0.5).unwrap();
    let h = grid.h();
    // (with a tolerance, the cells already within 0.01 h of their distance keep Φ⁰: the same bars)
    for (interface, tolerance) in [(InterfaceTreatment::ClosestPoint, 0.0), (InterfaceTreatment::SubcellPde, 0.0), (InterfaceTreatment::ClosestPoint, 0.01)] {
        // A non-distance function with the ellipse as zero set: |∇Φ⁰| runs from 0.57 to 2.
        let mut phi = Field::from_fn(&grid, Location::Centre, |x, y| -(x * x / (a * a) + y * y / (b * b) - 1.0) * 0.1);
        let e0 = eikonal_error(&phi, &grid, 3.0 * h);
        let before: Vec<f64> = interface_points(&phi, &grid).iter().map(|p| ellipse_distance(p[0], p[1], a, b)).collect();
        let mut r = Redistancer::new(&grid, RedistanceSettings { interface, tolerance, ..Default::default() }).unwrap();
        let info = r.redistance(&mut phi, &grid, Exec::SERIAL).unwrap();
        let after: Vec<f64> = interface_points(&phi, &grid).iter().map(|p| ellipse_distance(p[0], p[1], a, b)).collect();
        let max_before = before.iter().cloned().fold(0.0, f64::max) / h;
        let max_after = after.iter().cloned().fold(0.0, f64::max) / h;
        let mean_after = after.iter().sum::<f64>() / after.len() as f64 / h;
        let e3 = eikonal_error(&phi, &grid, 3.0 * h);
        let e6 = eikonal_error(&phi, &grid, 6.0 * h);
        println!(
            "ellipse, {interface:?}, tolerance {tolerance}: {info:?}\n  crossings' distance to the exact ellipse / h: before max {max_before:.4}, after max {max_after:.4} mean {mean_after:.5} ({} points)\n  eikonal error before (3h band) {e0:?}\n  after (3h) {e3:?}\n  after (6h) {e6:?}",
            after.len()
        );
        assert_eq!(before.len(), after.len(), "the interface must cross the same number of grid lines");
        // Acceptance: the zero level set moves by < 0.1 h. Before redistancing the crossings
        // (linear interpolation of Φ⁰ between centres) are already 0.016 h off at the tips.
        assert!(max_after < 0.1, "{interface:?}: interface moved up to {max_after:.3} h");
        // |∇Φ| ≈ 1 near the interface: Φ⁰ has a mean error of 0.54 in the 3-cell band; both
        // treatments bring it below 1e-3 (measured 2e-4 to 6e-4, max 5e-3 to 1e-2 in the 6-cell
        // band, where the kinks of the distance function on the major axis begin).
        assert!(e0.mean > 0.3, "test set-up: Φ⁰ should be far from a distance function ({e0:?})");
        assert!(e6.mean < 0.005, "{interface:?}: eikonal error in the 6-cell band {e6:?}");
        assert!(e3.max < 0.03, "{interface:?}: eikonal error in the 3-cell band {e3:?}");
    }
}

#[test]
fn repeated_redistancing_does_not_creep() {
    // The paper redistances every 10 steps: thousands of calls in a run. A distance function
    // redistanced 100 times must keep its area: circle of radius 6 cells and a square (corners).
    let grid = Grid::new(64, 64, 64.0, 64.0).unwrap();
    for (shape, tol_closest, creeps) in
        [(Shape::Circle { xc: 31.3, yc: 32.6, radius: 6.0 }, 4e-4, true), (Shape::Rectangle { x0: 20.3, x1: 40.6, y0: 22.2, y1: 41.7 }, 1e-4, false)]
    {
        let mut area = [0.0; 2];
        for (m, interface) in [InterfaceTreatment::ClosestPoint, InterfaceTreatment::SubcellPde].into_iter().enumerate() {
            let mut phi = Field::zeros(&grid, Location::Centre);
            init_signed_distance(&shape, &grid, &mut phi).unwrap();
            let a0 = dense_area(&phi, &grid, Exec::SERIAL);
            let mut r = Redistancer::new(&grid, RedistanceSettings { interface, ..Default::default() }).unwrap();
            for _ in 0..100 {
                r.redistance(&mut phi, &grid, Exec::SERIAL).unwrap();
            }
            area[m] = dense_area(&phi, &grid, Exec::SERIAL) / a0 - 1.0;
        }
        println!("{shape:?}: relative area change after 100 calls: closest point {:+.2e}, subcell PDE {:+.2e}", area[0], area[1]);
        // Closest point: measured +1.5e-4 (circle r = 6h) and −1.2e-5 (square); the subcell PDE
        // shrinks the circle by 2.6e-2 (0.04 h (h/r)² per call), which this test documents.
        assert!(area[0].abs() < tol_closest, "closest point: area change {:.2e}", area[0]);
        if creeps {
            assert!(area[1] < -1e-2, "subcell PDE expected to creep on a 6-cell circle ({:.2e})", area[1]);
        }
    }
}

#[test]
fn redistancing_keeps_a_distance_function_almost_unchanged() {
    let grid = Grid::new(96, 96, 1.0, 1.0).unwrap();
    let circle = Shape::Circle { xc: 0.47, yc: 0.52, radius: 0.23 };
    let mut phi = Field::zeros(&grid, Location::Centre);
    init_signed_distance(&circle, &grid, &mut phi).unwrap();
    let exact = phi.clone();
    let mut r = Redistancer::new(&grid, RedistanceSettings::default()).unwrap();
    let info = r.redistance(&mut phi, &grid, Exec::SERIAL).unwrap();
    // the guard of the continuous equation's bounds never acts on a smooth interface
    assert_eq!(info.clamped_cells, 0);
    let mut max_err = 0.0f64;
    for j in 0..96 {
        for i in 0..96 {
            let e = exact.at(i, j);
            if e.abs() < 6.0 * grid.dx {
                max_err = max_err.max((phi.at(i, j) - e).abs());
            }
        }
    }
    println!("circle redistancing: max |Φ − d| in a 6-cell band = {:.3e} h", max_err / grid.dx);
    // The frozen closest-point band reproduces the distance to O(h⁴) and the WENO5 PDE keeps it
    // (measured 3e-6 h; the subcell-PDE treatment gives 5e-4 h): 1e-4 h.
    assert!(max_err < 1e-4 * grid.dx, "max |Φ − d| = {:.3} h", max_err / grid.dx);
}

/// Height of the highest zero crossing of Φ in each column (linear between the two cells), in
/// cells of height `dy`; 0 where the column holds no dense phase.
fn surface_heights(phi: &Field, grid: &Grid) -> Vec<f64> {
    (0..grid.nx as isize)
        .map(|i| match (0..grid.ny as isize).rev().find(|&j| phi.at(i, j) > 0.0) {
            None => 0.0,
            Some(j) if j + 1 == grid.ny as isize => grid.ny as f64,
            Some(j) => {
                let (a, b) = (phi.at(i, j), phi.at(i, j + 1));
                j as f64 + 0.5 + a / (a - b)
            }
        })
        .collect()
}

/// Values of the cells next to the interface (a 4-neighbour of the other sign).
fn interface_values(phi: &Field, grid: &Grid) -> Vec<f64> {
    let (nx, ny) = (grid.nx as isize, grid.ny as isize);
    let mut v = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let p = phi.at(i, j);
            let across = [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().any(|&(a, b)| {
                let (k, l) = (i + a, j + b);
                (0..nx).contains(&k) && (0..ny).contains(&l) && phi.at(k, l) * p < 0.0
            });
            if across {
                v.push(p);
            }
        }
    }
    v
}

/// A rough deposit on the bed, three cells deep at the back and a film of 0.6 cell at the front,
/// with bumps of about five cells: what the column leaves at rest. Redistanced after every step
/// of a run at rest (hundreds of calls a second), the closest-point treatment moves such a
/// surface a little at every call, where the bicubic sees bumps of a few cells; with
/// `redistance_tolerance` = t the interface cells already within t·h of their distance keep
/// their values, and after a few calls nothing moves any more.
#[test]
fn redistancing_with_a_tolerance_leaves_a_deposit_at_rest_in_place() {
    let grid = Grid::new(192, 32, 192.0, 32.0).unwrap(); // h = 1; 6 144 cells: parallel sweeps
    let surface = |x: f64| (3.0 - 0.04 * x).max(0.6) + 0.3 * (2.0 * PI * x / 4.7).sin() + 0.2 * (2.0 * PI * x / 7.3).cos();
    // the surface heights after the first call, and heights and interface cells after 10 and
    // after 200 calls
    let run = |tolerance: f64, exec: Exec| {
        let mut phi = Field::from_fn(&grid, Location::Centre, |x, y| surface(x) - y);
        let mut r = Redistancer::new(&grid, RedistanceSettings { tolerance, ..Default::default() }).unwrap();
        // the first call brings Φ to a distance (|∇Φ| is 1.0–1.4 before it)
        r.redistance(&mut phi, &grid, exec).unwrap();
        let first = surface_heights(&phi, &grid);
        for _ in 1..10 {
            r.redistance(&mut phi, &grid, exec).unwrap();
        }
        let tenth = (surface_heights(&phi, &grid), interface_values(&phi, &grid));
        for _ in 10..200 {
            r.redistance(&mut phi, &grid, exec).unwrap();
        }
        (first, tenth, (surface_heights(&phi, &grid), interface_values(&phi, &grid)), phi)
    };
    let largest = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    // measured (h): t = 0: 6.3e-2 in 200 calls, 5.9e-2 of it after the tenth; 1e-3: 6.0e-2 (the
    // reset's change per call is larger than t); 3e-3: 2.3e-3; 1e-2: 0; 3e-2: 1.0e-2 (all three
    // within t, and nothing moves after the tenth call)
    for tolerance in [0.0, 0.001, 0.003, 0.01, 0.03] {
        let (first, (h10, cells10), (h200, cells200), phi) = run(tolerance, Exec::SERIAL);
        let moved = largest(&first, &h200);
        let same = cells10.len() == cells200.len() && cells10.iter().zip(&cells200).all(|(a, b)| a.to_bits() == b.to_bits());
        println!(
            "tolerance {tolerance}: the surface moved {moved:.2e} h in 200 calls ({:.2e} after the tenth); interface cells kept after the tenth: {same}",
            largest(&h10, &h200)
        );
        if tolerance == 0.0 {
            assert!(moved > 1e-2, "the test's surface should creep without a tolerance: {moved:.2e} h");
        }
        if tolerance >= 0.003 {
            assert!(same && moved <= tolerance, "tolerance {tolerance}: moved {moved:.2e} h, cells kept after the tenth call: {same}");
        }
        if tolerance == 0.01 {
            assert!(moved == 0.0, "{moved:e}");
            let pool = build_pool(2).unwrap();
            let (_, _, _, parallel) = pool.install(|| run(tolerance, Exec { parallel: true }));
            assert!(phi.slice().iter().zip(parallel.slice()).all(|(a, b)| a.to_bits() == b.to_bits()), "one thread against two");
        }
    }
}

#[test]
fn redistance_settings_are_validated() {
    let grid = Grid::new(16, 16, 1.0, 1.0).unwrap();
    for (s, name) in [
        (RedistanceSettings { iterations: 0, ..Default::default() }, "iterations"),
        (RedistanceSettings { cfl: 0.8, ..Default::default() }, "cfl"),
        (RedistanceSettings { band: Some(0.5), ..Default::default() }, "band"),
        (RedistanceSettings { tolerance: 0.8, ..Default::default() }, "tolerance"),
        (RedistanceSettings { tolerance: -0.1, ..Default::default() }, "tolerance"),
    ] {
        match Redistancer::new(&grid, s) {
            Err(Error::InvalidParameter { name: n, .. }) => assert_eq!(n, name),
            other => panic!("expected an error on `{name}`, got {other:?}"),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Shapes and diagnostics
// ---------------------------------------------------------------------------------------------

#[test]
fn paper_column_rectangle_is_subcell_exact() {
    // docs/reference-data.md, "The paper": h = 0.45/256 m, column 0.2 m × 0.4 m, domain longer than 2.05 m.
    let grid = Grid::new(1280, 256, 2.25, 0.45).unwrap();
    let h = grid.h();
    assert!((h - 1.7578125e-3).abs() < 1e-15);
    let exact = 0.2 * 0.4;
    let mut phi = Field::zeros(&grid, Location::Centre);
    for (shape, what) in [
        (Shape::Rectangle { x0: 0.0, x1: 0.2, y0: 0.0, y1: 0.4 }, "flush with the walls"),
        (Shape::Rectangle { x0: -1.0, x1: 0.2, y0: -1.0, y1: 0.4 }, "extending through the walls"),
        (Shape::Rectangle { x0: 0.7001, x1: 0.9001, y0: 0.0203, y1: 0.4203 }, "inside the domain"),
    ] {
        init_signed_distance(&shape, &grid, &mut phi).unwrap();
        let area = dense_area(&phi, &grid, Exec::SERIAL);
        let refined = dense_area_refined(&phi, &grid, 8, Exec::SERIAL);
        println!("column {what}: area {area:.9} (relative error {:.2e}), refined {:.2e}", area / exact - 1.0, refined / exact - 1.0);
        assert!((refined / exact - 1.0).abs() < 1e-3);
        // Acceptance: 1e-3 relative. Straight edges are exact for the piecewise-linear
        // reconstruction; only the O(h²) rounding at convex corners remains (h²/0.08 ≈ 4e-5).
        assert!((area / exact - 1.0).abs() < 1e-3, "{what}: area {area}");
    }
    // The zero level set at the exact non-grid-aligned position x = 0.2 (113.78 cells) on a
    // row at mid-height of the flush column, and y = 0.4 on a column at mid-width.
    init_signed_distance(&Shape::Rectangle { x0: -1.0, x1: 0.2, y0: -1.0, y1: 0.4 }, &grid, &mut phi).unwrap();
    let (i, j) = ((0.2 / h - 0.5) as isize, 100);
    let (pa, pb) = (phi.at(i, j), phi.at(i + 1, j));
    assert!(pa > 0.0 && pb < 0.0);
    let x_cross = grid.xc(i) + pa / (pa - pb) * h;
    assert!((x_cross - 0.2).abs() < 1e-12, "x crossing {x_cross}");
    let (i, j) = (30, (0.4 / h - 0.5) as isize);
    let (pa, pb) = (phi.at(i, j), phi.at(i, j + 1));
    let y_cross = grid.yc(j) + pa / (pa - pb) * h;
    assert!((y_cross - 0.4).abs() < 1e-12, "y crossing {y_cross}");
}

#[test]
fn slotted_disk_distance_is_exact() {
    let shape = validation::zalesak_shape();
    // Brute force: the boundary sampled every 1e-3 (arc, slot sides, slot top).
    let (xc, yc, r, hw, top): (f64, f64, f64, f64, f64) = (50.0, 75.0, 15.0, 2.5, 85.0);
    let ycut = yc - (r * r - hw * hw).sqrt();
    let mut pts = Vec::new();
    let n_arc = 100_000;
    for k in 0..n_arc {
        let t = 2.0 * PI * k as f64 / n_arc as f64;
        let (x, y) = (xc + r * t.cos(), yc + r * t.sin());
        if !((x - xc).abs() < hw && y < yc) {
            pts.push((x, y));
        }
    }
    for k in 0..=20_000 {
        let s = k as f64 / 20_000.0;
        pts.push((xc - hw, ycut + s * (top - ycut)));
        pts.push((xc + hw, ycut + s * (top - ycut)));
        pts.push((xc - hw + s * 2.0 * hw, top));
    }
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..400 {
        let (x, y) = (25.0 + 50.0 * rnd(), 50.0 + 50.0 * rnd());
        let d = shape.signed_distance(x, y);
        let brute = pts.iter().map(|&(px, py)| (x - px).hypot(y - py)).fold(f64::INFINITY, f64::min);
        // Sampling spacing ≤ 2π·15/1e5 ≈ 1e-3: the brute force over-estimates by < 1e-3.
        assert!((d.abs() - brute).abs() < 1e-3, "at ({x}, {y}): {d} vs {brute}");
        let inside = (x - xc).hypot(y - yc) < r && !((x - xc).abs() < hw && y < top);
        assert_eq!(d > 0.0, inside);
    }
}

#[test]
fn dense_area_is_second_order_for_a_circle() {
    let circle = Shape::Circle { xc: 0.503, yc: 0.488, radius: 0.3 };
    let exact = circle.area().unwrap();
    let mut refined = vec![];
    let errs: Vec<f64> = [32, 64, 128]
        .iter()
        .map(|&n| {
            let grid = Grid::new(n, n, 1.0, 1.0).unwrap();
            let mut phi = Field::zeros(&grid, Location::Centre);
            init_signed_distance(&circle, &grid, &mut phi).unwrap();
            refined.push((dense_area_refined(&phi, &grid, 8, Exec::SERIAL) - exact).abs() / exact);
            (dense_area(&phi, &grid, Exec::SERIAL) - exact).abs()
        })
        .collect();
    println!("refined relative area errors {refined:?}");
    // Bicubic + 8 × 8 sub-cells: the second-order error divided by 64 at least.
    for (r, e) in refined.iter().zip(&errs) {
        assert!(*r < e / exact / 30.0, "refined {r:e} vs second order {:e}", e / exact);
    }
    let o = order(errs[1], errs[2]);
    println!("circle area errors {errs:?}, order {o:.2}");
    // Piecewise-linear reconstruction: second order (1.8 allows for the irregular cut pattern);
    // the chord error of a circle of 38 cells radius is ≈ h²/(6R)·2πR/A ≈ 1.2e-4 relative.
    assert!(o > 1.8 && errs[2] / exact < 2e-4, "area errors {errs:?}");
}

#[test]
fn shapes_are_validated_and_combine() {
    match (Shape::Circle { xc: 0.0, yc: 0.0, radius: -1.0 }).validate() {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "radius"),
        other => panic!("{other:?}"),
    }
    let layer = Shape::HalfPlane { px: 0.0, py: 0.1, nx: 0.0, ny: 2.0 };
    assert!((layer.signed_distance(0.3, 0.04) - 0.06).abs() < 1e-15);
    let u = Shape::Union(vec![layer.clone(), Shape::Circle { xc: 0.5, yc: 0.3, radius: 0.1 }]);
    assert!(u.contains(0.5, 0.35) && u.contains(0.9, 0.05) && !u.contains(0.9, 0.3));
    let d = Shape::Difference(Box::new(layer), Box::new(Shape::Circle { xc: 0.5, yc: 0.0, radius: 0.05 }));
    assert!(!d.contains(0.5, 0.01) && d.contains(0.7, 0.01));
}

// ---------------------------------------------------------------------------------------------
// Heaviside and material laws
// ---------------------------------------------------------------------------------------------

#[test]
fn heaviside_and_two_phase_laws() {
    let eps = 0.015;
    assert_eq!(heaviside(-eps * 1.0001, eps), 0.0);
    assert_eq!(heaviside(eps * 1.0001, eps), 1.0);
    assert!((heaviside(0.0, eps) - 0.5).abs() < 1e-15);
    // continuity at ±ε and δ_ε = dH/dΦ (central difference, error O(δ²) ≈ 1e-9)
    assert!(heaviside(eps, eps) == 1.0 && heaviside(-eps, eps).abs() < 1e-15);
    for k in -10..=10 {
        let p = 0.09 * k as f64 * eps;
        let d = 1e-7;
        let fd = (heaviside(p + d, eps) - heaviside(p - d, eps)) / (2.0 * d);
        assert!((fd - dirac(p, eps)).abs() < 1e-5 / eps, "δ at {p}");
    }
    // paper's values: granular ρ_s = 2500 (here the mixture density of the model is the
    // caller's), air 1; η 0.1 and 2e-5 Pa s.
    let grid = Grid::new(1280, 256, 2.25, 0.45).unwrap();
    let p = TwoPhaseProperties::new(2500.0, 1.0, 0.1, 2e-5, &grid).unwrap();
    assert!((p.eps - 1.5 * 0.45 / 256.0).abs() < 1e-15);
    assert_eq!(p.density(1.0), 2500.0);
    assert_eq!(p.density(-1.0), 1.0);
    assert!((p.density(0.0) - 1250.5).abs() < 1e-12);
    // harmonic mean at H = ½: 2/(1/0.1 + 1/2e-5) = 3.9992e-5, far below the arithmetic 0.05
    assert!((p.viscosity(0.0) - 2.0 / (10.0 + 5e4)).abs() < 1e-18);
    assert!((p.viscosity(1.0) - 0.1).abs() < 1e-15 && (p.viscosity(-1.0) - 2e-5).abs() < 1e-18);
    // κ(Φ) = κ_f H + κ_∞ (1 − H) with κ_∞ = 1e16 (paper)
    assert_eq!(p.blend(1.0, 0.035, 1e16), 0.035);
    let bad = TwoPhaseProperties { eta_light: 0.0, ..p };
    match bad.validate() {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "eta_light"),
        other => panic!("{other:?}"),
    }
    // field version
    let mut phi = Field::zeros(&grid, Location::Centre);
    init_signed_distance(&Shape::Rectangle { x0: -1.0, x1: 0.2, y0: -1.0, y1: 0.4 }, &grid, &mut phi).unwrap();
    let mut rho = Field::zeros(&grid, Location::Centre);
    map_centre_field(&phi, &mut rho, Exec::SERIAL, |f| p.density(f)).unwrap();
    assert_eq!(rho.at(10, 10), 2500.0);
    assert_eq!(rho.at(1000, 200), 1.0);
}

// ---------------------------------------------------------------------------------------------
// Serial == parallel
// ---------------------------------------------------------------------------------------------

#[test]
fn serial_and_parallel_give_identical_fields() {
    let grid = Grid::new(160, 120, 100.0, 75.0).unwrap();
    let run = |exec: Exec| -> (Field, f64) {
        let mut phi = Field::zeros(&grid, Location::Centre);
        init_signed_distance(&Shape::SlottedDisk { xc: 50.0, yc: 45.0, radius: 15.0, slot_width: 5.0, slot_top: 55.0 }, &grid, &mut phi).unwrap();
        let w = PI / 314.0;
        let u = Field::from_fn(&grid, Location::XFace, |_, y| w * (37.5 - y) + 0.1);
        let v = Field::from_fn(&grid, Location::YFace, |x, _| w * (x - 50.0));
        let mut tr = LevelSetTransport::new(&grid);
        let mut rd = Redistancer::new(&grid, RedistanceSettings::default()).unwrap();
        let dt = stable_dt(&u, &v, &grid, 0.5, exec).unwrap();
        for step in 1..=20 {
            tr.advect(&mut phi, &u, &v, &grid, dt, exec).unwrap();
            if step % 10 == 0 {
                rd.redistance(&mut phi, &grid, exec).unwrap();
            }
        }
        let a = dense_area(&phi, &grid, exec);
        (phi, a)
    };
    let (serial, a_serial) = run(Exec::SERIAL);
    let pool = build_pool(2).unwrap();
    let (parallel, a_parallel) = pool.install(|| run(Exec { parallel: true }));
    let scale = serial.max_abs();
    let mut diff = 0.0f64;
    for (a, b) in serial.interior().iter().zip(parallel.interior().iter()) {
        diff = diff.max((a - b).abs());
    }
    // Each cell's arithmetic is independent of the row split and the area sums per block in
    // block order: identical to round-off, asserted at 1e-12 relative.
    assert!(diff <= 1e-12 * scale, "max |serial − parallel| = {diff:e}");
    assert!((a_serial - a_parallel).abs() <= 1e-12 * a_serial);
}

/// Thin films and one-cell air pockets against a wall (the front of a collapsing column at
/// coarse resolution, where an unbounded discrete iteration can reach |Φ| ≈ 1900 h): whatever the
/// iteration does, Φ keeps the sign of Φ⁰ and |Φ| ≤ |Φ⁰| + τ (τ the pseudo time), the bounds the
/// continuous equation φ_τ = S(Φ⁰)(1 − |∇φ|) guarantees.
#[test]
fn redistancing_respects_the_bounds_of_the_continuous_equation() {
    let (nx, ny) = (48, 16);
    let grid = Grid::new(nx, ny, 3.0, 1.0).unwrap();
    let h = grid.dx;
    let mut phi = Field::zeros(&grid, Location::Centre);
    // a granular film 1.5 h thick on the wall y = 0 with pockets of air 0.6 h high under it,
    // and a non-distance far field (gradient 3)
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (grid.xc(i as isize), grid.yc(j as isize));
            let film = 0.75 * h - (y - 0.75 * h).abs();
            let pocket = if (i / 4) % 3 == 1 { 0.3 * h - y } else { -1.0 };
            let v = if pocket > 0.0 { -pocket } else { film };
            phi.set(i, j, if v < 0.0 { 3.0 * v } else { v } + 1e-3 * (x * 7.0).sin() * h);
        }
    }
    let phi0 = phi.clone();
    let settings = RedistanceSettings::default();
    let mut r = Redistancer::new(&grid, settings).unwrap();
    let info = r.redistance(&mut phi, &grid, Exec::SERIAL).unwrap();
    let tau = info.pseudo_time;
    for j in 0..ny as isize {
        for i in 0..nx as isize {
            let (a, b) = (phi0.at(i, j), phi.at(i, j));
            // sign always; magnitude inside the band the pseudo time reached (beyond τ − 2h the
            // far field is the fast-sweeping distance)
            let in_band = b.abs() < tau - 2.0 * h;
            assert!(a * b >= 0.0 && (!in_band || b.abs() <= a.abs() + tau + 1e-12), "cell ({i}, {j}): Φ⁰ = {a:.3e}, Φ = {b:.3e}, τ = {tau:.3e}");
        }
    }
    println!("thin film: {} interface cells, {} clamped", info.interface_cells, info.clamped_cells);
}
