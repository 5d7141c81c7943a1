//! Small detached pieces of the dense phase turned to air (option `piece_removal_cells`; not in
//! the paper, granrs's own, measured in docs/validation.md, "Arrest of the deposit").
//!
//! After the transport of eq. (10a), ∂Φ/∂t + u·∇Φ = 0 (Aravena et al. §2.4), and its
//! redistancing, every region of {Φ > 0} that is 8-connected on the cell centres and holds at
//! most N cells, other than the largest region (the deposit, kept whatever N), is given the value
//!
//!   Φ|_piece ← max { Φ_c : c an 8-neighbour of the piece outside it } ≤ 0,
//!
//! the level of the air around it: the piece becomes part of the air without a new zero
//! crossing, and the global mass correction (`Interface::correct_mass`) puts the area it held
//! back on the interface. What it is for: specks of Φ > 0 a cell or two in size that the
//! transport leaves in the air ahead of a deposit's thin tip, which the air carries at its own
//! speed and which a rest criterion over the cells with Φ > 0 sees as granular motion.
//!
//! The search is serial (a breadth-first fill in a fixed order: the result does not depend on
//! the threads) and allocation-free: its two buffers of one u32 per cell of the grid are
//! allocated once in [`DetachedPieces::new`].

use crate::grid::{Field, Grid, HALO};

/// The removal of pieces of at most `max_cells` cells, with its buffers.
pub struct DetachedPieces {
    max_cells: usize,
    /// The piece each cell belongs to (0: not granular or not visited yet), row-major over the
    /// interior of the field the removal is given.
    label: Vec<u32>,
    /// The cells of the piece being filled, in the order they were reached (the fill's queue).
    members: Vec<u32>,
}

impl DetachedPieces {
    /// Buffers for fields of at most the cells of `grid` (a window of it included).
    pub fn new(grid: &Grid, max_cells: usize) -> Self {
        let n = grid.nx * grid.ny;
        DetachedPieces { max_cells, label: vec![0; n], members: vec![0; n] }
    }

    /// Turns every 8-connected region of {Φ > 0} of at most `max_cells` cells in the interior of
    /// `phi` to air (module docs), except the largest region of the field (the first of them in
    /// row-major order when several are as large), which is the deposit whatever `max_cells`.
    /// Returns the number of cells changed. The ghost layers are not touched (the stage fills
    /// them before the next use). Panics if `phi` holds more cells than the grid given to
    /// [`DetachedPieces::new`].
    pub fn remove(&mut self, phi: &mut Field) -> usize {
        let (nx, ny, st) = (phi.nx, phi.ny, phi.stride());
        let n = nx * ny;
        assert!(n <= self.label.len(), "a field of {n} cells for buffers of {}", self.label.len());
        if self.max_cells == 0 || n == 0 {
            return 0;
        }
        let at = |k: usize| (k / nx + HALO) * st + HALO + k % nx;
        let label = &mut self.label[..n];
        label.fill(0);
        let members = &mut self.members[..n];
        let values = phi.slice_mut();
        // the cells of the region of `start` with label `from`, relabelled `to`, into `members`
        // (breadth first, in a fixed order); returns how many
        let fill = |label: &mut [u32], members: &mut [u32], values: &[f64], start: usize, from: u32, to: u32| -> usize {
            label[start] = to;
            members[0] = start as u32;
            let (mut head, mut len) = (0usize, 1usize);
            while head < len {
                let k = members[head] as usize;
                head += 1;
                let (j, i) = (k / nx, k % nx);
                for jj in j.saturating_sub(1)..(j + 2).min(ny) {
                    for ii in i.saturating_sub(1)..(i + 2).min(nx) {
                        let m = jj * nx + ii;
                        if label[m] == from && values[at(m)] > 0.0 {
                            label[m] = to;
                            members[len] = m as u32;
                            len += 1;
                        }
                    }
                }
            }
            len
        };
        // every region labelled, and the largest found
        let (mut next, mut largest, mut largest_cells) = (0u32, 0u32, 0usize);
        for start in 0..n {
            if label[start] == 0 && values[at(start)] > 0.0 {
                next += 1;
                let cells = fill(label, members, values, start, 0, next);
                if cells > largest_cells {
                    (largest, largest_cells) = (next, cells);
                }
            }
        }
        // the others of at most max_cells cells: the level of the air around them (their
        // outer 8-neighbours all hold Φ ≤ 0, the region being a whole connected component)
        let mut changed = 0;
        for start in 0..n {
            let l = label[start];
            if l == 0 || l == largest {
                continue;
            }
            let len = fill(label, members, values, start, l, 0);
            if len > self.max_cells {
                continue;
            }
            let mut around = f64::NEG_INFINITY;
            for &k in &members[..len] {
                let (j, i) = (k as usize / nx, k as usize % nx);
                for jj in j.saturating_sub(1)..(j + 2).min(ny) {
                    for ii in i.saturating_sub(1)..(i + 2).min(nx) {
                        let v = values[at(jj * nx + ii)];
                        if v <= 0.0 {
                            around = around.max(v);
                        }
                    }
                }
            }
            if around == f64::NEG_INFINITY {
                continue; // nothing around it (cannot happen beside a larger region)
            }
            for &k in &members[..len] {
                values[at(k as usize)] = around;
            }
            changed += len;
        }
        changed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Location;
    use crate::levelset::dense_area;
    use crate::Exec;

    fn field(grid: &Grid, cells: &[(usize, usize, f64)]) -> Field {
        let mut phi = Field::from_fn(grid, Location::Centre, |_, _| -0.5 * grid.dx);
        for &(j, i, v) in cells {
            phi.interior_mut()[[j, i]] = v;
        }
        phi
    }

    #[test]
    fn a_speck_becomes_air_and_the_deposit_and_larger_pieces_stay() {
        let grid = Grid::new(16, 8, 1.6, 0.8).unwrap();
        let h = grid.dx;
        let mut cells = vec![];
        for j in 0..3 {
            for i in 0..6 {
                cells.push((j, i, 0.5 * h)); // the deposit, 18 cells
            }
        }
        cells.push((3, 6, 0.1 * h)); // touches the deposit's corner (2, 5): part of it
        cells.push((0, 8, 0.2 * h)); // a speck beyond a gap of one cell
        cells.push((1, 8, 0.1 * h)); // the speck's second cell
        for (j, i) in [(5, 12), (5, 13), (6, 12), (6, 13)] {
            cells.push((j, i, 0.3 * h)); // a piece of four cells
        }
        let mut phi = field(&grid, &cells);
        phi.interior_mut()[[2, 8]] = -0.2 * h; // the air just above the speck
        let before = phi.clone();
        let mut pieces = DetachedPieces::new(&grid, 3);
        assert_eq!(pieces.remove(&mut phi), 2);
        let (a, b) = (phi.interior(), before.interior());
        assert_eq!(a[[0, 8]], -0.2 * h, "the level of the air around the speck");
        assert_eq!(a[[1, 8]], -0.2 * h);
        for j in 0..8 {
            for i in 0..16 {
                if i != 8 || j > 1 {
                    assert_eq!(a[[j, i]], b[[j, i]], "({j}, {i}) unchanged");
                }
            }
        }
        // a piece of four cells goes with a limit of four
        let mut pieces = DetachedPieces::new(&grid, 4);
        let mut phi = before.clone();
        assert_eq!(pieces.remove(&mut phi), 6);
        assert!(phi.interior()[[5, 12]] <= 0.0 && phi.interior()[[3, 6]] > 0.0);
        // none with 0
        let mut phi = before.clone();
        assert_eq!(DetachedPieces::new(&grid, 0).remove(&mut phi), 0);
        assert_eq!(phi.interior(), before.interior());
    }

    #[test]
    fn the_area_removed_is_the_pieces_and_a_window_of_the_grid_is_accepted() {
        let grid = Grid::new(32, 16, 3.2, 1.6).unwrap();
        let h = grid.dx;
        let layer: Vec<_> = (0..32).map(|i| (0, i, 0.4 * h)).collect();
        let mut with = field(&grid, &[layer.as_slice(), &[(10, 20, 0.3 * h)]].concat());
        let without = field(&grid, &layer);
        assert_eq!(DetachedPieces::new(&grid, 1).remove(&mut with), 1);
        assert_eq!(dense_area(&with, &grid, Exec::SERIAL), dense_area(&without, &grid, Exec::SERIAL));
        // a field smaller than the grid (an active window)
        let window = Grid::new(8, 4, 0.8, 0.4).unwrap();
        let mut phi = field(&window, &[(0, 0, 0.2 * h), (0, 1, 0.2 * h), (2, 5, 0.2 * h)]);
        assert_eq!(DetachedPieces::new(&grid, 2).remove(&mut phi), 1);
        assert!(phi.interior()[[2, 5]] <= 0.0 && phi.interior()[[0, 0]] > 0.0);
    }

    #[test]
    fn the_largest_region_stays_whatever_the_limit() {
        // a limit larger than the deposit removes the smaller regions only; a lone region stays
        let grid = Grid::new(16, 8, 1.6, 0.8).unwrap();
        let h = grid.dx;
        let mut cells: Vec<_> = (0..6).map(|i| (0, i, 0.5 * h)).collect();
        cells.extend([(0, 10, 0.2 * h), (0, 11, 0.2 * h), (5, 14, 0.1 * h)]);
        let mut phi = field(&grid, &cells);
        assert_eq!(DetachedPieces::new(&grid, 1_000_000).remove(&mut phi), 3);
        assert!((0..6).all(|i| phi.interior()[[0, i]] > 0.0));
        let mut lone = field(&grid, &[(3, 3, 0.2 * h)]);
        assert_eq!(DetachedPieces::new(&grid, 1_000_000).remove(&mut lone), 0);
        // two regions as large: the first in row-major order is kept
        let mut twins = field(&grid, &[(0, 0, 0.2 * h), (0, 8, 0.2 * h)]);
        assert_eq!(DetachedPieces::new(&grid, 4).remove(&mut twins), 1);
        assert!(twins.interior()[[0, 0]] > 0.0 && twins.interior()[[0, 8]] <= 0.0);
    }
}
