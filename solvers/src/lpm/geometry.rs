//! Per-(direction, slab) sub-segment tables (spec §1.6, D5, D17).
//!
//! The rays of one direction start at the centres of the entry face's cells and share one
//! direction, so their crossings within slab z are identical up to an integer lateral
//! shift: one table entry per (direction, slab) describes every ray. Positions are exact
//! rationals: in units of 1/(2m) voxel the lateral coordinate of a ray at slab z and slab
//! fraction t is X = m + 2U(z + t) with the integer U = 2p + 1 − m, so a crossing of the
//! voxel boundary 2mK happens at t = (2mK − m − 2Uz)/(2U), a correctly rounded quotient of
//! two exact integers. Equal crossing times are therefore bitwise equal and zero-length
//! sub-segments (ties, e.g. m even) are dropped exactly.

use super::directions::Direction;

/// One sub-segment of a ray inside one slab.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seg {
    /// Lateral voxel offsets (b, c) of the sub-segment relative to the ray's lattice index
    /// (absolute, not reduced modulo the grid: the lattice index plus the offset, modulo the
    /// lateral size, is the voxel; a change of the quotient is a wrap event).
    pub offset: [i64; 2],
    /// Euclidean length in units of the voxel edge h.
    pub len: f64,
}

/// The sub-segments of one direction, slab by slab in sweep order.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectionTable {
    /// `segs[start[z]..start[z + 1]]` are the sub-segments of slab z (sweep order), in the
    /// order the rays traverse them.
    pub segs: Vec<Seg>,
    /// Offsets into `segs`, one per slab plus one.
    pub start: Vec<usize>,
}

impl DirectionTable {
    /// The table of `dir` over `slabs` slabs (m cells per face edge).
    pub fn new(dir: &Direction, m: usize, slabs: usize) -> Self {
        let m = m as i64;
        let [ub, uc] = dir.drift_num;
        let len_per_slab = 1.0 / dir.cos_axis;
        let mut segs = Vec::with_capacity(3 * slabs);
        let mut start = Vec::with_capacity(slabs + 1);
        // The crossing time in (0, 1) of one lateral axis, if any.
        let crossing = |u: i64, z: i64| -> Option<f64> {
            if u == 0 {
                return None;
            }
            let x0 = m + 2 * u * z;
            let x1 = x0 + 2 * u;
            let (lo, hi) = (x0.min(x1), x0.max(x1));
            // The multiple of 2m strictly inside (lo, hi); |2u| < 2m so at most one.
            let k = (lo.div_euclid(2 * m) + 1) * 2 * m;
            (k < hi).then(|| (k - x0) as f64 / (2 * u) as f64)
        };
        for z in 0..slabs as i64 {
            start.push(segs.len());
            let mut ts = vec![0.0, 1.0];
            ts.extend(crossing(ub, z));
            ts.extend(crossing(uc, z));
            ts.sort_by(f64::total_cmp);
            ts.dedup();
            for w in ts.windows(2) {
                let (t0, t1) = (w[0], w[1]);
                let tm = 0.5 * (t0 + t1);
                // Lateral positions at the midpoint, in voxels relative to the lattice index.
                let pos = |u: i64| 0.5 + (z as f64 + tm) * u as f64 / m as f64;
                segs.push(Seg {
                    offset: [pos(ub).floor() as i64, pos(uc).floor() as i64],
                    len: (t1 - t0) * len_per_slab,
                });
            }
        }
        start.push(segs.len());
        Self { segs, start }
    }

    /// The sub-segments of slab z.
    pub fn slab(&self, z: usize) -> &[Seg] {
        &self.segs[self.start[z]..self.start[z + 1]]
    }
}
