//! TEMPORARY stand-in (Jacobi-preconditioned CG) with the public API of the pressure solvers;
//! replaced by the multigrid-preconditioned CG + faer Cholesky implementation.
use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::grid::PressureBc;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveInfo { pub iterations: usize, pub residual: f64, pub initial_residual: f64, pub rhs_mean_removed: f64 }
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PressureSolverKind { MultigridCg, Direct }
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverSettings { pub kind: PressureSolverKind, pub rtol: f64, pub max_iterations: usize, pub pre_smooth: usize, pub post_smooth: usize }
impl Default for SolverSettings {
    fn default() -> Self { SolverSettings { kind: PressureSolverKind::MultigridCg, rtol: 1e-8, max_iterations: 20000, pre_smooth: 2, post_smooth: 2 } }
}
impl SolverSettings { pub fn validate(&self) -> Result<()> { Ok(()) } }
pub struct PoissonSolver { nx: usize, ny: usize, dx: f64, dy: f64, bc: [PressureBc; 4], bx: Vec<f64>, by: Vec<f64>, shift: Vec<f64>, settings: SolverSettings, r: Vec<f64>, z: Vec<f64>, q: Vec<f64>, d: Vec<f64>, diag: Vec<f64> }
impl PoissonSolver {
    pub fn new(nx: usize, ny: usize, dx: f64, dy: f64, bc: [PressureBc; 4], settings: SolverSettings) -> Result<Self> {
        let n = nx * ny;
        Ok(PoissonSolver { nx, ny, dx, dy, bc, bx: vec![1.0; ny * (nx + 1)], by: vec![1.0; (ny + 1) * nx], shift: vec![0.0; n], settings, r: vec![0.0; n], z: vec![0.0; n], q: vec![0.0; n], d: vec![0.0; n], diag: vec![0.0; n] })
    }
    pub fn is_singular(&self) -> bool { self.bc.iter().all(|b| *b == PressureBc::Neumann) && self.shift.iter().all(|&s| s == 0.0) }
    pub fn set_coefficients_with_shift(&mut self, beta_x: &[f64], beta_y: &[f64], shift: &[f64], exec: Exec) -> Result<()> { self.shift.copy_from_slice(shift); self.set_coefficients(beta_x, beta_y, exec) }
    pub fn set_coefficients(&mut self, beta_x: &[f64], beta_y: &[f64], _exec: Exec) -> Result<()> {
        self.bx.copy_from_slice(beta_x); self.by.copy_from_slice(beta_y);
        let (nx, ny) = (self.nx, self.ny);
        for j in 0..ny { for i in 0..nx {
            let mut s = 0.0;
            let w = |b: PressureBc| if b == PressureBc::Dirichlet { 2.0 } else { 0.0 };
            s += if i > 0 { self.bx[j * (nx + 1) + i] } else { w(self.bc[0]) * self.bx[j * (nx + 1)] } / (self.dx * self.dx);
            s += if i + 1 < nx { self.bx[j * (nx + 1) + i + 1] } else { w(self.bc[1]) * self.bx[j * (nx + 1) + nx] } / (self.dx * self.dx);
            s += if j > 0 { self.by[j * nx + i] } else { w(self.bc[2]) * self.by[i] } / (self.dy * self.dy);
            s += if j + 1 < ny { self.by[(j + 1) * nx + i] } else { w(self.bc[3]) * self.by[ny * nx + i] } / (self.dy * self.dy);
            self.diag[j * nx + i] = s + self.shift[j * nx + i];
        }}
        Ok(())
    }
    pub fn apply(&self, p: &[f64], out: &mut [f64], _exec: Exec) {
        let (nx, ny) = (self.nx, self.ny);
        let (ix2, iy2) = (1.0 / (self.dx * self.dx), 1.0 / (self.dy * self.dy));
        for j in 0..ny { for i in 0..nx {
            let c = p[j * nx + i];
            let mut s = 0.0;
            let dir = |b: PressureBc| b == PressureBc::Dirichlet;
            if i > 0 { s += self.bx[j * (nx + 1) + i] * (p[j * nx + i - 1] - c) * ix2 } else if dir(self.bc[0]) { s -= 2.0 * self.bx[j * (nx + 1)] * c * ix2 }
            if i + 1 < nx { s += self.bx[j * (nx + 1) + i + 1] * (p[j * nx + i + 1] - c) * ix2 } else if dir(self.bc[1]) { s -= 2.0 * self.bx[j * (nx + 1) + nx] * c * ix2 }
            if j > 0 { s += self.by[j * nx + i] * (p[(j - 1) * nx + i] - c) * iy2 } else if dir(self.bc[2]) { s -= 2.0 * self.by[i] * c * iy2 }
            if j + 1 < ny { s += self.by[(j + 1) * nx + i] * (p[(j + 1) * nx + i] - c) * iy2 } else if dir(self.bc[3]) { s -= 2.0 * self.by[ny * nx + i] * c * iy2 }
            out[j * nx + i] = s - self.shift[j * nx + i] * c;
        }}
    }
    pub fn solve(&mut self, f: &[f64], p: &mut [f64], exec: Exec) -> Result<SolveInfo> {
        let n = f.len();
        let sing = self.is_singular();
        let mean = if sing { f.iter().sum::<f64>() / n as f64 } else { 0.0 };
        let fnorm = f.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>().sqrt();
        if fnorm == 0.0 { p.fill(0.0); return Ok(SolveInfo { rhs_mean_removed: mean, ..Default::default() }); }
        let mut q = std::mem::take(&mut self.q);
        self.apply(p, &mut q, exec);
        for k in 0..n { self.r[k] = -(f[k] - mean) + q[k]; } // r = b - A x with A = -L, b = -f
        let r0 = self.r.iter().map(|x| x * x).sum::<f64>().sqrt() / fnorm;
        for k in 0..n { self.z[k] = self.r[k] / self.diag[k]; self.d[k] = self.z[k]; }
        let mut rz: f64 = (0..n).map(|k| self.r[k] * self.z[k]).sum();
        let mut it = 0; let mut res = r0;
        while res > self.settings.rtol {
            if it >= self.settings.max_iterations { self.q = q; return Err(Error::NotConverged { solver: "jacobi CG".into(), iterations: it, residual: res, tolerance: self.settings.rtol }); }
            self.apply(&self.d, &mut q, exec);
            let dq: f64 = (0..n).map(|k| -self.d[k] * q[k]).sum();
            let alpha = rz / dq;
            for k in 0..n { p[k] += alpha * self.d[k]; self.r[k] += alpha * q[k]; }
            res = self.r.iter().map(|x| x * x).sum::<f64>().sqrt() / fnorm;
            for k in 0..n { self.z[k] = self.r[k] / self.diag[k]; }
            let rz1: f64 = (0..n).map(|k| self.r[k] * self.z[k]).sum();
            let beta = rz1 / rz; rz = rz1;
            for k in 0..n { self.d[k] = self.z[k] + beta * self.d[k]; }
            it += 1;
        }
        if sing { let m = p.iter().sum::<f64>() / n as f64; p.iter_mut().for_each(|x| *x -= m); }
        self.q = q;
        Ok(SolveInfo { iterations: it, residual: res, initial_residual: r0, rhs_mean_removed: mean })
    }
}
