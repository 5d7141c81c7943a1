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
//! `free_surface_window_1792x72`: the granular-only model's free-surface system on the active
//! window of the paper's grid late in the collapse (h = 1.95 mm, the grains a fifth of the
//! window's cells: a deposit 0.1 m deep at the back wall thinning to 2 cells at x = 3 m):
//! faces with air on either side carry β = 0, air cells the trivial row p = 0 (σ = 1), grains
//! beside the air the ghost-fluid Dirichlet term 2β/h² (the surface half-way between the
//! centres). One MGCG solve to 1e-8 with the cycle and the CG vectors on the rows' spans (the
//! default) and on whole rows (`PoissonSolver::set_cycle_spans(false)`): the same iterates.
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

/// The free-surface system of `free_surface_window_1792x72` (module header).
struct FreeSurface {
    nx: usize,
    ny: usize,
    h: f64,
    bx: Vec<f64>,
    by: Vec<f64>,
    sigma: Vec<f64>,
    /// The right-hand side: on the grains, zero in the air.
    f: Vec<f64>,
}

fn free_surface_window() -> FreeSurface {
    let (nx, ny, h) = (1792, 72, 3.5 / 1792.0);
    let depth = |x: f64| if x < 3.0 { 0.1 * (-1.6 * x).exp() + 2.0 * h } else { 0.0 };
    let grain = |i: usize, j: usize| (j as f64 + 0.5) * h < depth((i as f64 + 0.5) * h);
    let g: Vec<bool> = (0..nx * ny).map(|k| grain(k % nx, k / nx)).collect();
    let mut bx = vec![0.0; ny * (nx + 1)];
    let mut by = vec![0.0; (ny + 1) * nx];
    let mut sigma: Vec<f64> = g.iter().map(|&x| if x { 0.0 } else { 1.0 }).collect();
    let beta = 1.0 / 1450.0;
    for j in 0..ny {
        for i in 0..nx {
            if !g[j * nx + i] {
                continue;
            }
            // the four neighbours: a grain couples, air adds the Dirichlet term
            for (di, dj, face) in [(-1i64, 0i64, j * (nx + 1) + i), (1, 0, j * (nx + 1) + i + 1), (0, -1, j * nx + i), (0, 1, (j + 1) * nx + i)] {
                let (ni, nj) = (i as i64 + di, j as i64 + dj);
                if ni < 0 || nj < 0 || ni >= nx as i64 || nj >= ny as i64 {
                    continue; // a wall: no flux
                }
                if g[nj as usize * nx + ni as usize] {
                    if di != 0 {
                        bx[face] = beta;
                    } else {
                        by[face] = beta;
                    }
                } else {
                    sigma[j * nx + i] += 2.0 * beta / (h * h);
                }
            }
        }
    }
    let f = (0..nx * ny).map(|k| if g[k] { ((k % nx) as f64 * 0.013).sin() + ((k / nx) as f64 * 0.21).cos() } else { 0.0 }).collect();
    FreeSurface { nx, ny, h, bx, by, sigma, f }
}

fn free_surface(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let FreeSurface { nx, ny, h, bx, by, sigma, f } = free_surface_window();
    let grains = sigma.iter().filter(|&&s| s != 1.0).count();
    let mut group = c.benchmark_group("free_surface_window_1792x72");
    group.sample_size(20).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    group.throughput(Throughput::Elements((nx * ny) as u64));
    for (label, threads) in [("serial", 1usize), ("2threads", 2)] {
        let exec = Exec::with_threads(threads);
        let run = |f: &mut (dyn FnMut() + Send)| if threads > 1 { pool.install(f) } else { f() };
        for (name, spans) in [("spans", true), ("whole_rows", false)] {
            let mut s = PoissonSolver::new_shifted(nx, ny, h, h, [PressureBc::Neumann; 4], SolverSettings::default()).unwrap();
            s.set_cycle_spans(spans);
            s.set_coefficients_with_shift(&bx, &by, &sigma, exec).unwrap();
            let mut p = vec![0.0; nx * ny];
            let info = s.solve(&f, &mut p, exec).unwrap();
            if threads == 1 {
                println!("free surface, {name}: {grains} grains of {} cells, {} iterations, relative residual {:.2e}", nx * ny, info.iterations, info.residual);
            }
            group.bench_function(format!("solve_W(2,2)_to_1e-8_{name}/{label}"), |b| {
                b.iter(|| {
                    run(&mut || {
                        p.iter_mut().for_each(|v| *v = 0.0);
                        black_box(s.solve(&f, &mut p, exec).unwrap());
                    })
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, pressure, free_surface);
criterion_main!(benches);
