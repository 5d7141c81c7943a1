//! One grid level of the pressure equation: face coefficients, the five-point operator, the
//! residual and the red–black Gauss–Seidel smoother.
//!
//! The solvers work with A = −L, which is symmetric positive definite (semi-definite when every
//! side is Neumann):
//!
//! (A p)_ij = d_ij p_ij − cx_{i+1,j} p_{i+1,j} − cx_{i,j} p_{i−1,j} − cy_{i,j+1} p_{i,j+1} − cy_{i,j} p_{i,j−1}
//!
//! with the couplings cx_{i,j} = β^x_{i,j}/dx² on interior vertical faces, cy_{i,j} = β^y_{i,j}/dy²
//! on interior horizontal faces, and 0 on boundary faces. The diagonal d_ij is the sum of the four
//! couplings plus, for every boundary face of the cell, 0 (Neumann: no flux) or 2β_face/h²
//! (Dirichlet p = 0 on the face: ghost value −p_ij).

use super::par::{self, SharedMut};
use crate::exec::Exec;
use crate::grid::PressureBc;

/// The four sides in the order of the `bc` arrays.
const LEFT: usize = 0;
const RIGHT: usize = 1;
const BOTTOM: usize = 2;
const TOP: usize = 3;

/// One level of the grid hierarchy with the coefficients of its operator.
#[derive(Debug)]
pub(crate) struct Level {
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// Cell width.
    pub dx: f64,
    /// Cell height.
    pub dy: f64,
    /// Pressure conditions (left, right, bottom, top).
    pub bc: [PressureBc; 4],
    /// β on vertical faces, shape (ny, nx+1).
    pub beta_x: Vec<f64>,
    /// β on horizontal faces, shape (ny+1, nx).
    pub beta_y: Vec<f64>,
    /// Couplings across vertical faces, shape (ny, nx+1); 0 on boundary faces.
    pub cx: Vec<f64>,
    /// Couplings across horizontal faces, shape (ny+1, nx); 0 on boundary faces.
    pub cy: Vec<f64>,
    /// Diagonal shift σ ≥ 0 (A = −L + σ, a Helmholtz-type operator), shape (ny, nx); zero for
    /// the pressure equation.
    pub shift: Vec<f64>,
    /// Diagonal of A, shape (ny, nx).
    pub diag: Vec<f64>,
    /// 1 / diagonal (0 where the diagonal is 0: a lone cell with Neumann conditions).
    pub inv_diag: Vec<f64>,
    /// A row of zeros standing for the missing rows beyond the bottom and top boundaries.
    zeros: Vec<f64>,
}

impl Level {
    /// A level of `nx × ny` cells with unit coefficients (set by [`Level::update_stencil`]).
    pub fn new(nx: usize, ny: usize, dx: f64, dy: f64, bc: [PressureBc; 4]) -> Self {
        Level {
            nx,
            ny,
            dx,
            dy,
            bc,
            beta_x: vec![1.0; ny * (nx + 1)],
            beta_y: vec![1.0; (ny + 1) * nx],
            cx: vec![0.0; ny * (nx + 1)],
            cy: vec![0.0; (ny + 1) * nx],
            shift: vec![0.0; nx * ny],
            diag: vec![0.0; nx * ny],
            inv_diag: vec![0.0; nx * ny],
            zeros: vec![0.0; nx],
        }
    }

    /// Number of cells.
    #[inline]
    pub fn cells(&self) -> usize {
        self.nx * self.ny
    }

    /// Coarse face coefficients from the fine level `fine` (twice as many cells each way): each
    /// coarse face is made of two fine faces and gets their arithmetic mean (the flux through
    /// the coarse face is the sum of the fluxes through its two halves).
    pub fn coarsen_coefficients(&mut self, fine: &Level, exec: Exec) {
        let (nx, nfx) = (self.nx, fine.nx);
        debug_assert!(fine.nx == 2 * nx && fine.ny == 2 * self.ny);
        let fbx = &fine.beta_x;
        exec.for_each_row(&mut self.beta_x, nx + 1, |j, row| {
            let (r0, r1) = (2 * j * (nfx + 1), (2 * j + 1) * (nfx + 1));
            for (i, v) in row.iter_mut().enumerate() {
                *v = 0.5 * (fbx[r0 + 2 * i] + fbx[r1 + 2 * i]);
            }
        });
        let fby = &fine.beta_y;
        exec.for_each_row(&mut self.beta_y, nx, |j, row| {
            let r = 2 * j * nfx;
            for (i, v) in row.iter_mut().enumerate() {
                *v = 0.5 * (fby[r + 2 * i] + fby[r + 2 * i + 1]);
            }
        });
        // σ is a mass term per unit area: the coarse value is the mean of the four children
        let fs = &fine.shift;
        exec.for_each_row(&mut self.shift, nx, |j, row| {
            let (r0, r1) = (2 * j * nfx, (2 * j + 1) * nfx);
            for (i, v) in row.iter_mut().enumerate() {
                *v = 0.25 * (fs[r0 + 2 * i] + fs[r0 + 2 * i + 1] + fs[r1 + 2 * i] + fs[r1 + 2 * i + 1]);
            }
        });
    }

    /// Computes couplings and diagonal from `beta_x`, `beta_y` and the boundary conditions.
    pub fn update_stencil(&mut self, exec: Exec) {
        let (nx, ny) = (self.nx, self.ny);
        let (idx2, idy2) = (1.0 / (self.dx * self.dx), 1.0 / (self.dy * self.dy));
        let bx = &self.beta_x;
        exec.for_each_row(&mut self.cx, nx + 1, |j, row| {
            for (i, c) in row.iter_mut().enumerate() {
                *c = if i == 0 || i == nx { 0.0 } else { bx[j * (nx + 1) + i] * idx2 };
            }
        });
        let by = &self.beta_y;
        exec.for_each_row(&mut self.cy, nx, |j, row| {
            for (i, c) in row.iter_mut().enumerate() {
                *c = if j == 0 || j == ny { 0.0 } else { by[j * nx + i] * idy2 };
            }
        });
        let dirichlet = self.bc.map(|b| if b == PressureBc::Dirichlet { 2.0 } else { 0.0 });
        let (cx, cy, sh) = (&self.cx, &self.cy, &self.shift);
        exec.for_each_row(&mut self.diag, nx, |j, row| {
            for (i, d) in row.iter_mut().enumerate() {
                let mut s = sh[j * nx + i] + cx[j * (nx + 1) + i] + cx[j * (nx + 1) + i + 1] + cy[j * nx + i] + cy[(j + 1) * nx + i];
                if i == 0 {
                    s += dirichlet[LEFT] * bx[j * (nx + 1)] * idx2;
                }
                if i == nx - 1 {
                    s += dirichlet[RIGHT] * bx[j * (nx + 1) + nx] * idx2;
                }
                if j == 0 {
                    s += dirichlet[BOTTOM] * by[i] * idy2;
                }
                if j == ny - 1 {
                    s += dirichlet[TOP] * by[ny * nx + i] * idy2;
                }
                *d = s;
            }
        });
        let diag = &self.diag;
        exec.for_each_row(&mut self.inv_diag, nx, |j, row| {
            for (i, v) in row.iter_mut().enumerate() {
                let d = diag[j * nx + i];
                *v = if d > 0.0 { 1.0 / d } else { 0.0 };
            }
        });
    }

    /// Calls `emit(i, (A p)_ij)` for every cell of row `j`.
    #[inline(always)]
    pub fn stencil_row(&self, j: usize, p: &[f64], mut emit: impl FnMut(usize, f64)) {
        let nx = self.nx;
        let pc = &p[j * nx..(j + 1) * nx];
        let ps = if j > 0 { &p[(j - 1) * nx..j * nx] } else { &self.zeros[..] };
        let pn = if j + 1 < self.ny { &p[(j + 1) * nx..(j + 2) * nx] } else { &self.zeros[..] };
        let cxr = &self.cx[j * (nx + 1)..(j + 1) * (nx + 1)];
        let cys = &self.cy[j * nx..(j + 1) * nx];
        let cyn = &self.cy[(j + 1) * nx..(j + 2) * nx];
        let dg = &self.diag[j * nx..(j + 1) * nx];
        if nx == 1 {
            emit(0, dg[0] * pc[0] - cys[0] * ps[0] - cyn[0] * pn[0]);
            return;
        }
        emit(0, dg[0] * pc[0] - cxr[1] * pc[1] - cys[0] * ps[0] - cyn[0] * pn[0]);
        for i in 1..nx - 1 {
            emit(i, dg[i] * pc[i] - cxr[i] * pc[i - 1] - cxr[i + 1] * pc[i + 1] - cys[i] * ps[i] - cyn[i] * pn[i]);
        }
        let i = nx - 1;
        emit(i, dg[i] * pc[i] - cxr[i] * pc[i - 1] - cys[i] * ps[i] - cyn[i] * pn[i]);
    }

    /// r = b − A x.
    pub fn residual(&self, x: &[f64], b: &[f64], r: &mut [f64], exec: Exec) {
        let nx = self.nx;
        exec.for_each_row(r, nx, |j, row| {
            let br = &b[j * nx..(j + 1) * nx];
            self.stencil_row(j, x, |i, v| row[i] = br[i] - v)
        });
    }

    /// One red–black Gauss–Seidel sweep: a half-sweep over the cells of colour `first`
    /// ((i + j) mod 2 == first), then one over the other colour. A half-sweep sets
    /// x_ij = (b_ij + Σ couplings × neighbours) / d_ij; the neighbours of a cell all have the other
    /// colour, so each cell's update reads the same values whatever the order of the updates:
    /// serial and parallel sweeps give bit-identical results. With `from_zero`, the first
    /// half-sweep starts from x = 0 (x need not be initialised).
    ///
    /// Both half-sweeps are fused to read the arrays once: serially as a wavefront (colour
    /// `first` on row j, then the other colour on row j − 1); in parallel by blocks of
    /// [`SMOOTH_BLOCK`] rows, each doing colour `first` on all its rows and the other colour on
    /// its interior rows, then, after all blocks are done, the other colour on the first and last
    /// row of every block (they depend on the neighbouring blocks).
    pub fn smooth(&self, x: &mut [f64], b: &[f64], first: usize, from_zero: bool, exec: Exec) {
        let (nx, ny) = (self.nx, self.ny);
        assert!(x.len() == nx * ny && b.len() == nx * ny);
        let second = 1 - first;
        let ptr = SharedMut(x.as_mut_ptr());
        if !exec.use_parallel(nx * ny) {
            // SAFETY: single thread; all indices are in bounds (see `half_sweep_row`).
            unsafe {
                for j in 0..ny {
                    self.half_sweep_row(ptr.get(), b, j, first, from_zero);
                    if j > 0 {
                        self.half_sweep_row(ptr.get(), b, j - 1, second, false);
                    }
                }
                self.half_sweep_row(ptr.get(), b, ny - 1, second, false);
            }
            return;
        }
        // Phase A: colour `first` on every row of the block, the other colour on its interior rows.
        par::for_blocks_of(exec, ny, nx * ny, SMOOTH_BLOCK, |rows| {
            // SAFETY: this block writes colour `first` in its rows and the other colour in its
            // interior rows (start+1 ..= end−2). Other blocks read, in this phase, only the other
            // colour of this block's first and last rows, which nobody writes in this phase; the
            // interior updates read colour `first` in rows start ..= end−1 only, which only this
            // block writes. Row and column indices are in bounds (see `half_sweep_row`).
            unsafe {
                for j in rows.clone() {
                    self.half_sweep_row(ptr.get(), b, j, first, from_zero);
                    if j >= rows.start + 2 {
                        self.half_sweep_row(ptr.get(), b, j - 1, second, false);
                    }
                }
            }
        });
        // Phase B: the other colour on the first and last row of every block.
        par::for_blocks_of(exec, ny, nx * ny, SMOOTH_BLOCK, |rows| {
            // SAFETY: blocks write the other colour in their own first and last rows and read
            // only colour `first`, which nobody writes in this phase.
            unsafe {
                self.half_sweep_row(ptr.get(), b, rows.start, second, false);
                if rows.end - 1 > rows.start {
                    self.half_sweep_row(ptr.get(), b, rows.end - 1, second, false);
                }
            }
        });
    }

    /// Gauss–Seidel update of the cells of colour `colour` in row `j` of the buffer at `base`
    /// (nx·ny values); with `from_zero`, x = b/d (the other colour taken as 0).
    ///
    /// # Safety
    /// `base` must point to nx·ny values; no other thread may write the cells of the other colour
    /// in rows j−1..=j+1, nor read or write the cells of colour `colour` in row j, during the
    /// call. Indices: rows j±1 are read only when they exist (the zero row stands in otherwise),
    /// columns i±1 only when 0 ≤ i±1 < nx. No reference to the buffer is created.
    #[inline(always)]
    unsafe fn half_sweep_row(&self, base: *mut f64, b: &[f64], j: usize, colour: usize, from_zero: bool) {
        let (nx, ny) = (self.nx, self.ny);
        let start = (colour + j) % 2;
        let br = &b[j * nx..(j + 1) * nx];
        let inv = &self.inv_diag[j * nx..(j + 1) * nx];
        let pc = base.add(j * nx);
        if from_zero {
            for i in (start..nx).step_by(2) {
                *pc.add(i) = br[i] * inv[i];
            }
            return;
        }
        // Raw pointers into the coefficient rows (lengths nx + 1 and nx, checked by the slicing).
        let cxr = self.cx[j * (nx + 1)..(j + 1) * (nx + 1)].as_ptr();
        let cys = self.cy[j * nx..(j + 1) * nx].as_ptr();
        let cyn = self.cy[(j + 1) * nx..(j + 2) * nx].as_ptr();
        let (br, inv) = (br.as_ptr(), inv.as_ptr());
        let ps: *const f64 = if j > 0 { base.add((j - 1) * nx) } else { self.zeros.as_ptr() };
        let pn: *const f64 = if j + 1 < ny { base.add((j + 1) * nx) } else { self.zeros.as_ptr() };
        // i < nx for every call below.
        let update = |i: usize, west: f64, east: f64| -> f64 {
            let horizontal = *br.add(i) + *cxr.add(i) * west + *cxr.add(i + 1) * east;
            let vertical = *cys.add(i) * *ps.add(i) + *cyn.add(i) * *pn.add(i);
            (horizontal + vertical) * *inv.add(i)
        };
        if nx == 1 {
            if start == 0 {
                *pc = update(0, 0.0, 0.0);
            }
            return;
        }
        let mut i = start;
        if i == 0 {
            *pc = update(0, 0.0, *pc.add(1));
            i = 2;
        }
        while i < nx - 1 {
            *pc.add(i) = update(i, *pc.add(i - 1), *pc.add(i + 1));
            i += 2;
        }
        if i == nx - 1 {
            *pc.add(i) = update(i, *pc.add(i - 1), 0.0);
        }
    }

    /// Residual of this level restricted by averaging the 4 children: b_c = ¼ Σ_children (b − A x),
    /// without storing the fine residual.
    pub fn restrict_residual(&self, x: &[f64], b: &[f64], coarse_b: &mut [f64], exec: Exec) {
        let (nx, ncx) = (self.nx, self.nx / 2);
        exec.for_each_row(coarse_b, ncx, |jc, row| {
            row.iter_mut().for_each(|v| *v = 0.0);
            for j in [2 * jc, 2 * jc + 1] {
                let br = &b[j * nx..(j + 1) * nx];
                self.stencil_row(j, x, |i, v| row[i >> 1] += br[i] - v);
            }
            row.iter_mut().for_each(|v| *v *= 0.25);
        });
    }
}

/// Rows per block of the parallel red–black sweep (the smoother needs no reduction, so its block
/// size only trades parallelism against the boundary rows of phase B).
pub(crate) const SMOOTH_BLOCK: usize = 16;
