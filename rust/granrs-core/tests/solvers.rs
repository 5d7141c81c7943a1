//! Tests of the pressure-equation solvers (`granrs_core::solvers`): discretisation order,
//! multigrid-CG iteration counts (constant coefficients and a 1450:1 density jump), agreement with
//! the sparse direct solver, serial == parallel, warm start and input validation.
//!
//! Heavy: run with `cargo test --release -p granrs-core --test solvers -- --nocapture` to see
//! the tables. The V/W-cycle and smoothing comparison compares with the stored table
//! `tests/ref/multigrid_cycles.ref`; `GRANRS_BLESS=1` writes it instead.

use std::f64::consts::PI;

#[path = "common/reftable.rs"]
mod reftable;
use reftable::{Column, Tol};

use granrs_core::solvers::{Cycle, PoissonSolver, PressureSolverKind, SolveInfo, SolverSettings};
use granrs_core::{Error, Exec, PressureBc};

const N: PressureBc = PressureBc::Neumann;
const D: PressureBc = PressureBc::Dirichlet;
/// All sides Neumann (singular).
const ALL_NEUMANN: [PressureBc; 4] = [N, N, N, N];
/// Top Dirichlet (outflow), other sides walls: the production configuration.
const TOP_DIRICHLET: [PressureBc; 4] = [N, N, N, D];

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// Face coefficients from a function β(x, y) sampled at face centres.
fn faces_from_fn(nx: usize, ny: usize, dx: f64, dy: f64, beta: impl Fn(f64, f64) -> f64) -> (Vec<f64>, Vec<f64>) {
    let mut bx = vec![0.0; ny * (nx + 1)];
    for j in 0..ny {
        for i in 0..=nx {
            bx[j * (nx + 1) + i] = beta(i as f64 * dx, (j as f64 + 0.5) * dy);
        }
    }
    let mut by = vec![0.0; (ny + 1) * nx];
    for j in 0..=ny {
        for i in 0..nx {
            by[j * nx + i] = beta((i as f64 + 0.5) * dx, j as f64 * dy);
        }
    }
    (bx, by)
}

/// Face coefficients β = 1/ρ from cell densities: harmonic mean of the two cells' β (that is,
/// 1 / arithmetic mean of ρ); boundary faces take the adjacent cell's value.
fn faces_from_density(nx: usize, ny: usize, rho: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let face = |a: f64, b: f64| 2.0 / (a + b);
    let mut bx = vec![0.0; ny * (nx + 1)];
    for j in 0..ny {
        for i in 0..=nx {
            let l = rho[j * nx + i.saturating_sub(1)];
            let r = rho[j * nx + i.min(nx - 1)];
            bx[j * (nx + 1) + i] = face(l, r);
        }
    }
    let mut by = vec![0.0; (ny + 1) * nx];
    for j in 0..=ny {
        for i in 0..nx {
            let s = rho[j.saturating_sub(1) * nx + i];
            let n = rho[j.min(ny - 1) * nx + i];
            by[j * nx + i] = face(s, n);
        }
    }
    (bx, by)
}

/// The density field of the column-collapse case: ρ = 1450 in the column x < 0.2, y < 0.4 and in a
/// thin layer y < 0.05 over the whole channel, ρ = 1 (air) elsewhere. Neither interface is
/// aligned with any grid level (0.2/dx = 113.8, 0.4/dy = 227.6, 0.05/dy = 28.4 at 1280 × 256).
fn column_density(nx: usize, ny: usize, dx: f64, dy: f64) -> Vec<f64> {
    let mut rho = vec![1.0; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = ((i as f64 + 0.5) * dx, (j as f64 + 0.5) * dy);
            if (x < 0.2 && y < 0.4) || y < 0.05 {
                rho[j * nx + i] = 1450.0;
            }
        }
    }
    rho
}

/// f = discrete divergence of a smooth face field (u, v) whose normal component vanishes on the
/// boundary, as in a projection (its sum is exactly 0, so it suits the singular case too).
fn divergence_rhs(nx: usize, ny: usize, lx: f64, ly: f64) -> Vec<f64> {
    let (dx, dy) = (lx / nx as f64, ly / ny as f64);
    let u = |x: f64, y: f64| (PI * x / lx).sin() * (3.0 * PI * y / ly).cos() + 0.3 * (4.0 * PI * x / lx).sin();
    let v = |x: f64, y: f64| (PI * y / ly).sin() * (5.0 * PI * x / lx).cos() * (1.0 + y / ly);
    let mut f = vec![0.0; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let (xc, yc) = ((i as f64 + 0.5) * dx, (j as f64 + 0.5) * dy);
            let du = u((i + 1) as f64 * dx, yc) - u(i as f64 * dx, yc);
            let dv = v(xc, (j + 1) as f64 * dy) - v(xc, j as f64 * dy);
            f[j * nx + i] = du / dx + dv / dy;
        }
    }
    f
}

/// Deterministic pseudo-random numbers in [−1, 1) (xorshift64*).
fn random_vec(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s ^= s >> 12;
            s ^= s << 25;
            s ^= s >> 27;
            let r = s.wrapping_mul(0x2545_F491_4F6C_DD1D);
            (r >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        })
        .collect()
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    norm(&d) / norm(b)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// ‖f − L p‖₂ / ‖f‖₂ computed with `apply` (independent of the solver's own residual).
fn true_residual(solver: &PoissonSolver, f: &[f64], p: &[f64], singular: bool) -> f64 {
    let mut lp = vec![0.0; p.len()];
    solver.apply(p, &mut lp, Exec::SERIAL);
    let m = if singular { mean(f) } else { 0.0 };
    let r: Vec<f64> = f.iter().zip(&lp).map(|(fv, l)| fv - m - l).collect();
    let fm: Vec<f64> = f.iter().map(|fv| fv - m).collect();
    norm(&r) / norm(&fm)
}

fn settings(kind: PressureSolverKind, rtol: f64) -> SolverSettings {
    SolverSettings { kind, rtol, ..SolverSettings::default() }
}

/// Solves L p = f from p = 0 with MGCG; returns (p, info).
#[allow(clippy::too_many_arguments)]
fn mgcg_solve(
    nx: usize,
    ny: usize,
    dx: f64,
    dy: f64,
    bc: [PressureBc; 4],
    beta: (&[f64], &[f64]),
    f: &[f64],
    s: SolverSettings,
) -> (Vec<f64>, SolveInfo, PoissonSolver) {
    let mut solver = PoissonSolver::new(nx, ny, dx, dy, bc, s).unwrap();
    solver.set_coefficients(beta.0, beta.1, Exec::SERIAL).unwrap();
    let mut p = vec![0.0; nx * ny];
    let info = solver.solve(f, &mut p, Exec::SERIAL).unwrap();
    (p, info, solver)
}

// ---------------------------------------------------------------------------------------------
// 1. Manufactured solutions: second-order convergence with a smooth variable β
// ---------------------------------------------------------------------------------------------

/// Smooth coefficient with a 3:1 variation: β = 2 + sin(πx) cos(2πy).
fn beta_smooth(x: f64, y: f64) -> f64 {
    2.0 + (PI * x).sin() * (2.0 * PI * y).cos()
}

fn grad_beta_smooth(x: f64, y: f64) -> (f64, f64) {
    (PI * (PI * x).cos() * (2.0 * PI * y).cos(), -2.0 * PI * (PI * x).sin() * (2.0 * PI * y).sin())
}

/// RMS error of the discrete solution against `exact` on the unit square with n × n cells.
/// `exact` returns (p, ∂p/∂x, ∂p/∂y, Δp); f = β Δp + ∇β·∇p is sampled at cell centres.
fn manufactured_error(n: usize, bc: [PressureBc; 4], kind: PressureSolverKind, exact: impl Fn(f64, f64) -> [f64; 4]) -> f64 {
    let h = 1.0 / n as f64;
    let (bx, by) = faces_from_fn(n, n, h, h, beta_smooth);
    let mut f = vec![0.0; n * n];
    let mut pe = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..n {
            let (x, y) = ((i as f64 + 0.5) * h, (j as f64 + 0.5) * h);
            let [p, px, py, lap] = exact(x, y);
            let (gx, gy) = grad_beta_smooth(x, y);
            f[j * n + i] = beta_smooth(x, y) * lap + gx * px + gy * py;
            pe[j * n + i] = p;
        }
    }
    let singular = bc.iter().all(|&b| b == N);
    // rtol 1e-12: the algebraic error is far below the O(h²) discretisation error.
    let (mut p, info, solver) = mgcg_solve(n, n, h, h, bc, (&bx, &by), &f, settings(kind, 1e-12));
    // MGCG guarantees its tolerance; the direct solve is exact up to rounding (≈ cond(A) ε).
    let tol = if kind == PressureSolverKind::Direct { 1e-10 } else { 1e-12 };
    assert!(info.residual <= tol, "residual {info:?}");
    assert!(true_residual(&solver, &f, &p, singular) < 1e-11, "apply and solve disagree");
    if singular {
        // Solutions are defined up to a constant: compare zero-mean representatives.
        assert!(mean(&p).abs() < 1e-12, "singular solution does not have zero mean: {}", mean(&p));
        let m = mean(&pe);
        pe.iter_mut().for_each(|v| *v -= m);
        let m = mean(&p);
        p.iter_mut().for_each(|v| *v -= m);
    }
    let d: Vec<f64> = p.iter().zip(&pe).map(|(a, b)| a - b).collect();
    norm(&d) / n as f64
}

fn check_second_order(name: &str, bc: [PressureBc; 4], exact: impl Fn(f64, f64) -> [f64; 4] + Copy) {
    for kind in [PressureSolverKind::MultigridCg, PressureSolverKind::Direct] {
        let errors: Vec<f64> = [32, 64, 128].iter().map(|&n| manufactured_error(n, bc, kind, exact)).collect();
        let orders = [(errors[0] / errors[1]).log2(), (errors[1] / errors[2]).log2()];
        let shown: Vec<String> = errors.iter().map(|e| format!("{e:.3e}")).collect();
        println!("{name} ({kind:?}): RMS errors n=32,64,128: {shown:?}, observed orders {orders:.3?}");
        // The scheme is second order; 1.9 leaves room for the pre-asymptotic regime at n = 32
        // while still failing for any first-order boundary or coefficient treatment.
        for o in orders {
            assert!(o >= 1.9, "{name} ({kind:?}): observed order {o:.3} < 1.9 (errors {errors:?})");
        }
    }
}

#[test]
fn manufactured_solution_all_neumann_is_second_order() {
    // p = cos(πx) cos(πy): ∂p/∂n = 0 on every side.
    check_second_order("all Neumann, p = cos(πx)cos(πy)", ALL_NEUMANN, |x, y| {
        let (c, s, cy, sy) = ((PI * x).cos(), (PI * x).sin(), (PI * y).cos(), (PI * y).sin());
        [c * cy, -PI * s * cy, -PI * c * sy, -2.0 * PI * PI * c * cy]
    });
}

#[test]
fn manufactured_solution_top_dirichlet_is_second_order() {
    // p = cos(πx) cos(πy/2): ∂p/∂n = 0 left, right, bottom; p = 0 on the top.
    check_second_order("top Dirichlet, p = cos(πx)cos(πy/2)", TOP_DIRICHLET, |x, y| {
        let (c, s, cy, sy) = ((PI * x).cos(), (PI * x).sin(), (0.5 * PI * y).cos(), (0.5 * PI * y).sin());
        [c * cy, -PI * s * cy, -0.5 * PI * c * sy, -1.25 * PI * PI * c * cy]
    });
}

#[test]
fn manufactured_solution_all_dirichlet_is_second_order() {
    // p = sin(πx) sin(πy): p = 0 on every side.
    check_second_order("all Dirichlet, p = sin(πx)sin(πy)", [D, D, D, D], |x, y| {
        let (c, s, cy, sy) = ((PI * x).cos(), (PI * x).sin(), (PI * y).cos(), (PI * y).sin());
        [s * sy, PI * c * sy, PI * s * cy, -2.0 * PI * PI * s * sy]
    });
}

// ---------------------------------------------------------------------------------------------
// 2. Iteration counts with constant coefficients
// ---------------------------------------------------------------------------------------------

fn constant_counts(bc: [PressureBc; 4], random: bool) -> Vec<usize> {
    let mut counts = Vec::new();
    for n in [128, 256, 512, 1024] {
        let h = 1.0 / n as f64;
        let (bx, by) = (vec![1.0; n * (n + 1)], vec![1.0; (n + 1) * n]);
        let f = if random { random_vec(n * n, n as u64) } else { divergence_rhs(n, n, 1.0, 1.0) };
        let (_, info, _) = mgcg_solve(n, n, h, h, bc, (&bx, &by), &f, SolverSettings::default());
        assert!(info.residual <= 1e-8);
        counts.push(info.iterations);
    }
    counts
}

#[test]
fn iteration_counts_constant_coefficients_are_small_and_mesh_independent() {
    println!("MGCG iterations to ‖f − Lp‖/‖f‖ ≤ 1e-8, β = 1, p0 = 0");
    println!("{:<28} {:>6} {:>6} {:>6} {:>6}", "case", "128²", "256²", "512²", "1024²");
    for (name, bc) in [("all Neumann (singular)", ALL_NEUMANN), ("top Dirichlet", TOP_DIRICHLET)] {
        for random in [true, false] {
            let c = constant_counts(bc, random);
            let label = format!("{name}, {}", if random { "random f" } else { "smooth f" });
            println!("{label:<28} {:>6} {:>6} {:>6} {:>6}", c[0], c[1], c[2], c[3]);
            // Multigrid preconditioning makes the count independent of the mesh: ≤ 15 and a
            // spread of at most 3 over an 8× refinement (plain CG would grow 8×).
            let (lo, hi) = (*c.iter().min().unwrap(), *c.iter().max().unwrap());
            assert!(hi <= 15, "{label}: {c:?}");
            assert!(hi - lo <= 3, "{label}: spread {c:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 3. Density jump 1450:1 on the column-collapse grid
// ---------------------------------------------------------------------------------------------

const JUMP_NX: usize = 1280;
const JUMP_NY: usize = 256;
const JUMP_LX: f64 = 2.25;
const JUMP_LY: f64 = 0.45;

fn jump_counts(bc: [PressureBc; 4]) -> (SolveInfo, SolveInfo) {
    let (nx, ny, lx, ly) = (JUMP_NX, JUMP_NY, JUMP_LX, JUMP_LY);
    let (dx, dy) = (lx / nx as f64, ly / ny as f64);
    let f = divergence_rhs(nx, ny, lx, ly);
    let rho = column_density(nx, ny, dx, dy);
    let (bx, by) = faces_from_density(nx, ny, &rho);
    let (p, jump, solver) = mgcg_solve(nx, ny, dx, dy, bc, (&bx, &by), &f, SolverSettings::default());
    let singular = bc == ALL_NEUMANN;
    // Independent check of the reported residual (tolerance 1e-8 plus rounding of the check).
    assert!(true_residual(&solver, &f, &p, singular) < 1.5e-8);
    let (cx, cy) = (vec![1.0; ny * (nx + 1)], vec![1.0; (ny + 1) * nx]);
    let (_, constant, _) = mgcg_solve(nx, ny, dx, dy, bc, (&cx, &cy), &f, SolverSettings::default());
    (jump, constant)
}

#[test]
fn density_jump_converges_like_constant_coefficients() {
    println!("1280 × 256, 2.25 m × 0.45 m, ρ = 1450 (column x<0.2, y<0.4 and layer y<0.05) / 1 (air)");
    println!("{:<24} {:>10} {:>10}", "bc", "jump", "β = 1");
    for (name, bc) in [("top Dirichlet", TOP_DIRICHLET), ("all Neumann (singular)", ALL_NEUMANN)] {
        let (jump, constant) = jump_counts(bc);
        println!("{name:<24} {:>10} {:>10}", jump.iterations, constant.iterations);
        // Required: ≤ 15 iterations to 1e-8 despite the 1450:1 jump, and within ±3 of the
        // constant-coefficient count on the same grid and right-hand side.
        assert!(jump.residual <= 1e-8);
        assert!(jump.iterations <= 15, "{name}: {} iterations with the jump", jump.iterations);
        assert!(jump.iterations.abs_diff(constant.iterations) <= 3, "{name}: jump {} vs constant {}", jump.iterations, constant.iterations);
    }
}

// ---------------------------------------------------------------------------------------------
// 4. MGCG agrees with the direct solver
// ---------------------------------------------------------------------------------------------

#[test]
fn multigrid_cg_agrees_with_direct() {
    let n = 64;
    let h = 1.0 / n as f64;
    let f = random_vec(n * n, 7);
    // Smooth 3:1 coefficient, and a 1450:1 jump (a disc of dense material).
    let smooth = faces_from_fn(n, n, h, h, beta_smooth);
    let mut rho = vec![1.0; n * n];
    for j in 0..n {
        for i in 0..n {
            let (x, y) = ((i as f64 + 0.5) * h - 0.4, (j as f64 + 0.5) * h - 0.3);
            if x * x + y * y < 0.2 * 0.2 {
                rho[j * n + i] = 1450.0;
            }
        }
    }
    let jump = faces_from_density(n, n, &rho);
    for (name, (bx, by)) in [("smooth β", &smooth), ("β jump 1450:1", &jump)] {
        for bc in [ALL_NEUMANN, TOP_DIRICHLET, [D, N, D, N]] {
            let (pd, infod, _) = mgcg_solve(n, n, h, h, bc, (bx, by), &f, settings(PressureSolverKind::Direct, 1e-8));
            // rtol 1e-12 for MGCG: the error is ≤ cond(A) × 1e-12 ≈ 1e-12 × 4n²/π² × 1450 ≈ 2e-6
            // in the worst case, typically far less; the check is 1e-7 relative as required.
            assert_eq!(infod.iterations, 1);
            assert!(infod.residual < 1e-10, "direct residual {}", infod.residual);
            // Both cycles are valid (symmetric) preconditioners and must reach the same solution.
            for cycle in [Cycle::W, Cycle::V] {
                let s = SolverSettings { rtol: 1e-12, cycle, ..SolverSettings::default() };
                let (pm, infom, _) = mgcg_solve(n, n, h, h, bc, (bx, by), &f, s);
                let d = rel_diff(&pm, &pd);
                println!("{name}, bc {bc:?}, {cycle:?}-cycle: ‖p_mg − p_direct‖/‖p_direct‖ = {d:.2e} ({} its)", infom.iterations);
                assert!(d < 1e-7, "{name} {bc:?} {cycle:?}: MGCG and direct differ by {d:e}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 5. Serial == parallel
// ---------------------------------------------------------------------------------------------

#[test]
fn serial_and_parallel_solutions_are_bit_identical() {
    let (nx, ny) = (256, 128);
    let (dx, dy) = (2.0 / nx as f64, 1.0 / ny as f64);
    let rho = column_density(nx, ny, dx * 0.5, dy * 0.4);
    let (bx, by) = faces_from_density(nx, ny, &rho);
    let f = random_vec(nx * ny, 3);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    for bc in [ALL_NEUMANN, TOP_DIRICHLET] {
        let run = |exec: Exec| -> (Vec<f64>, SolveInfo) {
            let mut solver = PoissonSolver::new(nx, ny, dx, dy, bc, SolverSettings::default()).unwrap();
            solver.set_coefficients(&bx, &by, exec).unwrap();
            let mut p = vec![0.0; nx * ny];
            let info = solver.solve(&f, &mut p, exec).unwrap();
            (p, info)
        };
        let (ps, is) = run(Exec::SERIAL);
        let (pp, ip) = pool.install(|| run(Exec { parallel: true }));
        // Work is split in fixed row blocks, reductions are summed in block order and the
        // red–black smoother is order-independent within a colour: the results must be
        // bit-identical, not merely close (the required 1e-12 is implied).
        assert_eq!(is, ip, "{bc:?}: solve info differs");
        assert!(ps.iter().zip(&pp).all(|(a, b)| a.to_bits() == b.to_bits()), "{bc:?}: solutions differ");
        assert!(is.iterations > 3, "the problem is too easy to test anything");
    }
}

/// A free-surface system as the granular-only model and the pore pressure build it: a deposit
/// (a column collapsing into a thin tail), a detached 2 × 2 blob of grains, an air pocket in the
/// deposit; faces with air on either side carry β = 0, air cells the trivial row σ p = 0 with
/// σ = 1, grains a shift σ = 50 and β = 1 + ½ sin(x) cos(y). Returns (β_x, β_y, σ, grains).
fn free_surface_system(nx: usize, ny: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<bool>) {
    let grain = |i: usize, j: usize| -> bool {
        let (x, y) = ((i as f64 + 0.5) / nx as f64, (j as f64 + 0.5) / ny as f64);
        let deposit = y < 0.6 * (-6.0 * x).exp() + 0.04 && x < 0.8;
        let blob = (nx / 2 + 6..nx / 2 + 8).contains(&i) && (ny / 2..ny / 2 + 2).contains(&j);
        let pocket = (2..4).contains(&i) && (1..3).contains(&j);
        (deposit && !pocket) || blob
    };
    let g: Vec<bool> = (0..nx * ny).map(|k| grain(k % nx, k / nx)).collect();
    let beta = |i: usize, j: usize| 1.0 + 0.5 * (0.37 * i as f64).sin() * (0.71 * j as f64).cos();
    let mut bx = vec![0.0; ny * (nx + 1)];
    for j in 0..ny {
        for i in 1..nx {
            if g[j * nx + i - 1] && g[j * nx + i] {
                bx[j * (nx + 1) + i] = beta(i, j);
            }
        }
    }
    let mut by = vec![0.0; (ny + 1) * nx];
    for j in 1..ny {
        for i in 0..nx {
            if g[(j - 1) * nx + i] && g[j * nx + i] {
                by[j * nx + i] = beta(i, j);
            }
        }
    }
    let sigma = g.iter().map(|&x| if x { 50.0 } else { 1.0 }).collect();
    (bx, by, sigma, g)
}

/// The iterates of MGCG on the system of [`free_surface_system`] with the cycle on the rows'
/// spans or on whole rows: (solution with −0 read as +0, as bits; the solve's info).
fn free_surface_solve(nx: usize, ny: usize, f: &[f64], spans: bool, exec: Exec) -> (Vec<u64>, SolveInfo) {
    let (bx, by, sigma, _) = free_surface_system(nx, ny);
    let mut solver = PoissonSolver::new_shifted(nx, ny, 1.0 / ny as f64, 1.0 / ny as f64, [N, N, N, N], SolverSettings::default()).unwrap();
    solver.set_cycle_spans(spans);
    solver.set_coefficients_with_shift(&bx, &by, &sigma, exec).unwrap();
    let mut p = vec![0.0; nx * ny];
    let info = solver.solve(f, &mut p, exec).unwrap();
    (p.iter().map(|v| (v + 0.0).to_bits()).collect(), info)
}

#[test]
fn the_cycle_on_the_spans_of_a_free_surface_gives_the_whole_rows_iterates() {
    // The air cells are isolated (no coupling) with a zero right-hand side: the cycle skips
    // them and must reproduce the iterates of the cycle on whole rows bit for bit (up to the
    // sign of a zero), serially and on two threads, including a blob of 2 × 2 grains whose
    // coarse cell is isolated but whose children are not, and grids that do not halve evenly.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    for (nx, ny) in [(256, 64), (200, 36), (96, 96)] {
        let (_, _, _, grains) = free_surface_system(nx, ny);
        let f: Vec<f64> = random_vec(nx * ny, 11).iter().zip(&grains).map(|(v, &g)| if g { *v } else { 0.0 }).collect();
        let (want, want_info) = free_surface_solve(nx, ny, &f, false, Exec::SERIAL);
        assert!(want_info.iterations > 3, "{nx}×{ny}: the problem is too easy to test anything");
        for (spans, exec) in [(true, Exec::SERIAL), (true, Exec::with_threads(2)), (false, Exec::with_threads(2))] {
            let (got, info) = pool.install(|| free_surface_solve(nx, ny, &f, spans, exec));
            assert_eq!(info, want_info, "{nx}×{ny}, spans {spans}, {exec:?}: solve info differs");
            assert!(got == want, "{nx}×{ny}, spans {spans}, {exec:?}: solutions differ");
        }
        // a source in an isolated air cell: the spans do not apply (the cell's x = b/σ is not
        // zero), and the solve must still be that of whole rows
        let mut g = f.clone();
        let air = grains.iter().rposition(|&x| !x).unwrap();
        g[air] = 1.0;
        let (want, want_info) = free_surface_solve(nx, ny, &g, false, Exec::SERIAL);
        let (got, info) = free_surface_solve(nx, ny, &g, true, Exec::SERIAL);
        assert_eq!(info, want_info, "{nx}×{ny}, source in the air");
        assert!(got == want, "{nx}×{ny}, source in the air: solutions differ");
        // the air cell's equation −σ p = b stands alone (σ = 1): its error is its residual,
        // at most the solve's ‖r‖ ≤ rtol ‖b‖
        let bound = SolverSettings::default().rtol * norm(&g);
        assert!((f64::from_bits(got[air]) + g[air]).abs() <= bound, "{nx}×{ny}: the air cell holds p = −b/σ");
    }
}

// ---------------------------------------------------------------------------------------------
// 6. Warm start, trivial right-hand sides and input validation
// ---------------------------------------------------------------------------------------------

#[test]
fn warm_start_needs_at_most_one_iteration() {
    let (nx, ny) = (256, 128);
    let (dx, dy) = (2.0 / nx as f64, 1.0 / ny as f64);
    let rho = column_density(nx, ny, dx * 0.5, dy * 0.4);
    let (bx, by) = faces_from_density(nx, ny, &rho);
    let f = divergence_rhs(nx, ny, 2.0, 1.0);
    for bc in [ALL_NEUMANN, TOP_DIRICHLET] {
        let mut solver = PoissonSolver::new(nx, ny, dx, dy, bc, SolverSettings::default()).unwrap();
        solver.set_coefficients(&bx, &by, Exec::SERIAL).unwrap();
        let mut p = vec![0.0; nx * ny];
        let first = solver.solve(&f, &mut p, Exec::SERIAL).unwrap();
        let second = solver.solve(&f, &mut p, Exec::SERIAL).unwrap();
        println!("{bc:?}: cold {} iterations, warm {} (initial residual {:.1e})", first.iterations, second.iterations, second.initial_residual);
        assert!(first.iterations > 3);
        // The previous solution already satisfies the tolerance (residual ≤ 1e-8).
        assert!(second.iterations <= 1, "warm start took {} iterations", second.iterations);
        assert!(second.initial_residual <= 1e-8);
    }
}

#[test]
fn zero_and_constant_rhs_give_zero_pressure() {
    let n = 32;
    let h = 1.0 / n as f64;
    let mut solver = PoissonSolver::new(n, n, h, h, ALL_NEUMANN, SolverSettings::default()).unwrap();
    assert!(solver.is_singular());
    let mut p = vec![1.0; n * n];
    let info = solver.solve(&vec![0.0; n * n], &mut p, Exec::SERIAL).unwrap();
    assert_eq!(info.iterations, 0);
    assert!(p.iter().all(|&v| v == 0.0));
    // A constant f is incompatible with all-Neumann conditions: its mean is removed (and
    // reported), which leaves f = 0.
    let info = solver.solve(&vec![2.5; n * n], &mut p, Exec::SERIAL).unwrap();
    assert_eq!(info.iterations, 0);
    assert!((info.rhs_mean_removed - 2.5).abs() < 1e-14, "{info:?}");
    assert!(p.iter().all(|&v| v == 0.0));
    let solver = PoissonSolver::new(n, n, h, h, TOP_DIRICHLET, SolverSettings::default()).unwrap();
    assert!(!solver.is_singular());
}

fn param_name(e: Error) -> String {
    match e {
        Error::InvalidParameter { name, .. } => name,
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
}

#[test]
fn invalid_inputs_are_rejected_with_the_parameter_name() {
    let (nx, ny) = (16, 8);
    let h = 1.0 / 16.0;
    let s = SolverSettings::default();
    // Construction.
    assert_eq!(param_name(PoissonSolver::new(0, ny, h, h, TOP_DIRICHLET, s).unwrap_err()), "nx");
    assert_eq!(param_name(PoissonSolver::new(nx, ny, h, f64::NAN, TOP_DIRICHLET, s).unwrap_err()), "dy");
    assert_eq!(param_name(SolverSettings { rtol: 0.0, ..s }.validate().unwrap_err()), "rtol");
    assert_eq!(param_name(SolverSettings { max_iterations: 0, ..s }.validate().unwrap_err()), "max_iterations");
    assert_eq!(param_name(SolverSettings { post_smooth: 3, ..s }.validate().unwrap_err()), "post_smooth");
    assert_eq!(param_name(PoissonSolver::new(nx, ny, h, h, TOP_DIRICHLET, SolverSettings { pre_smooth: 0, post_smooth: 0, ..s }).unwrap_err()), "pre_smooth");

    let mut solver = PoissonSolver::new(nx, ny, h, h, TOP_DIRICHLET, s).unwrap();
    let (mut bx, by) = (vec![1.0; ny * (nx + 1)], vec![1.0; (ny + 1) * nx]);
    // Shapes.
    match solver.set_coefficients(&bx[1..], &by, Exec::SERIAL).unwrap_err() {
        Error::Shape { name, expected, .. } => {
            assert_eq!(name, "beta_x");
            assert_eq!(expected, vec![ny, nx + 1]);
        }
        e => panic!("{e:?}"),
    }
    let mut p = vec![0.0; nx * ny];
    match solver.solve(&vec![0.0; nx * ny + 1], &mut p, Exec::SERIAL).unwrap_err() {
        Error::Shape { name, .. } => assert_eq!(name, "f"),
        e => panic!("{e:?}"),
    }
    // Non-positive and non-finite coefficients name the array and the face.
    bx[3 * (nx + 1) + 5] = -1.0;
    assert_eq!(param_name(solver.set_coefficients(&bx, &by, Exec::SERIAL).unwrap_err()), "beta_x[j=3, i=5]");
    bx[3 * (nx + 1) + 5] = 1.0;
    let mut by_nan = by.clone();
    by_nan[nx] = f64::INFINITY;
    assert_eq!(param_name(solver.set_coefficients(&bx, &by_nan, Exec::SERIAL).unwrap_err()), "beta_y[j=1, i=0]");
    solver.set_coefficients(&bx, &by, Exec::SERIAL).unwrap();
    // Non-finite right-hand side and initial guess.
    let mut f = random_vec(nx * ny, 1);
    f[2 * nx + 7] = f64::NAN;
    assert_eq!(param_name(solver.solve(&f, &mut p, Exec::SERIAL).unwrap_err()), "f[j=2, i=7]");
    f[2 * nx + 7] = 0.0;
    p[0] = f64::NEG_INFINITY;
    assert_eq!(param_name(solver.solve(&f, &mut p, Exec::SERIAL).unwrap_err()), "p[j=0, i=0]");
    p[0] = 0.0;
    // Non-convergence is a typed error with the solver's name, the iterations and the residual.
    let mut tight = PoissonSolver::new(nx, ny, h, h, TOP_DIRICHLET, SolverSettings { max_iterations: 1, ..s }).unwrap();
    tight.set_coefficients(&bx, &by, Exec::SERIAL).unwrap();
    match tight.solve(&f, &mut p, Exec::SERIAL).unwrap_err() {
        Error::NotConverged { solver, iterations, residual, tolerance } => {
            assert_eq!(solver, "multigrid-preconditioned CG");
            assert_eq!(iterations, 1);
            assert!(residual > tolerance && tolerance == 1e-8);
        }
        e => panic!("{e:?}"),
    }
}

#[test]
fn odd_grid_sizes_and_single_level_work() {
    // 45 × 33: no coarsening possible, the "V-cycle" is the exact coarse solve (1 iteration);
    // 48 × 20 coarsens to 12 × 5.
    for (nx, ny) in [(45, 33), (48, 20), (1, 7), (5, 1)] {
        let (dx, dy) = (1.0 / nx as f64, 1.0 / ny as f64);
        let f = random_vec(nx * ny, 11);
        for bc in [ALL_NEUMANN, TOP_DIRICHLET] {
            let (bx, by) = faces_from_fn(nx, ny, dx, dy, beta_smooth);
            let (p, info, solver) = mgcg_solve(nx, ny, dx, dy, bc, (&bx, &by), &f, SolverSettings::default());
            assert!(info.residual <= 1e-8);
            assert!(true_residual(&solver, &f, &p, bc == ALL_NEUMANN) < 1.5e-8, "{nx}×{ny} {bc:?}");
        }
    }
    let s = PoissonSolver::new(48, 20, 0.1, 0.1, TOP_DIRICHLET, SolverSettings::default()).unwrap();
    assert_eq!(s.level_sizes(), vec![(48, 20), (24, 10), (12, 5)]);
    println!("{s}");
}

// ---------------------------------------------------------------------------------------------
// No allocation in solve / apply
// ---------------------------------------------------------------------------------------------

/// Global allocator that counts the allocations made by the current thread.
struct CountingAllocator;

thread_local! {
    static ALLOCATIONS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

// SAFETY: forwards to the system allocator; the counter is a const-initialised thread-local
// `Cell`, which never allocates.
unsafe impl std::alloc::GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (every allocation goes there).
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: `ptr` was allocated by `System` with `layout`; same contract as the caller's.
        unsafe { std::alloc::System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

fn allocations() -> usize {
    ALLOCATIONS.with(|c| c.get())
}

#[test]
fn solve_apply_and_set_coefficients_do_not_allocate() {
    let (nx, ny) = (128, 64);
    let (dx, dy) = (2.0 / nx as f64, 1.0 / ny as f64);
    let rho = column_density(nx, ny, dx * 0.5, dy * 0.4);
    let (bx, by) = faces_from_density(nx, ny, &rho);
    let f = random_vec(nx * ny, 5);
    // The counter does see allocations.
    let a0 = allocations();
    let v = std::hint::black_box(vec![1.0; 10]);
    assert!(allocations() > a0 && v.len() == 10);
    for (kind, bc) in
        [(PressureSolverKind::MultigridCg, ALL_NEUMANN), (PressureSolverKind::MultigridCg, TOP_DIRICHLET), (PressureSolverKind::Direct, ALL_NEUMANN)]
    {
        let mut solver = PoissonSolver::new(nx, ny, dx, dy, bc, settings(kind, 1e-8)).unwrap();
        let mut p = vec![0.0; nx * ny];
        let mut out = vec![0.0; nx * ny];
        let before = allocations();
        solver.set_coefficients(&bx, &by, Exec::SERIAL).unwrap();
        let info = solver.solve(&f, &mut p, Exec::SERIAL).unwrap();
        solver.apply(&p, &mut out, Exec::SERIAL);
        let count = allocations() - before;
        // Work arrays and factorisation workspaces are allocated once in `new`.
        assert_eq!(count, 0, "{kind:?} {bc:?}: {count} allocations in set_coefficients/solve/apply ({info:?})");
    }
}

/// The comparison behind the default settings (W-cycle, ν = 2): PCG iterations to 1e-8 for V/W
/// cycles and ν = 1..3 on the 1280 × 256 density-jump case and with β = 1, for the production
/// boundary conditions (top Dirichlet) and all-Neumann, compared with
/// `tests/ref/multigrid_cycles.ref`. The iteration counts must match exactly: the solver is
/// deterministic (serial == parallel bit for bit, `serial_and_parallel_solutions_are_bit_identical`), and a
/// count that moves by one signals a changed smoother, transfer or cycle. The serial time of one
/// repeated solve is printed beside the counts, not compared (speed lives in `cargo bench -p
/// granrs-core --bench pressure`). About 7 s in release on the 2-core VM. Regenerate the table
/// with `GRANRS_BLESS=1 cargo test --release -p granrs-core --test solvers --
/// compare_cycles_and_smoothing`.
#[test]
fn compare_cycles_and_smoothing() {
    let (nx, ny, lx, ly) = (JUMP_NX, JUMP_NY, JUMP_LX, JUMP_LY);
    let (dx, dy) = (lx / nx as f64, ly / ny as f64);
    let f = divergence_rhs(nx, ny, lx, ly);
    let rho = column_density(nx, ny, dx, dy);
    let (bx, by) = faces_from_density(nx, ny, &rho);
    let (cx, cy) = (vec![1.0; ny * (nx + 1)], vec![1.0; (ny + 1) * nx]);
    let columns = [
        Column { name: "cycle", tol: Tol::Label },
        Column { name: "jump_top_dirichlet", tol: Tol::Exact },
        Column { name: "beta1_top_dirichlet", tol: Tol::Exact },
        Column { name: "jump_all_neumann", tol: Tol::Exact },
        Column { name: "beta1_all_neumann", tol: Tol::Exact },
    ];
    let mut rows = Vec::new();
    for cycle in [Cycle::W, Cycle::V] {
        for nu in 1..=3 {
            let s = SolverSettings { cycle, pre_smooth: nu, post_smooth: nu, ..SolverSettings::default() };
            let mut row = vec![format!("{cycle:?}({nu},{nu})")];
            let mut times = Vec::new();
            for bc in [TOP_DIRICHLET, ALL_NEUMANN] {
                let (_, j, mut solver) = mgcg_solve(nx, ny, dx, dy, bc, (&bx, &by), &f, s);
                let mut p = vec![0.0; nx * ny];
                let t = std::time::Instant::now();
                solver.solve(&f, &mut p, Exec::SERIAL).unwrap();
                times.push(format!("{:.0} ms", t.elapsed().as_secs_f64() * 1e3));
                let (_, c, _) = mgcg_solve(nx, ny, dx, dy, bc, (&cx, &cy), &f, s);
                row.push(j.iterations.to_string());
                row.push(c.iterations.to_string());
            }
            println!("{}: serial solve time of the jump case, top Dirichlet {}, all Neumann {}", row[0], times[0], times[1]);
            rows.push(row);
        }
    }
    let header = [
        "MGCG iterations to a relative residual of 1e-8 from zero, 1280 x 256 cells of a 2.25 m x 0.45 m box: the column's",
        "1450:1 density jump (jump_*) and beta = 1 (beta1_*), top Dirichlet or all Neumann (tests/solvers.rs, compare_cycles_and_smoothing).",
        "Compared exactly. Regenerate: GRANRS_BLESS=1 cargo test --release -p granrs-core --test solvers -- compare_cycles_and_smoothing",
    ];
    reftable::check("multigrid_cycles", &header, &columns, &rows);
}

#[test]
fn harder_density_fields_converge() {
    // Stress cases beyond the required ones, on 512 × 128 (same 2.25 m × 0.45 m box):
    // ρ ratio 2500:1; a slumped column whose interface is a staircase diagonal; 60 dense
    // droplets of 2–6 cells radius floating in air (isolated inclusions give CG near-null
    // modes). Measured 7–8 iterations; the bound of 12 leaves room for rounding-level changes
    // but fails on any loss of robustness (bilinear transfers needed 30–130 on such fields).
    let (nx, ny, lx, ly) = (512, 128, JUMP_LX, JUMP_LY);
    let (dx, dy) = (lx / nx as f64, ly / ny as f64);
    let f = divergence_rhs(nx, ny, lx, ly);
    let cells = |pred: &dyn Fn(f64, f64) -> bool, dense: f64| -> Vec<f64> {
        (0..nx * ny)
            .map(|k| {
                let (x, y) = (((k % nx) as f64 + 0.5) * dx, ((k / nx) as f64 + 0.5) * dy);
                if pred(x, y) {
                    dense
                } else {
                    1.0
                }
            })
            .collect()
    };
    let centres: Vec<(f64, f64, f64)> =
        random_vec(180, 99).chunks(3).map(|c| ((c[0] + 1.0) * 0.5 * lx, (c[1] + 1.0) * 0.5 * ly, (4.0 + 2.0 * c[2]) * dx)).collect();
    let cases: Vec<(&str, Vec<f64>)> = vec![
        ("column, ρ ratio 2500", cells(&|x, y| (x < 0.2 && y < 0.4) || y < 0.05, 2500.0)),
        ("slumped column (diagonal)", cells(&|x, y| y < 0.4 * (1.0 - x / 0.9) || y < 0.02, 1450.0)),
        ("60 droplets", cells(&|x, y| centres.iter().any(|&(cx, cy, r)| (x - cx).powi(2) + (y - cy).powi(2) < r * r), 1450.0)),
    ];
    for (name, rho) in &cases {
        let (bx, by) = faces_from_density(nx, ny, rho);
        for bc in [TOP_DIRICHLET, ALL_NEUMANN] {
            let mut solver = PoissonSolver::new(nx, ny, dx, dy, bc, SolverSettings::default()).unwrap();
            solver.set_coefficients(&bx, &by, Exec::SERIAL).unwrap();
            let mut p = vec![0.0; nx * ny];
            let info = solver.solve(&f, &mut p, Exec::SERIAL).unwrap();
            println!("{name:<28} {bc:?}: {} iterations", info.iterations);
            assert!(true_residual(&solver, &f, &p, bc == ALL_NEUMANN) < 1.5e-8);
            assert!(info.iterations <= 12, "{name} {bc:?}: {} iterations", info.iterations);
        }
    }
}
