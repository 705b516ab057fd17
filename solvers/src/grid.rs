//! The uniform voxel grid shared by every method.

use crate::SolverError;

/// A uniform 3D grid of `nx × ny × nz` cubic voxels of edge `dl`, whose corner is at `origin`.
///
/// Voxel `(i, j, k)` has its centre at `origin + (i + ½, j + ½, k + ½)·dl` and linear index
/// `i + nx·(j + ny·k)` (x fastest), the layout of every field in this crate and of Mitsuba's
/// `.vol` files.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Voxels along x, y, z.
    pub n: [usize; 3],
    /// Voxel edge length Δl.
    pub dl: f64,
    /// Position of the grid's lower corner.
    pub origin: [f64; 3],
}

impl Grid {
    /// A grid with its lower corner at the origin. Fails if an axis has fewer than 3 voxels
    /// or `dl` is not finite and positive.
    pub fn new(n: [usize; 3], dl: f64) -> Result<Self, SolverError> {
        Self::with_origin(n, dl, [0.0; 3])
    }

    /// A cubic grid of `n³` voxels spanning `[0, extent]³`.
    pub fn cube(n: usize, extent: f64) -> Result<Self, SolverError> {
        if n == 0 {
            return Err(SolverError::GridTooSmall { axis: 'x', n });
        }
        Self::new([n; 3], extent / n as f64)
    }

    /// A grid with an explicit lower corner.
    pub fn with_origin(n: [usize; 3], dl: f64, origin: [f64; 3]) -> Result<Self, SolverError> {
        for (axis, &ni) in ['x', 'y', 'z'].iter().zip(&n) {
            if ni < 3 {
                return Err(SolverError::GridTooSmall { axis: *axis, n: ni });
            }
        }
        if !(dl.is_finite() && dl > 0.0) {
            return Err(SolverError::BadVoxelSize(dl));
        }
        n[0].checked_mul(n[1])
            .and_then(|v| v.checked_mul(n[2]))
            .filter(|&v| v <= isize::MAX as usize / 16)
            .ok_or(SolverError::GridTooLarge {
                nx: n[0],
                ny: n[1],
                nz: n[2],
            })?;
        Ok(Self { n, dl, origin })
    }

    /// Total number of voxels.
    pub fn len(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    /// Always false: a valid grid has at least 27 voxels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Linear index of voxel `(i, j, k)` (x fastest).
    #[inline(always)]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.n[0] * (j + self.n[1] * k)
    }

    /// Inverse of [`Grid::index`].
    #[inline(always)]
    pub fn coords(&self, index: usize) -> [usize; 3] {
        let i = index % self.n[0];
        let jk = index / self.n[0];
        [i, jk % self.n[1], jk / self.n[1]]
    }

    /// Centre of voxel `(i, j, k)`.
    #[inline(always)]
    pub fn center(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.origin[0] + (i as f64 + 0.5) * self.dl,
            self.origin[1] + (j as f64 + 0.5) * self.dl,
            self.origin[2] + (k as f64 + 0.5) * self.dl,
        ]
    }

    /// Edge lengths of the box, `n·dl` per axis.
    pub fn size(&self) -> [f64; 3] {
        [
            self.n[0] as f64 * self.dl,
            self.n[1] as f64 * self.dl,
            self.n[2] as f64 * self.dl,
        ]
    }

    /// The grid extent L of FLD Section 5 (used for σ_ε = 10⁻³/L): the longest edge.
    pub fn extent(&self) -> f64 {
        self.size().into_iter().fold(0.0, f64::max)
    }

    /// Whether voxel `(i, j, k)` lies in the outermost layer, where the Dirichlet boundary
    /// values live (FLD Section 5: "ignoring the voxels abutting the six grid faces").
    #[inline(always)]
    pub fn is_boundary(&self, i: usize, j: usize, k: usize) -> bool {
        i == 0 || j == 0 || k == 0 || i + 1 == self.n[0] || j + 1 == self.n[1] || k + 1 == self.n[2]
    }

    /// The linear indices of the voxels inside the boundary layer (not [`Grid::is_boundary`]),
    /// in index order.
    pub fn interior(&self) -> impl Iterator<Item = usize> + use<> {
        let g = *self;
        (0..g.len()).filter(move |&p| {
            let [i, j, k] = g.coords(p);
            !g.is_boundary(i, j, k)
        })
    }

    /// Samples `f` at every voxel centre, in index order.
    pub fn sample<T>(&self, mut f: impl FnMut([f64; 3]) -> T) -> Vec<T> {
        let mut out = Vec::with_capacity(self.len());
        for k in 0..self.n[2] {
            for j in 0..self.n[1] {
                for i in 0..self.n[0] {
                    out.push(f(self.center(i, j, k)));
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_and_coords_are_inverse() {
        let g = Grid::new([5, 4, 3], 0.5).unwrap();
        for idx in 0..g.len() {
            let [i, j, k] = g.coords(idx);
            assert_eq!(g.index(i, j, k), idx);
        }
    }

    #[test]
    fn interior_is_the_box_inside_the_layer() {
        let g = Grid::new([5, 4, 3], 0.5).unwrap();
        let inner: Vec<usize> = g.interior().collect();
        assert_eq!(
            inner,
            [
                g.index(1, 1, 1),
                g.index(2, 1, 1),
                g.index(3, 1, 1),
                g.index(1, 2, 1),
                g.index(2, 2, 1),
                g.index(3, 2, 1)
            ]
        );
    }

    #[test]
    fn bad_grids_are_errors() {
        assert!(matches!(
            Grid::new([2, 5, 5], 1.0),
            Err(SolverError::GridTooSmall { axis: 'x', n: 2 })
        ));
        assert!(matches!(
            Grid::new([5, 5, 5], 0.0),
            Err(SolverError::BadVoxelSize(_))
        ));
        assert!(matches!(
            Grid::new([5, 5, 5], f64::NAN),
            Err(SolverError::BadVoxelSize(_))
        ));
        assert!(Grid::new([usize::MAX / 2, 4, 4], 1.0).is_err());
    }
}
