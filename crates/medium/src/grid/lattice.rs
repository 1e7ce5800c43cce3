//! The cells a ray crosses on a regular lattice of blocks of voxels: 3D-DDA (Amanatides and
//! Woo 1987). With blocks of one voxel it walks the voxels themselves (optical depths, regular
//! tracking); with larger blocks it walks the macro cells of local-majorant tracking
//! ([`super::macro_cells`]). A block's faces are voxel planes computed exactly as the voxels'
//! own, so the two walks agree on where a ray crosses them.

use glam::DVec3;

/// A lattice of blocks of `stride` voxels per axis over a voxel grid (the last block of an axis
/// may be partial).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Lattice {
    /// The box's lower corner.
    pub min: DVec3,
    /// The box's upper corner.
    pub max: DVec3,
    /// Voxel counts per axis.
    pub voxels: [usize; 3],
    /// Voxels per block edge, per axis (at least 1).
    pub stride: [usize; 3],
    /// Blocks per axis, `ceil(voxels / stride)`.
    pub dims: [usize; 3],
    /// Voxel edge lengths (zero along `z` in flatland).
    pub cell: DVec3,
    /// `1 / cell` (zero along `z` in flatland).
    pub inv_cell: DVec3,
}

impl Lattice {
    /// The lattice of blocks of `stride` voxels.
    pub fn new(
        min: DVec3,
        max: DVec3,
        voxels: [usize; 3],
        cell: DVec3,
        inv_cell: DVec3,
        stride: [usize; 3],
    ) -> Self {
        let dims = [0, 1, 2].map(|a| voxels[a].div_ceil(stride[a].max(1)));
        Self {
            min,
            max,
            voxels,
            stride: stride.map(|s| s.max(1)),
            dims,
            cell,
            inv_cell,
        }
    }

    /// Coordinate of the `k`-th block plane along axis `a`: voxel plane `k stride`, the box's
    /// upper face exactly at or beyond the last voxel.
    #[inline]
    pub fn plane(&self, a: usize, k: usize) -> f64 {
        let v = k * self.stride[a];
        if v >= self.voxels[a] {
            self.max[a]
        } else {
            self.min[a] + v as f64 * self.cell[a]
        }
    }

    /// Walks the blocks crossed by `o + t d` for `t` in `[t0, t1]` (an interval inside the box,
    /// from `Aabb::clip`), calling `f(block, t_in, t_out)` for each, in order, until `f` returns
    /// `false`. Stretches are contiguous and non-decreasing; rounding may make some of zero
    /// length.
    pub fn walk(
        &self,
        o: DVec3,
        d: DVec3,
        t0: f64,
        t1: f64,
        mut f: impl FnMut([usize; 3], f64, f64) -> bool,
    ) {
        let p = o + t0 * d;
        let mut idx = [0usize; 3];
        let mut step = [0isize; 3];
        let mut t_next = [f64::INFINITY; 3];
        let inv_d = d.recip();
        for a in 0..3 {
            let n = self.dims[a];
            if n == 1 {
                // No inner planes (always the case for z in flatland).
                continue;
            }
            let c = (p[a] - self.min[a]) * self.inv_cell[a];
            let s = self.stride[a];
            if d[a] > 0.0 {
                idx[a] = ((c as usize) / s).min(n - 1);
                step[a] = 1;
                t_next[a] = (self.plane(a, idx[a] + 1) - o[a]) * inv_d[a];
            } else if d[a] < 0.0 {
                // A point on voxel plane k moving down is in voxel k - 1.
                idx[a] = (((c.ceil() - 1.0).max(0.0) as usize) / s).min(n - 1);
                step[a] = -1;
                t_next[a] = (self.plane(a, idx[a]) - o[a]) * inv_d[a];
            } else {
                idx[a] = ((c as usize) / s).min(n - 1);
            }
        }
        let mut t = t0;
        loop {
            let a = if t_next[0] <= t_next[1] {
                if t_next[0] <= t_next[2] { 0 } else { 2 }
            } else if t_next[1] <= t_next[2] {
                1
            } else {
                2
            };
            let t_cross = t_next[a];
            let end = t_cross.min(t1).max(t);
            if !f(idx, t, end) || t_cross >= t1 {
                return;
            }
            t = end;
            let next = idx[a] as isize + step[a];
            if next < 0 || next >= self.dims[a] as isize {
                // Left the grid a rounding error before t1.
                return;
            }
            idx[a] = next as usize;
            let k = if step[a] > 0 { idx[a] + 1 } else { idx[a] };
            t_next[a] = (self.plane(a, k) - o[a]) * inv_d[a];
        }
    }
}
