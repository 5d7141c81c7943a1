//! Operator sweeps, a full Navier–Stokes step, and a STREAM-like triad (the bandwidth reference
//! for docs/benchmarks.md), on the paper's 1280 × 256 grid, with 1 and 2 threads; and one row
//! sweep of [`Exec::for_each_row`] against its size (what a parallel sweep costs beyond its
//! work, and from which size a second thread pays).
//!
//! Run: `cargo bench -p granrs-core --bench kernels`. Each benchmark prints its throughput in
//! cell updates (or bytes) per second through criterion's `Throughput`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use granrs_core::exec::{build_pool, with_active_workers, Exec};
use granrs_core::grid::{BoundaryConditions, Field, Grid, Location, VelocityBc};
use granrs_core::models::{Material, ModelConfig, TwoPhaseModel};
use granrs_core::operators::{convection, divergence, fill_velocity_ghosts, strain_rate, viscous, BcMode};
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Duration;

fn paper_grid() -> Grid {
    Grid::new(1280, 256, 2.25, 0.45).unwrap()
}

fn fields(grid: &Grid) -> (Field, Field) {
    let mut u = Field::from_fn(grid, Location::XFace, |x, y| (3.0 * x).sin() * (5.0 * y).cos());
    let mut v = Field::from_fn(grid, Location::YFace, |x, y| (2.0 * x).cos() * (4.0 * y).sin());
    let bc = BoundaryConditions::uniform(VelocityBc::NoSlip);
    fill_velocity_ghosts(&mut u, &mut v, &bc, grid, BcMode::Full);
    (u, v)
}

fn operators(c: &mut Criterion) {
    let grid = paper_grid();
    let (u, v) = fields(&grid);
    let mut out_c = Field::zeros(&grid, Location::Centre);
    let mut out_u = Field::zeros(&grid, Location::XFace);
    let mut out_v = Field::zeros(&grid, Location::YFace);
    let mut dxy = Field::zeros(&grid, Location::Node);
    let mut dyy = Field::zeros(&grid, Location::Centre);
    let mut eta_c = Field::zeros(&grid, Location::Centre);
    eta_c.fill(0.1);
    let mut eta_n = Field::zeros(&grid, Location::Node);
    eta_n.fill(0.1);
    let mut g = c.benchmark_group("operators_1280x256");
    g.sample_size(20).measurement_time(Duration::from_secs(2)).warm_up_time(Duration::from_millis(500));
    g.throughput(Throughput::Elements(grid.cells() as u64));
    for threads in [1usize, 2] {
        let pool = build_pool(threads).unwrap();
        let exec = Exec::with_threads(threads);
        g.bench_with_input(BenchmarkId::new("divergence", threads), &threads, |b, _| {
            pool.install(|| b.iter(|| divergence(black_box(&u), &v, &grid, &mut out_c, exec)))
        });
        g.bench_with_input(BenchmarkId::new("viscous", threads), &threads, |b, _| {
            pool.install(|| b.iter(|| viscous(black_box(&u), &v, &eta_c, &eta_n, &grid, &mut out_u, &mut out_v, exec)))
        });
        g.bench_with_input(BenchmarkId::new("convection", threads), &threads, |b, _| {
            pool.install(|| b.iter(|| convection(black_box(&u), &v, &grid, &mut out_u, &mut out_v, exec)))
        });
        g.bench_with_input(BenchmarkId::new("strain_rate", threads), &threads, |b, _| {
            pool.install(|| b.iter(|| strain_rate(black_box(&u), &v, &grid, &mut out_c, &mut dyy, &mut dxy, exec)))
        });
    }
    g.finish();
}

/// One full two-phase Navier–Stokes step (no rheology) on the paper's grid: heavy column under air.
fn full_step(c: &mut Criterion) {
    let mut g = c.benchmark_group("ns_step_1280x256");
    g.sample_size(10).measurement_time(Duration::from_secs(5)).warm_up_time(Duration::from_secs(1));
    let grid = paper_grid();
    g.throughput(Throughput::Elements(grid.cells() as u64));
    for threads in [1usize, 2] {
        let bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(granrs_core::Side::Top, VelocityBc::Outflow);
        let mut cfg = ModelConfig::single_phase(grid.clone(), bc, Material { density: 1450.0, viscosity: 0.1 });
        cfg.light = Some(Material { density: 1.0, viscosity: 2e-5 });
        cfg.gravity = [0.0, -9.81];
        cfg.threads = threads;
        cfg.time.fixed_dt = Some(2e-4);
        let mut m = TwoPhaseModel::new(cfg).unwrap();
        m.phi = Field::from_fn(&grid, Location::Centre, |x, y| (0.2 - x).min(0.4 - y));
        m.fields_changed();
        m.initialise_pressure().unwrap();
        for _ in 0..5 {
            m.step().unwrap();
        }
        g.bench_with_input(BenchmarkId::new("step", threads), &threads, |b, _| b.iter(|| m.step().unwrap()));
    }
    g.finish();
}

/// STREAM-like triad a = b + s·c on 2.6 MB arrays (one field of the paper's grid: L3-resident on
/// this machine) and on 64 MB arrays (DRAM). Throughput counts 24 bytes per element.
fn triad(c: &mut Criterion) {
    let mut g = c.benchmark_group("stream_triad");
    g.sample_size(20).measurement_time(Duration::from_secs(2)).warm_up_time(Duration::from_millis(500));
    for n in [1290 * 262usize, 8 << 20] {
        let b_arr: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let c_arr: Vec<f64> = (0..n).map(|i| 1.0 / (1.0 + i as f64)).collect();
        let mut a_arr = vec![0.0; n];
        g.throughput(Throughput::Bytes((24 * n) as u64));
        for threads in [1usize, 2] {
            let pool = build_pool(threads).unwrap();
            g.bench_with_input(BenchmarkId::new(format!("n{n}"), threads), &threads, |bch, _| {
                pool.install(|| {
                    bch.iter(|| {
                        a_arr.par_chunks_mut(1 << 14).zip(b_arr.par_chunks(1 << 14)).zip(c_arr.par_chunks(1 << 14)).for_each(|((a, b), c)| {
                            for k in 0..a.len() {
                                a[k] = b[k] + 3.0 * c[k];
                            }
                        });
                        black_box(&a_arr);
                    })
                })
            });
        }
    }
    g.finish();
}

/// One row sweep x ← 0.999 x + 0.001 y + 0.0005 z ([`Exec::for_each_row`], rows of 512 values)
/// from 4 096 to 262 144 cells (96 KiB to 6 MiB of the three arrays), on 1 and 2 threads, with
/// the pool's threads kept awake as during a step ([`with_active_workers`]). The step's sweeps
/// have this granularity: at t = 1.5 s the column's active window holds about 9 400 cells at
/// ny = 64 and 122 000 at ny = 256. Throughput counts cells.
fn sweep_size(c: &mut Criterion) {
    let mut g = c.benchmark_group("sweep_size");
    g.sample_size(30).measurement_time(Duration::from_secs(1)).warm_up_time(Duration::from_millis(300));
    const NX: usize = 512;
    for cells in [4096usize, 8192, 16384, 32768, 65536, 131072, 262144] {
        let y: Vec<f64> = (0..cells).map(|i| (i as f64 * 0.37).sin()).collect();
        let z: Vec<f64> = (0..cells).map(|i| (i as f64 * 0.11).cos()).collect();
        let mut x = vec![1.0; cells];
        g.throughput(Throughput::Elements(cells as u64));
        for threads in [1usize, 2] {
            let pool = build_pool(threads).unwrap();
            let exec = Exec::with_threads(threads);
            g.bench_with_input(BenchmarkId::new(format!("cells{cells}"), threads), &threads, |bch, _| {
                pool.install(|| {
                    with_active_workers(|| {
                        bch.iter(|| {
                            exec.for_each_row(&mut x, NX, |j, row| {
                                let (yr, zr) = (&y[j * NX..(j + 1) * NX], &z[j * NX..(j + 1) * NX]);
                                for i in 0..row.len() {
                                    row[i] = 0.999 * row[i] + 0.001 * yr[i] + 0.0005 * zr[i];
                                }
                            });
                            black_box(&x);
                        })
                    })
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, operators, full_step, triad, sweep_size);
criterion_main!(benches);
