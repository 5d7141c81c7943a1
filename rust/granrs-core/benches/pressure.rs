//! Benchmarks of the pressure solver on two grids of the column collapse, ρ = 1450 in the column
//! and in a layer on the bed, ρ = 1 elsewhere (β = 1/ρ, harmonic mean at faces), top Dirichlet,
//! other sides Neumann:
//!
//! - `pressure_1280x256_jump`: 1280 × 256 cells on 2.25 m × 0.45 m, the column x < 0.2 m,
//!   y < 0.4 m, the layer y < 0.05 m;
//! - `pressure_window_2048x64_jump`: the active window of the paper's grid (h = 1.76 mm) once the
//!   column has spread, 2048 × 64 cells on 3.6 m × 0.1125 m, the deposit x < 0.2 m, y < 0.08 m
//!   and y < 0.02 m: a wide, low grid whose rows the threads share.
//!
//! Measures one operator application, one preconditioner cycle (W(2,2), the default, and
//! V(2,2)), one full MGCG solve to 1e-8 from p = 0, and `set_coefficients` (coarsening +
//! coarse Cholesky), serially and on a 2-thread pool. Throughput is reported in fine cells per
//! second ("elem/s" = cell updates per second of the whole operation).
//!
//! Run: `cargo bench -p granrs-core --bench pressure`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use granrs_core::solvers::{Cycle, PoissonSolver, SolverSettings};
use granrs_core::{Exec, PressureBc};

const BC: [PressureBc; 4] = [PressureBc::Neumann, PressureBc::Neumann, PressureBc::Neumann, PressureBc::Dirichlet];

/// A grid of `nx × ny` cells on `lx × ly` with the dense column x < `column.0`, y < `column.1`
/// and the layer y < `layer`.
#[derive(Clone, Copy)]
struct Case {
    name: &'static str,
    nx: usize,
    ny: usize,
    lx: f64,
    ly: f64,
    column: (f64, f64),
    layer: f64,
}

const CASES: [Case; 2] = [
    Case { name: "pressure_1280x256_jump", nx: 1280, ny: 256, lx: 2.25, ly: 0.45, column: (0.2, 0.4), layer: 0.05 },
    Case { name: "pressure_window_2048x64_jump", nx: 2048, ny: 64, lx: 3.6, ly: 0.1125, column: (0.2, 0.08), layer: 0.02 },
];

/// β on faces: 2/(ρ_a + ρ_b) (harmonic mean of the cells' β); boundary faces take the cell's.
fn coefficients(c: Case) -> (Vec<f64>, Vec<f64>) {
    let (nx, ny) = (c.nx, c.ny);
    let (dx, dy) = (c.lx / nx as f64, c.ly / ny as f64);
    let rho: Vec<f64> = (0..nx * ny)
        .map(|k| {
            let (x, y) = (((k % nx) as f64 + 0.5) * dx, ((k / nx) as f64 + 0.5) * dy);
            if (x < c.column.0 && y < c.column.1) || y < c.layer {
                1450.0
            } else {
                1.0
            }
        })
        .collect();
    let face = |a: f64, b: f64| 2.0 / (a + b);
    let mut bx = vec![0.0; ny * (nx + 1)];
    for j in 0..ny {
        for i in 0..=nx {
            bx[j * (nx + 1) + i] = face(rho[j * nx + i.saturating_sub(1)], rho[j * nx + i.min(nx - 1)]);
        }
    }
    let mut by = vec![0.0; (ny + 1) * nx];
    for j in 0..=ny {
        for i in 0..nx {
            by[j * nx + i] = face(rho[j.saturating_sub(1) * nx + i], rho[j.min(ny - 1) * nx + i]);
        }
    }
    (bx, by)
}

/// f = divergence of a smooth face field with zero normal component on the walls.
fn rhs(c: Case) -> Vec<f64> {
    let (nx, ny) = (c.nx, c.ny);
    let (dx, dy) = (c.lx / nx as f64, c.ly / ny as f64);
    let pi = std::f64::consts::PI;
    let u = |x: f64, y: f64| (pi * x / c.lx).sin() * (3.0 * pi * y / c.ly).cos();
    let v = |x: f64, y: f64| (pi * y / c.ly).sin() * (5.0 * pi * x / c.lx).cos();
    (0..nx * ny)
        .map(|k| {
            let (i, j) = (k % nx, k / nx);
            let (xc, yc) = ((i as f64 + 0.5) * dx, (j as f64 + 0.5) * dy);
            (u((i + 1) as f64 * dx, yc) - u(i as f64 * dx, yc)) / dx + (v(xc, (j + 1) as f64 * dy) - v(xc, j as f64 * dy)) / dy
        })
        .collect()
}

fn solver(c: Case, settings: SolverSettings, bx: &[f64], by: &[f64]) -> PoissonSolver {
    let mut s = PoissonSolver::new(c.nx, c.ny, c.lx / c.nx as f64, c.ly / c.ny as f64, BC, settings).unwrap();
    s.set_coefficients(bx, by, Exec::SERIAL).unwrap();
    s
}

fn pressure(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    for case in CASES {
        let (nx, ny) = (case.nx, case.ny);
        let (bx, by) = coefficients(case);
        let f = rhs(case);
        let cells = (nx * ny) as u64;
        let w = solver(case, SolverSettings::default(), &bx, &by);
        println!("{w}");
        {
            let mut w = solver(case, SolverSettings::default(), &bx, &by);
            let mut p = vec![0.0; nx * ny];
            let info = w.solve(&f, &mut p, Exec::SERIAL).unwrap();
            println!("full solve: {} iterations, relative residual {:.2e}", info.iterations, info.residual);
        }

        let mut group = c.benchmark_group(case.name);
        group.sample_size(10).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
        group.throughput(Throughput::Elements(cells));

        for (label, threads) in [("serial", 1usize), ("2threads", 2)] {
            let exec = Exec::with_threads(threads);
            let run = |f: &mut (dyn FnMut() + Send)| if threads > 1 { pool.install(f) } else { f() };

            let p = rhs(case);
            let mut out = vec![0.0; nx * ny];
            group.bench_function(format!("apply/{label}"), |b| b.iter(|| run(&mut || w.apply(black_box(&p), &mut out, exec))));

            for (name, cycle) in [("W(2,2)", Cycle::W), ("V(2,2)", Cycle::V)] {
                let mut s = solver(case, SolverSettings { cycle, ..SolverSettings::default() }, &bx, &by);
                let mut z = vec![0.0; nx * ny];
                group.bench_function(format!("cycle_{name}/{label}"), |b| b.iter(|| run(&mut || s.precondition(black_box(&f), &mut z, exec).unwrap())));
            }

            let mut s = solver(case, SolverSettings::default(), &bx, &by);
            let mut p = vec![0.0; nx * ny];
            group.bench_function(format!("solve_W(2,2)_to_1e-8/{label}"), |b| {
                b.iter(|| {
                    run(&mut || {
                        p.iter_mut().for_each(|v| *v = 0.0);
                        black_box(s.solve(&f, &mut p, exec).unwrap());
                    })
                })
            });

            group.bench_function(format!("set_coefficients/{label}"), |b| b.iter(|| run(&mut || s.set_coefficients(black_box(&bx), &by, exec).unwrap())));
        }
        group.finish();
    }
}

criterion_group!(benches, pressure);
criterion_main!(benches);
