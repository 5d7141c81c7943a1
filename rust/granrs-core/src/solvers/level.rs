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
    /// The span of each row, `spans[j] = (lo, hi)`: every cell of row j outside the columns
    /// lo..hi is isolated, its four couplings zero, and (on a coarse level) is the parent of no
    /// cell in a span of the finer level ([`Level::set_spans`]); (0, 0) for a row without
    /// such cells.
    pub spans: Vec<(usize, usize)>,
    /// Work of the rows for the smoother's blocks: `span_work[j]` = Σ_{k<j} (span length of
    /// row k + [`ROW_OVERHEAD`]), ny + 1 values.
    span_work: Vec<usize>,
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
            spans: vec![(0, nx); ny],
            span_work: (0..=ny).map(|j| j * (nx + ROW_OVERHEAD)).collect(),
        }
    }

    /// Sets the rows' spans from the couplings and, on a coarse level, from the spans of the
    /// finer level `fine` (a coarse cell whose children lie in a span is in its row's span).
    ///
    /// **Why the cycle may skip the rest.** A cell outside the spans has no coupling to any
    /// other cell, so that its equation is d x = b alone; where b = 0 there (checked by
    /// [`Level::zero_outside_spans`]'s callers for the fine level; the restricted residual of
    /// cells whose children are all outside the spans is 0) the cycle leaves it at ±0: the
    /// smoother sets it to (b + 0·neighbours)/d, its residual is 0, and a correction prolonged
    /// into it is undone by the next sweep. Its value enters the other cells' updates only
    /// multiplied by a zero coupling. The cycle restricted to the spans, with zeros outside them,
    /// therefore computes the same values bit for bit (up to the sign of a zero) with the work
    /// of the spans only: the granular-only model's air cells and the pore pressure's cells
    /// outside the grains are such isolated cells (a trivial row p = 0).
    pub fn set_spans(&mut self, fine: Option<&Level>, exec: Exec) {
        use rayon::prelude::*;
        let (nx, ny) = (self.nx, self.ny);
        let (cx, cy) = (&self.cx, &self.cy);
        let coupled =
            |j: usize, i: usize| cx[j * (nx + 1) + i] != 0.0 || cx[j * (nx + 1) + i + 1] != 0.0 || cy[j * nx + i] != 0.0 || cy[(j + 1) * nx + i] != 0.0;
        let row_span = |j: usize| -> (usize, usize) {
            let (mut lo, mut hi) = (nx, 0);
            if let Some(i) = (0..nx).find(|&i| coupled(j, i)) {
                lo = i;
                hi = (i..nx).rev().find(|&i| coupled(j, i)).map_or(i, |k| k) + 1;
            }
            if let Some(f) = fine {
                for jf in [2 * j, 2 * j + 1] {
                    let (a, b) = f.spans[jf];
                    if a < b {
                        lo = lo.min(a / 2);
                        hi = hi.max(b.div_ceil(2));
                    }
                }
            }
            if lo < hi {
                (lo, hi)
            } else {
                (0, 0)
            }
        };
        if exec.use_parallel(nx * ny) {
            self.spans.par_iter_mut().enumerate().for_each(|(j, s)| *s = row_span(j));
        } else {
            self.spans.iter_mut().enumerate().for_each(|(j, s)| *s = row_span(j));
        }
        for j in 0..ny {
            self.span_work[j + 1] = self.span_work[j] + self.spans[j].1 - self.spans[j].0 + ROW_OVERHEAD;
        }
    }

    /// The execution policy for a sweep over this level: `exec`, but serial when the sweep
    /// works on the spans and they hold too few cells for threads to pay
    /// ([`Exec::use_parallel`]; the results do not depend on it).
    pub fn exec_for(&self, exec: Exec, spans: bool) -> Exec {
        if spans && !exec.use_parallel(self.span_work[self.ny]) {
            Exec::SERIAL
        } else {
            exec
        }
    }

    /// The columns of row `j` the cycle works on: its span when `on`, else the whole row.
    #[inline(always)]
    pub fn span(&self, j: usize, on: bool) -> (usize, usize) {
        if on {
            self.spans[j]
        } else {
            (0, self.nx)
        }
    }

    /// Whether `v` (a field of this level) is zero outside the spans (−0 counts as zero); the
    /// rows are looked at on the threads of `exec`.
    pub fn zero_outside_spans(&self, v: &[f64], exec: Exec) -> bool {
        let nx = self.nx;
        let nonzero = exec.max_rows(self.ny, self.cells(), |j| {
            let (row, (lo, hi)) = (&v[j * nx..(j + 1) * nx], self.spans[j]);
            let zero = row[..lo].iter().chain(&row[hi..]).fold(true, |all, &x| all & (x == 0.0));
            if zero {
                0.0
            } else {
                1.0
            }
        });
        nonzero == 0.0
    }

    /// Sets `v` (a field of this level) to zero outside the spans.
    pub fn fill_outside_spans(&self, v: &mut [f64], exec: Exec) {
        let nx = self.nx;
        exec.for_each_row(v, nx, |j, row| {
            let (lo, hi) = self.spans[j];
            row[..lo].fill(0.0);
            row[hi..].fill(0.0);
        });
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
            let b = &bx[j * (nx + 1)..(j + 1) * (nx + 1)];
            scale_row(&mut row[1..nx], &b[1..nx], idx2);
            row[0] = 0.0;
            row[nx] = 0.0;
        });
        let by = &self.beta_y;
        exec.for_each_row(&mut self.cy, nx, |j, row| {
            if j == 0 || j == ny {
                row.fill(0.0);
            } else {
                scale_row(row, &by[j * nx..(j + 1) * nx], idy2);
            }
        });
        let dirichlet = self.bc.map(|b| if b == PressureBc::Dirichlet { 2.0 } else { 0.0 });
        let (cx, cy, sh) = (&self.cx, &self.cy, &self.shift);
        exec.for_each_row(&mut self.diag, nx, |j, row| {
            let cxr = &cx[j * (nx + 1)..(j + 1) * (nx + 1)];
            diagonal_row(row, &sh[j * nx..(j + 1) * nx], cxr, &cy[j * nx..(j + 1) * nx], &cy[(j + 1) * nx..(j + 2) * nx]);
            // the Dirichlet sides, added in the order left, right, bottom, top
            row[0] += dirichlet[LEFT] * bx[j * (nx + 1)] * idx2;
            row[nx - 1] += dirichlet[RIGHT] * bx[j * (nx + 1) + nx] * idx2;
            if j == 0 {
                for (d, b) in row.iter_mut().zip(&by[..nx]) {
                    *d += dirichlet[BOTTOM] * b * idy2;
                }
            }
            if j == ny - 1 {
                for (d, b) in row.iter_mut().zip(&by[ny * nx..(ny + 1) * nx]) {
                    *d += dirichlet[TOP] * b * idy2;
                }
            }
        });
        let diag = &self.diag;
        exec.for_each_row(&mut self.inv_diag, nx, |j, row| inverse_row(row, &diag[j * nx..(j + 1) * nx]));
    }

    /// The rows of `p` and of the coefficients that the operator reads for row `j` (the zero row
    /// stands for the rows beyond the bottom and top boundaries).
    #[inline(always)]
    fn row_views<'a>(&'a self, j: usize, p: &'a [f64]) -> StencilRow<'a> {
        let nx = self.nx;
        StencilRow {
            pc: &p[j * nx..(j + 1) * nx],
            ps: if j > 0 { &p[(j - 1) * nx..j * nx] } else { &self.zeros[..] },
            pn: if j + 1 < self.ny { &p[(j + 1) * nx..(j + 2) * nx] } else { &self.zeros[..] },
            cxr: &self.cx[j * (nx + 1)..(j + 1) * (nx + 1)],
            cys: &self.cy[j * nx..(j + 1) * nx],
            cyn: &self.cy[(j + 1) * nx..(j + 2) * nx],
            dg: &self.diag[j * nx..(j + 1) * nx],
        }
    }

    /// Calls `emit(i, (A p)_ij)` for every cell of row `j`.
    #[inline(always)]
    pub fn stencil_row(&self, j: usize, p: &[f64], mut emit: impl FnMut(usize, f64)) {
        let nx = self.nx;
        let StencilRow { pc, ps, pn, cxr, cys, cyn, dg } = self.row_views(j, p);
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

    /// r = b − A x (the values of [`Level::stencil_row`], row by row by [`Level::residual_range`]).
    pub fn residual(&self, x: &[f64], b: &[f64], r: &mut [f64], exec: Exec) {
        let nx = self.nx;
        exec.for_each_row(r, nx, |j, row| self.residual_range(j, x, b, 0, nx, row));
    }

    /// (A p) on the cells lo ≤ i < hi of row `j` into `out` (hi − lo values): the values of
    /// [`Level::stencil_row`] bit for bit, the interior cells by the vectorised [`apply_span`].
    pub fn apply_range(&self, j: usize, p: &[f64], lo: usize, hi: usize, out: &mut [f64]) {
        let nx = self.nx;
        debug_assert!(lo <= hi && hi <= nx && out.len() == hi - lo);
        if lo == hi {
            return;
        }
        let row = self.row_views(j, p);
        let StencilRow { pc, ps, pn, cxr, cys, cyn, dg } = row;
        if nx == 1 {
            out[0] = dg[0] * pc[0] - cys[0] * ps[0] - cyn[0] * pn[0];
            return;
        }
        let first = lo.max(1);
        let last = hi.min(nx - 1);
        if lo == 0 {
            out[0] = dg[0] * pc[0] - cxr[1] * pc[1] - cys[0] * ps[0] - cyn[0] * pn[0];
        }
        if last > first {
            apply_span(&mut out[first - lo..last - lo], &row, first);
        }
        if hi == nx {
            let i = nx - 1;
            out[i - lo] = dg[i] * pc[i] - cxr[i] * pc[i - 1] - cys[i] * ps[i] - cyn[i] * pn[i];
        }
    }

    /// One red–black Gauss–Seidel sweep: a half-sweep over the cells of colour `first`
    /// ((i + j) mod 2 == first), then one over the other colour. A half-sweep sets
    /// x_ij = (b_ij + Σ couplings × neighbours) / d_ij; the neighbours of a cell all have the other
    /// colour, so each cell's update reads the same values whatever the order of the updates:
    /// serial and parallel sweeps give bit-identical results. With `from_zero`, the first
    /// half-sweep starts from x = 0 (x need not be initialised).
    ///
    /// Both half-sweeps are fused to read the arrays once: serially as a wavefront (colour
    /// `first` on row j, then the other colour on row j − 1); in parallel by the blocks of
    /// [`smooth_blocks`] (at most [`SMOOTH_BLOCK`] rows), each doing colour `first` on all its rows and the other colour on
    /// its interior rows, then, after all blocks are done, the other colour on the first and last
    /// row of every block (they depend on the neighbouring blocks).
    ///
    /// With `spans` the sweep updates only the cells of the rows' spans ([`Level::set_spans`];
    /// the others must hold zeros and see b = 0), and the blocks hold equal work rather than
    /// equal rows.
    pub fn smooth(&self, x: &mut [f64], b: &[f64], first: usize, from_zero: bool, spans: bool, exec: Exec) {
        let (nx, ny) = (self.nx, self.ny);
        assert!(x.len() == nx * ny && b.len() == nx * ny);
        let second = 1 - first;
        let ptr = SharedMut(x.as_mut_ptr());
        if !exec.use_parallel(nx * ny) {
            // SAFETY: single thread; all indices are in bounds (see `half_sweep_row`).
            unsafe {
                for j in 0..ny {
                    self.half_sweep_row(ptr.get(), b, j, first, from_zero, spans);
                    if j > 0 {
                        self.half_sweep_row(ptr.get(), b, j - 1, second, false, spans);
                    }
                }
                self.half_sweep_row(ptr.get(), b, ny - 1, second, false, spans);
            }
            return;
        }
        let blocks = smooth_blocks(ny, rayon::current_num_threads());
        let work = if spans { Some(&self.span_work[..]) } else { None };
        // Phase A: colour `first` on every row of the block, the other colour on its interior rows.
        par::for_balanced_blocks(exec, ny, nx * ny, blocks, work, |rows| {
            // SAFETY: this block writes colour `first` in its rows and the other colour in its
            // interior rows (start+1 ..= end−2). Other blocks read, in this phase, only the other
            // colour of this block's first and last rows, which nobody writes in this phase; the
            // interior updates read colour `first` in rows start ..= end−1 only, which only this
            // block writes. Row and column indices are in bounds (see `half_sweep_row`).
            unsafe {
                for j in rows.clone() {
                    self.half_sweep_row(ptr.get(), b, j, first, from_zero, spans);
                    if j >= rows.start + 2 {
                        self.half_sweep_row(ptr.get(), b, j - 1, second, false, spans);
                    }
                }
            }
        });
        // Phase B: the other colour on the first and last row of every block.
        par::for_balanced_blocks(exec, ny, nx * ny, blocks, work, |rows| {
            if rows.is_empty() {
                return;
            }
            // SAFETY: blocks write the other colour in their own first and last rows and read
            // only colour `first`, which nobody writes in this phase.
            unsafe {
                self.half_sweep_row(ptr.get(), b, rows.start, second, false, spans);
                if rows.end - 1 > rows.start {
                    self.half_sweep_row(ptr.get(), b, rows.end - 1, second, false, spans);
                }
            }
        });
    }

    /// Gauss–Seidel update of the cells of colour `colour` in row `j` of the buffer at `base`
    /// (nx·ny values), in the row's span when `spans` (else the whole row); with `from_zero`,
    /// x = b/d (the other colour taken as 0).
    ///
    /// # Safety
    /// `base` must point to nx·ny values; no other thread may write the cells of the other colour
    /// in rows j−1..=j+1, nor read or write the cells of colour `colour` in row j, during the
    /// call. Indices: rows j±1 are read only when they exist (the zero row stands in otherwise),
    /// columns i±1 only when 0 ≤ i±1 < nx. No reference to the buffer is created.
    #[inline(always)]
    unsafe fn half_sweep_row(&self, base: *mut f64, b: &[f64], j: usize, colour: usize, from_zero: bool, spans: bool) {
        let (nx, ny) = (self.nx, self.ny);
        let (lo, hi) = self.span(j, spans);
        // the first cell of the colour at or after lo: (i + j) mod 2 == colour
        let start = lo + (colour + j + lo) % 2;
        let br = &b[j * nx..(j + 1) * nx];
        let inv = &self.inv_diag[j * nx..(j + 1) * nx];
        let pc = base.add(j * nx);
        if from_zero {
            for i in (start..hi).step_by(2) {
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
        if start >= hi {
            return;
        }
        if nx == 1 {
            *pc = update(0, 0.0, 0.0);
            return;
        }
        let mut i = start;
        if i == 0 {
            *pc = update(0, 0.0, *pc.add(1));
            i = 2;
        }
        let end = hi.min(nx - 1);
        while i < end {
            *pc.add(i) = update(i, *pc.add(i - 1), *pc.add(i + 1));
            i += 2;
        }
        if i == nx - 1 && i < hi {
            *pc.add(i) = update(i, *pc.add(i - 1), 0.0);
        }
    }

    /// Residual of this level restricted by averaging the 4 children: b_c = ¼ Σ_children (b − A x),
    /// without storing the fine residual. Each coarse row is made by chunks of
    /// [`RESTRICT_CHUNK`] / 2 coarse cells: the residual of the two fine rows under the chunk goes
    /// to buffers on the stack ([`Level::residual_range`]), then each coarse cell adds its four
    /// children in the order (2i, 2j), (2i+1, 2j), (2i, 2j+1), (2i+1, 2j+1), starting from 0.
    /// With `coarse` (the coarse level, whose spans cover the parents of this level's spans)
    /// only the coarse cells in its spans are computed, and the others are set to 0.
    pub fn restrict_residual(&self, x: &[f64], b: &[f64], coarse_b: &mut [f64], coarse: Option<&Level>, exec: Exec) {
        let (nx, ncx) = (self.nx, self.nx / 2);
        debug_assert!(nx % 2 == 0 && self.ny % 2 == 0 && coarse_b.len() == ncx * (self.ny / 2));
        const CHUNK: usize = RESTRICT_CHUNK / 2;
        exec.for_each_row(coarse_b, ncx, |jc, row| {
            let (clo, chi) = coarse.map_or((0, ncx), |c| c.spans[jc]);
            row[..clo].fill(0.0);
            row[chi..].fill(0.0);
            let (mut r0, mut r1) = ([0.0; RESTRICT_CHUNK], [0.0; RESTRICT_CHUNK]);
            for (c, out) in row[clo..chi].chunks_mut(CHUNK).enumerate() {
                let (lo, hi) = (2 * (clo + c * CHUNK), 2 * (clo + c * CHUNK + out.len()));
                let (r0, r1) = (&mut r0[..hi - lo], &mut r1[..hi - lo]);
                self.residual_range(2 * jc, x, b, lo, hi, r0);
                self.residual_range(2 * jc + 1, x, b, lo, hi, r1);
                for (k, v) in out.iter_mut().enumerate() {
                    *v = ((((0.0 + r0[2 * k]) + r0[2 * k + 1]) + r1[2 * k]) + r1[2 * k + 1]) * 0.25;
                }
            }
        });
    }

    /// `out[i − lo]` = (b − A p)_ij for the cells lo ≤ i < hi of row `j`: the operations of
    /// [`Level::stencil_row`], with the interior cells by the vectorised [`residual_span`].
    #[inline(always)]
    pub fn residual_range(&self, j: usize, p: &[f64], b: &[f64], lo: usize, hi: usize, out: &mut [f64]) {
        let nx = self.nx;
        debug_assert!(lo <= hi && hi <= nx && out.len() == hi - lo);
        let row = self.row_views(j, p);
        let StencilRow { pc, ps, pn, cxr, cys, cyn, dg } = row;
        let br = &b[j * nx..(j + 1) * nx];
        if lo == hi {
            return;
        }
        if nx == 1 {
            out[0] = br[0] - (dg[0] * pc[0] - cys[0] * ps[0] - cyn[0] * pn[0]);
            return;
        }
        let first = lo.max(1);
        let last = hi.min(nx - 1);
        if lo == 0 {
            out[0] = br[0] - (dg[0] * pc[0] - cxr[1] * pc[1] - cys[0] * ps[0] - cyn[0] * pn[0]);
        }
        if last > first {
            residual_span(&mut out[first - lo..last - lo], &row, br, first);
        }
        if hi == nx {
            let i = nx - 1;
            out[i - lo] = br[i] - (dg[i] * pc[i] - cxr[i] * pc[i - 1] - cys[i] * ps[i] - cyn[i] * pn[i]);
        }
    }
}

/// The rows read by the operator on one row j: p on rows j, j − 1, j + 1 (`pc`, `ps`, `pn`), the
/// couplings across the row's vertical faces (nx + 1 values), its south and north faces, and the
/// diagonal.
struct StencilRow<'a> {
    pc: &'a [f64],
    ps: &'a [f64],
    pn: &'a [f64],
    cxr: &'a [f64],
    cys: &'a [f64],
    cyn: &'a [f64],
    dg: &'a [f64],
}

crate::multiversion! {
    /// Residual of the interior cells first ≤ i < first + out.len() of one row (`b` the row of
    /// the right-hand side, 1 ≤ first, first + out.len() < nx): out = b − ((((d·pc − cw·pw) −
    /// ce·pe) − cs·ps) − cn·pn), the operations of [`Level::stencil_row`] in its order.
    fn residual_span / residual_span_base(out: &mut [f64], row: &StencilRow<'_>, b: &[f64], first: usize) {
        let (s, e) = (first, first + out.len());
        let (b, d, cw, ce) = (&b[s..e], &row.dg[s..e], &row.cxr[s..e], &row.cxr[s + 1..e + 1]);
        let (pw, pc, pe) = (&row.pc[s - 1..e - 1], &row.pc[s..e], &row.pc[s + 1..e + 1]);
        let (cs, ps, cn, pn) = (&row.cys[s..e], &row.ps[s..e], &row.cyn[s..e], &row.pn[s..e]);
        for (k, o) in out.iter_mut().enumerate() {
            *o = b[k] - (d[k] * pc[k] - cw[k] * pw[k] - ce[k] * pe[k] - cs[k] * ps[k] - cn[k] * pn[k]);
        }
    }
}

crate::multiversion! {
    /// (A p) on the interior cells first ≤ i < first + out.len() of one row (1 ≤ first,
    /// first + out.len() < nx): ((((d·pc − cw·pw) − ce·pe) − cs·ps) − cn·pn), the operations of
    /// [`Level::stencil_row`] in its order.
    fn apply_span / apply_span_base(out: &mut [f64], row: &StencilRow<'_>, first: usize) {
        let (s, e) = (first, first + out.len());
        let (d, cw, ce) = (&row.dg[s..e], &row.cxr[s..e], &row.cxr[s + 1..e + 1]);
        let (pw, pc, pe) = (&row.pc[s - 1..e - 1], &row.pc[s..e], &row.pc[s + 1..e + 1]);
        let (cs, ps, cn, pn) = (&row.cys[s..e], &row.ps[s..e], &row.cyn[s..e], &row.pn[s..e]);
        for (k, o) in out.iter_mut().enumerate() {
            *o = d[k] * pc[k] - cw[k] * pw[k] - ce[k] * pe[k] - cs[k] * ps[k] - cn[k] * pn[k];
        }
    }
}

crate::multiversion! {
    /// out[i] = b[i] · s.
    fn scale_row / scale_row_base(out: &mut [f64], b: &[f64], s: f64) {
        let b = &b[..out.len()];
        for (o, &v) in out.iter_mut().zip(b) {
            *o = v * s;
        }
    }
}

crate::multiversion! {
    /// The diagonal of a row before its Dirichlet sides: σ + c_w + c_e + c_s + c_n, added in
    /// that order (`cxr` holds the row's nx + 1 x-couplings).
    fn diagonal_row / diagonal_row_base(out: &mut [f64], sh: &[f64], cxr: &[f64], cys: &[f64], cyn: &[f64]) {
        let n = out.len();
        let (sh, cw, ce, cys, cyn) = (&sh[..n], &cxr[..n], &cxr[1..n + 1], &cys[..n], &cyn[..n]);
        for i in 0..n {
            out[i] = sh[i] + cw[i] + ce[i] + cys[i] + cyn[i];
        }
    }
}

crate::multiversion! {
    /// out[i] = 1/d[i] where d[i] > 0, else 0.
    fn inverse_row / inverse_row_base(out: &mut [f64], d: &[f64]) {
        let d = &d[..out.len()];
        for (o, &v) in out.iter_mut().zip(d) {
            *o = if v > 0.0 { 1.0 / v } else { 0.0 };
        }
    }
}

/// The work of a row's loop beyond its span's cells, in cells, for the smoother's blocks.
const ROW_OVERHEAD: usize = 8;

/// Fine cells per chunk of the restriction (two stack buffers of 2 KiB).
const RESTRICT_CHUNK: usize = 256;

/// Most rows per block of the parallel red–black sweep. The smoother needs no reduction and its
/// result does not depend on the blocks, so their size only trades parallelism against the
/// boundary rows of phase B, which a second pass visits ([`smooth_blocks`]).
pub(crate) const SMOOTH_BLOCK: usize = 16;

/// The number of blocks of the parallel red–black sweep over `ny` rows on `threads` threads: a
/// multiple of the threads, with at most [`SMOOTH_BLOCK`] rows each, so that every thread gets
/// the same number of rows to within one per block. An active window of 65 rows on two threads
/// makes 6 blocks of 10–11 rows (blocks of 16 rows would make 5, three for one thread and two
/// for the other); the full grid of 256 rows makes 16 blocks of 16.
pub(crate) fn smooth_blocks(ny: usize, threads: usize) -> usize {
    let threads = threads.max(1);
    threads * ny.div_ceil(threads * SMOOTH_BLOCK).max(1)
}

#[cfg(test)]
mod tests {
    //! The span kernels against the operator applied cell by cell, bit for bit.
    use super::*;

    /// A level with face coefficients that vary from face to face (a jump of 10³ across a
    /// wavy line, as at the interface), Dirichlet on the top, and a right-hand side and a guess.
    fn case(nx: usize, ny: usize) -> (Level, Vec<f64>, Vec<f64>) {
        let bc = [PressureBc::Neumann, PressureBc::Neumann, PressureBc::Neumann, PressureBc::Dirichlet];
        let mut level = Level::new(nx, ny, 0.01, 0.012, bc);
        let beta = |x: f64, y: f64| if y > 0.5 + 0.1 * (7.0 * x).sin() { 1.0 } else { 1e-3 };
        for j in 0..ny {
            for i in 0..=nx {
                level.beta_x[j * (nx + 1) + i] = beta(i as f64 / nx as f64, (j as f64 + 0.5) / ny as f64);
            }
        }
        for j in 0..=ny {
            for i in 0..nx {
                level.beta_y[j * nx + i] = beta((i as f64 + 0.5) / nx as f64, j as f64 / ny as f64);
            }
        }
        level.update_stencil(Exec::SERIAL);
        let wave = |k: usize, a: f64| (a * k as f64).sin() + 0.3 * (0.37 * a * k as f64).cos();
        let b = (0..nx * ny).map(|k| wave(k, 0.91)).collect();
        let x = (0..nx * ny).map(|k| wave(k, 1.73)).collect();
        (level, b, x)
    }

    /// The restriction as the sum of the children scattered in cell order.
    fn restrict_by_cells(level: &Level, x: &[f64], b: &[f64]) -> Vec<f64> {
        let (nx, ncx) = (level.nx, level.nx / 2);
        let mut out = vec![0.0; ncx * (level.ny / 2)];
        for (jc, row) in out.chunks_mut(ncx).enumerate() {
            for j in [2 * jc, 2 * jc + 1] {
                let br = &b[j * nx..(j + 1) * nx];
                level.stencil_row(j, x, |i, v| row[i >> 1] += br[i] - v);
            }
            row.iter_mut().for_each(|v| *v *= 0.25);
        }
        out
    }

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    const SIZES: [(usize, usize); 7] = [(2, 2), (4, 6), (6, 1), (130, 40), (514, 18), (600, 96), (1280, 64)];

    /// `case` with the cells above a wavy line decoupled (zero coefficients, a unit shift) and
    /// x = b = 0 there: rows whose spans shrink to nothing, so that blocks of equal work may be
    /// empty or one row long.
    fn case_with_spans(nx: usize, ny: usize) -> (Level, Vec<f64>, Vec<f64>) {
        let (mut level, mut b, mut x) = case(nx, ny);
        let top = |i: usize| 1 + (0.15 * ny as f64 * (1.0 + (9.0 * i as f64 / nx as f64).sin())) as usize;
        for j in 0..ny {
            for i in 0..=nx {
                if j >= top(i.min(nx - 1)) || (i > 0 && j >= top(i - 1)) {
                    level.beta_x[j * (nx + 1) + i] = 0.0;
                }
            }
        }
        for j in 0..=ny {
            for i in 0..nx {
                if j >= top(i) {
                    level.beta_y[j * nx + i] = 0.0;
                }
            }
        }
        level.shift.fill(1.0);
        level.update_stencil(Exec::SERIAL);
        level.set_spans(None, Exec::SERIAL);
        for j in 0..ny {
            let (lo, hi) = level.spans[j];
            for i in (0..nx).filter(|&i| i < lo || i >= hi) {
                b[j * nx + i] = 0.0;
                x[j * nx + i] = 0.0;
            }
        }
        (level, b, x)
    }

    #[test]
    fn the_parallel_sweep_is_the_serial_sweep_bit_for_bit() {
        // the serial sweep (one thread) is the wavefront of the definition; the parallel one
        // runs blocks of 1 to 16 rows, some of them empty with spans (blocks of equal work)
        let sizes = [(4100, 1), (2050, 2), (1400, 3), (130, 40), (64, 70), (600, 96), (300, 150)];
        for threads in [2, 3, 4] {
            let pool = crate::exec::build_pool(threads).unwrap();
            for (nx, ny) in sizes {
                for spans in [false, true] {
                    let (level, b, x0) = if spans { case_with_spans(nx, ny) } else { case(nx, ny) };
                    for (first, from_zero) in [(0, true), (0, false), (1, false)] {
                        let mut want = x0.clone();
                        level.smooth(&mut want, &b, first, from_zero, spans, Exec::SERIAL);
                        let mut got = x0.clone();
                        pool.install(|| level.smooth(&mut got, &b, first, from_zero, spans, Exec::with_threads(threads)));
                        assert_eq!(bits(&got), bits(&want), "{nx}×{ny}, {threads} threads, spans {spans}, colour {first}, from zero {from_zero}");
                    }
                }
            }
        }
    }

    /// The couplings, diagonal and inverse diagonal cell by cell, with the Dirichlet sides added
    /// in the order left, right, bottom, top (the definition `update_stencil` is checked against).
    fn stencil_by_cells(level: &Level) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let (nx, ny) = (level.nx, level.ny);
        let (idx2, idy2) = (1.0 / (level.dx * level.dx), 1.0 / (level.dy * level.dy));
        let (bx, by) = (&level.beta_x, &level.beta_y);
        let cx: Vec<f64> = (0..ny * (nx + 1)).map(|k| if k % (nx + 1) == 0 || k % (nx + 1) == nx { 0.0 } else { bx[k] * idx2 }).collect();
        let cy: Vec<f64> = (0..(ny + 1) * nx).map(|k| if k / nx == 0 || k / nx == ny { 0.0 } else { by[k] * idy2 }).collect();
        let dirichlet = level.bc.map(|b| if b == PressureBc::Dirichlet { 2.0 } else { 0.0 });
        let mut diag = vec![0.0; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                let mut s = level.shift[j * nx + i] + cx[j * (nx + 1) + i] + cx[j * (nx + 1) + i + 1] + cy[j * nx + i] + cy[(j + 1) * nx + i];
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
                diag[j * nx + i] = s;
            }
        }
        let inv = diag.iter().map(|&d| if d > 0.0 { 1.0 / d } else { 0.0 }).collect();
        (cx, cy, diag, inv)
    }

    #[test]
    fn the_stencil_rows_are_the_stencil_cell_by_cell() {
        let pool = crate::exec::build_pool(2).unwrap();
        let n = PressureBc::Neumann;
        let d = PressureBc::Dirichlet;
        for bc in [[n, n, n, d], [d, d, d, d], [d, n, d, n], [n, n, n, n]] {
            for (nx, ny) in [(1, 1), (1, 5), (6, 1), (37, 5), (130, 40)] {
                let (mut level, _, _) = case(nx, ny);
                level.bc = bc;
                level.shift.iter_mut().enumerate().for_each(|(k, s)| *s = if k % 3 == 0 { 0.0 } else { 0.1 * k as f64 });
                let want = stencil_by_cells(&level);
                for exec in [Exec::SERIAL, Exec::with_threads(2)] {
                    level.cx.fill(f64::NAN);
                    level.diag.fill(f64::NAN);
                    pool.install(|| level.update_stencil(exec));
                    let got = (&level.cx, &level.cy, &level.diag, &level.inv_diag);
                    assert_eq!(bits(got.0), bits(&want.0), "cx, {nx}×{ny}, {bc:?}");
                    assert_eq!(bits(got.1), bits(&want.1), "cy, {nx}×{ny}, {bc:?}");
                    assert_eq!(bits(got.2), bits(&want.2), "diag, {nx}×{ny}, {bc:?}");
                    assert_eq!(bits(got.3), bits(&want.3), "inv_diag, {nx}×{ny}, {bc:?}");
                }
            }
        }
    }

    #[test]
    fn restriction_by_spans_adds_the_same_children_in_the_same_order() {
        let pool = crate::exec::build_pool(2).unwrap();
        for (nx, ny) in SIZES.into_iter().filter(|&(nx, ny)| nx % 2 == 0 && ny % 2 == 0) {
            let (level, b, x) = case(nx, ny);
            let expected = bits(&restrict_by_cells(&level, &x, &b));
            for exec in [Exec::SERIAL, Exec::with_threads(2)] {
                let mut out = vec![f64::NAN; expected.len()];
                pool.install(|| level.restrict_residual(&x, &b, &mut out, None, exec));
                assert_eq!(bits(&out), expected, "{nx}×{ny}, {exec:?}");
            }
        }
    }

    #[test]
    fn residual_range_matches_the_stencil_on_every_cut_of_a_row() {
        let (level, b, x) = case(37, 5);
        for j in 0..5 {
            let mut row = vec![0.0; 37];
            level.stencil_row(j, &x, |i, v| row[i] = b[j * 37 + i] - v);
            for (lo, hi) in [(0, 37), (0, 1), (36, 37), (1, 36), (5, 6), (3, 20), (20, 20)] {
                let mut out = vec![f64::NAN; hi - lo];
                level.residual_range(j, &x, &b, lo, hi, &mut out);
                assert_eq!(bits(&out), bits(&row[lo..hi]), "row {j}, cells {lo}..{hi}");
            }
        }
    }

    #[test]
    fn apply_range_matches_the_stencil_on_every_row_length() {
        for nx in [1, 2, 3, 37] {
            let (level, _, x) = case(nx, 5);
            for j in 0..5 {
                let mut want = vec![0.0; nx];
                level.stencil_row(j, &x, |i, v| want[i] = v);
                let mut got = vec![f64::NAN; nx];
                level.apply_range(j, &x, 0, nx, &mut got);
                assert_eq!(bits(&got), bits(&want), "nx {nx}, row {j}");
                // the cuts of a row's span
                for (lo, hi) in [(0, 1), (nx - 1, nx), (nx / 2, nx), (1.min(nx), nx / 2), (nx / 3, nx / 3)] {
                    let (lo, hi) = (lo.min(hi), hi.max(lo));
                    let mut got = vec![f64::NAN; hi - lo];
                    level.apply_range(j, &x, lo, hi, &mut got);
                    assert_eq!(bits(&got), bits(&want[lo..hi]), "nx {nx}, row {j}, cells {lo}..{hi}");
                }
            }
        }
        let (level, _, x) = case(300, 3);
        let row = level.row_views(1, &x);
        let (mut a, mut c) = (vec![0.0; 298], vec![0.0; 298]);
        apply_span(&mut a, &row, 1);
        apply_span_base(&mut c, &row, 1);
        assert_eq!(bits(&a), bits(&c));
    }

    #[test]
    fn both_copies_of_the_residual_span_agree() {
        let (level, b, x) = case(300, 3);
        let (nx, j) = (300, 1);
        let row = level.row_views(j, &x);
        let (mut a, mut c) = (vec![0.0; nx - 2], vec![0.0; nx - 2]);
        residual_span(&mut a, &row, &b[j * nx..(j + 1) * nx], 1);
        residual_span_base(&mut c, &row, &b[j * nx..(j + 1) * nx], 1);
        assert_eq!(bits(&a), bits(&c));
    }
}
