//! Level-set kernels on the paper's grid (1280 × 256 cells, h = 0.45/256 m): one TVD-RK3
//! advection step, one redistancing call (20 pseudo-time iterations, the default), and the
//! volume fraction's step of `interface_transport = "clsvof"` (the two split sweeps, and the
//! rebuild of Φ from F), serial and on a 2-thread pool. State: the collapsed-column-like interface of a 0.2 m × 0.4 m column
//! sheared by a smooth velocity field.
//!
//! Run: `cargo bench -p granrs-core --bench levelset`.

use criterion::{criterion_group, criterion_main, Criterion};
use granrs_core::exec::build_pool;
use granrs_core::levelset::{
    init_signed_distance, stable_dt, InterfaceTreatment, LevelSetTransport, PlicNormal, RedistanceSettings, Redistancer, Shape, VolumeFraction, WenoWeights,
};
use granrs_core::{Exec, Field, Grid, Location};
use std::hint::black_box;
use std::time::Duration;

fn setup() -> (Grid, Field, Field, Field) {
    let grid = Grid::new(1280, 256, 2.25, 0.45).unwrap();
    let mut phi = Field::zeros(&grid, Location::Centre);
    init_signed_distance(&Shape::Rectangle { x0: -1.0, x1: 0.2, y0: -1.0, y1: 0.4 }, &grid, &mut phi).unwrap();
    // A smooth, roughly collapsing flow (m/s).
    let u = Field::from_fn(&grid, Location::XFace, |x, y| 1.5 * (y / 0.45) * (-x / 0.5).exp());
    let v = Field::from_fn(&grid, Location::YFace, |x, y| -0.8 * (y / 0.45) * (-(x - 0.1).powi(2) / 0.02).exp());
    (grid, phi, u, v)
}

fn bench(c: &mut Criterion) {
    let (grid, phi0, u, v) = setup();
    let dt = stable_dt(&u, &v, &grid, 0.5, Exec::SERIAL).unwrap();
    let pool = build_pool(2).unwrap();
    let mut group = c.benchmark_group("levelset_1280x256");
    group.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));

    for (name, weights) in [("advect_rk3_weno5js", WenoWeights::JiangShu), ("advect_rk3_weno5m", WenoWeights::Mapped)] {
        let mut tr = LevelSetTransport::with_weights(&grid, weights);
        let mut phi = phi0.clone();
        group.bench_function(format!("{name}_serial"), |b| b.iter(|| tr.advect(black_box(&mut phi), &u, &v, &grid, dt, Exec::SERIAL).unwrap()));
        let mut phi = phi0.clone();
        group.bench_function(format!("{name}_2threads"), |b| {
            b.iter(|| pool.install(|| tr.advect(black_box(&mut phi), &u, &v, &grid, dt, Exec { parallel: true }).unwrap()))
        });
    }

    // Redistance a transported (not exactly distance) field: restore it before each call.
    let mut moved = phi0.clone();
    let mut tr = LevelSetTransport::new(&grid);
    for _ in 0..10 {
        tr.advect(&mut moved, &u, &v, &grid, dt, Exec::SERIAL).unwrap();
    }
    for (name, settings) in [
        ("redistance_closest_point", RedistanceSettings::default()),
        ("redistance_subcell_pde", RedistanceSettings { interface: InterfaceTreatment::SubcellPde, ..Default::default() }),
        ("redistance_closest_point_band12", RedistanceSettings { band: Some(12.0), ..Default::default() }),
    ] {
        let mut rd = Redistancer::new(&grid, settings).unwrap();
        let mut phi = moved.clone();
        group.bench_function(format!("{name}_serial"), |b| {
            b.iter(|| {
                phi.assign(&moved);
                rd.redistance(black_box(&mut phi), &grid, Exec::SERIAL).unwrap()
            })
        });
        group.bench_function(format!("{name}_2threads"), |b| {
            b.iter(|| {
                phi.assign(&moved);
                pool.install(|| rd.redistance(black_box(&mut phi), &grid, Exec { parallel: true }).unwrap())
            })
        });
    }
    // the volume fraction: F from the column's Φ, transported (restored before each call) and Φ
    // rebuilt from it
    for (name, normal) in [("vof_levelset_normal", PlicNormal::LevelSet), ("vof_youngs", PlicNormal::Youngs)] {
        let mut vof = VolumeFraction::new(&grid, normal);
        let mut phi = phi0.clone();
        vof.set_from_level_set(&mut phi, &grid);
        let f0 = vof.f.clone();
        for (threads, exec) in [("serial", Exec::SERIAL), ("2threads", Exec { parallel: true })] {
            group.bench_function(format!("{name}_transport_{threads}"), |b| {
                b.iter(|| {
                    vof.f.assign(&f0);
                    pool.install(|| vof.transport(black_box(&mut phi), &u, &v, &grid, dt, true, exec).unwrap())
                })
            });
            group.bench_function(format!("{name}_rebuild_{threads}"), |b| {
                b.iter(|| {
                    phi.assign(&phi0);
                    pool.install(|| vof.rebuild_level_set(black_box(&mut phi), &grid, exec))
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
