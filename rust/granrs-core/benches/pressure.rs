//! Benchmarks of the pressure solver on the column-collapse grid: 1280 × 256 cells on
//! 2.25 m × 0.45 m, ρ = 1450 in the column x < 0.2 m, y < 0.4 m and in a layer y < 0.05 m, ρ = 1
//! elsewhere (β = 1/ρ, harmonic mean at faces), top Dirichlet, other sides Neumann.
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

const NX: usize = 1280;
const NY: usize = 256;
const LX: f64 = 2.25;
const LY: f64 = 0.45;
const BC: [PressureBc; 4] = [PressureBc::Neumann, PressureBc::Neumann, PressureBc::Neumann, PressureBc::Dirichlet];

/// β on faces: 2/(ρ_a + ρ_b) (harmonic mean of the cells' β); boundary faces take the cell's.
fn coefficients() -> (Vec<f64>, Vec<f64>) {
    let (dx, dy) = (LX / NX as f64, LY / NY as f64);
    let rho: Vec<f64> = (0..NX * NY)
        .map(|k| {
            let (x, y) = (((k % NX) as f64 + 0.5) * dx, ((k / NX) as f64 + 0.5) * dy);
            if (x < 0.2 && y < 0.4) || y < 0.05 {
                1450.0
            } else {
                1.0
            }
        })
        .collect();
    let face = |a: f64, b: f64| 2.0 / (a + b);
    let mut bx = vec![0.0; NY * (NX + 1)];
    for j in 0..NY {
        for i in 0..=NX {
            bx[j * (NX + 1) + i] = face(rho[j * NX + i.saturating_sub(1)], rho[j * NX + i.min(NX - 1)]);
        }
    }
    let mut by = vec![0.0; (NY + 1) * NX];
    for j in 0..=NY {
        for i in 0..NX {
            by[j * NX + i] = face(rho[j.saturating_sub(1) * NX + i], rho[j.min(NY - 1) * NX + i]);
        }
    }
    (bx, by)
}

/// f = divergence of a smooth face field with zero normal component on the walls.
fn rhs() -> Vec<f64> {
    let (dx, dy) = (LX / NX as f64, LY / NY as f64);
    let pi = std::f64::consts::PI;
    let u = |x: f64, y: f64| (pi * x / LX).sin() * (3.0 * pi * y / LY).cos();
    let v = |x: f64, y: f64| (pi * y / LY).sin() * (5.0 * pi * x / LX).cos();
    (0..NX * NY)
        .map(|k| {
            let (i, j) = (k % NX, k / NX);
            let (xc, yc) = ((i as f64 + 0.5) * dx, (j as f64 + 0.5) * dy);
            (u((i + 1) as f64 * dx, yc) - u(i as f64 * dx, yc)) / dx + (v(xc, (j + 1) as f64 * dy) - v(xc, j as f64 * dy)) / dy
        })
        .collect()
}

fn solver(settings: SolverSettings, bx: &[f64], by: &[f64]) -> PoissonSolver {
    let mut s = PoissonSolver::new(NX, NY, LX / NX as f64, LY / NY as f64, BC, settings).unwrap();
    s.set_coefficients(bx, by, Exec::SERIAL).unwrap();
    s
}

fn pressure(c: &mut Criterion) {
    let (bx, by) = coefficients();
    let f = rhs();
    let cells = (NX * NY) as u64;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let w = solver(SolverSettings::default(), &bx, &by);
    println!("{w}");
    {
        let mut w = solver(SolverSettings::default(), &bx, &by);
        let mut p = vec![0.0; NX * NY];
        let info = w.solve(&f, &mut p, Exec::SERIAL).unwrap();
        println!("full solve: {} iterations, relative residual {:.2e}", info.iterations, info.residual);
    }

    let mut group = c.benchmark_group("pressure_1280x256_jump");
    group.sample_size(10).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    group.throughput(Throughput::Elements(cells));

    for (label, threads) in [("serial", 1usize), ("2threads", 2)] {
        let exec = Exec::with_threads(threads);
        let run = |f: &mut (dyn FnMut() + Send)| if threads > 1 { pool.install(f) } else { f() };

        let p = rhs();
        let mut out = vec![0.0; NX * NY];
        group.bench_function(format!("apply/{label}"), |b| b.iter(|| run(&mut || w.apply(black_box(&p), &mut out, exec))));

        for (name, cycle) in [("W(2,2)", Cycle::W), ("V(2,2)", Cycle::V)] {
            let mut s = solver(SolverSettings { cycle, ..SolverSettings::default() }, &bx, &by);
            let mut z = vec![0.0; NX * NY];
            group.bench_function(format!("cycle_{name}/{label}"), |b| b.iter(|| run(&mut || s.precondition(black_box(&f), &mut z, exec).unwrap())));
        }

        let mut s = solver(SolverSettings::default(), &bx, &by);
        let mut p = vec![0.0; NX * NY];
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

criterion_group!(benches, pressure);
criterion_main!(benches);
