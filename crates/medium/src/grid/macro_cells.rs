//! Local majorants for delta tracking ([`super::Tracking::Local`]): the grid cut into blocks of
//! voxels (macro cells), each with the largest `sigma_t` of its voxels. A flight draws one
//! optical depth `tau = -ln(1 - u)` of the majorant medium and walks the macro cells, spending
//! `majorant x length` of it in each; where it runs out, a tentative collision is accepted as
//! real with probability `sigma_t(x) / majorant` (else a fresh `tau` from there). The majorant
//! medium is piecewise constant and bounds `sigma_t` everywhere, so the flights have exactly the
//! distribution of delta tracking against one global majorant (and of regular tracking), while
//! a flight through a sparse region takes few tentative collisions there: a small dense region
//! (a vessel, an inclusion) no longer sets the collision rate in the whole box.
//!
//! The block edge is the step over which one majorant holds: Belcour et al. 2014 (Algorithm 1)
//! march with a step set by the local bandwidth, which is biased for a tracer that must be
//! exact; here the step is where the bound is re-evaluated, and it is chosen by a cost model
//! ([`MacroCells::build`]) in units of one tentative collision, per flight of the mean length
//! `1 / sigma_bar` (`sigma_bar` the mean extinction over the box):
//!
//! - one global majorant (delta tracking): `1 + M / sigma_bar` (`M = max sigma_t`; the 1 is
//!   what every flight costs besides its tentative collisions);
//! - blocks of edge `b`: `1 + SETUP + (M_b + X_b) / sigma_bar`, `M_b` the volume-weighted mean
//!   of the blocks' majorants, `X_b = sum_a E|d_a| / edge_a` the block faces an isotropic ray
//!   crosses per unit length (one tentative collision's cost each), `SETUP` the walk's set-up.
//!
//! `SETUP = 0.5` from `benches/flights.rs`: on the layered head, where one global majorant is
//! nearly tight (110 /cm against a mean of 97), blocks of two voxels took 1.24 times as long
//! per flight; the model keeps the global majorant there and takes blocks where a small dense
//! region sets it (a 2 mm cube of 1000 /cm in a 4 cm cube of 10 /cm: 15 times faster).

use super::lattice::Lattice;
use glam::DVec3;

/// The macro cells of a grid: a block lattice and each block's majorant.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct MacroCells {
    /// The blocks.
    pub lattice: Lattice,
    /// `max sigma_t` over each block's voxels, C order of the block indices.
    pub majorant: Vec<f64>,
}

impl MacroCells {
    /// Blocks of `stride` voxels over a grid whose voxels (C order, `dims`) have extinctions
    /// `sigma_t`; `voxels` is the grid's own voxel lattice (stride 1).
    pub fn with_stride(voxels: &Lattice, sigma_t: &[f64], stride: [usize; 3]) -> Self {
        let lattice = Lattice::new(
            voxels.min,
            voxels.max,
            voxels.voxels,
            voxels.cell,
            voxels.inv_cell,
            stride,
        );
        let [nx, ny, nz] = voxels.voxels;
        let [bx, by, bz] = lattice.dims;
        let s = lattice.stride;
        let mut majorant = vec![0.0f64; bx * by * bz];
        for ix in 0..nx {
            for iy in 0..ny {
                let row = (ix * ny + iy) * nz;
                let block_row = ((ix / s[0]) * by + iy / s[1]) * bz;
                for iz in 0..nz {
                    let m = &mut majorant[block_row + iz / s[2]];
                    *m = m.max(sigma_t[row + iz]);
                }
            }
        }
        Self { lattice, majorant }
    }

    /// The walk's set-up per flight, in tentative collisions (module docs).
    pub const SETUP: f64 = 0.5;

    /// The macro cells of the cheapest cubic block (in voxels: 1, 2, 4, ... below the largest
    /// voxel count) by the cost model of the module docs, with its cost per flight and that of
    /// one global majorant (`None` for the cells when no block size beats it).
    pub fn build(voxels: &Lattice, sigma_t: &[f64], flat: bool) -> (Option<Self>, f64, f64) {
        let largest = voxels.voxels.iter().copied().max().unwrap_or(1);
        let volume = |a: usize| voxels.cell[a] * voxels.voxels[a] as f64;
        // E|d_a| of an isotropic direction: 1/2 in 3D, 2/pi in flatland (x and y only).
        let mean_abs = if flat {
            2.0 / std::f64::consts::PI
        } else {
            0.5
        };
        let axes = if flat { 2 } else { 3 };
        let sigma_bar = sigma_t.iter().sum::<f64>() / sigma_t.len().max(1) as f64;
        let global_majorant = sigma_t.iter().fold(0.0f64, |m, &t| m.max(t));
        let per_flight = |work: f64| {
            if sigma_bar > 0.0 {
                work / sigma_bar
            } else {
                0.0
            }
        };
        let global = 1.0 + per_flight(global_majorant);
        let mut best: Option<(Self, f64)> = None;
        let mut b = 1usize;
        while b < largest {
            let stride = [b, b, if flat { 1 } else { b }];
            let cells = Self::with_stride(voxels, sigma_t, stride);
            // Volume-weighted mean majorant (partial blocks weigh less).
            let mut weighted = 0.0;
            let l = &cells.lattice;
            for (i, &m) in cells.majorant.iter().enumerate() {
                let idx = [
                    i / (l.dims[1] * l.dims[2]),
                    (i / l.dims[2]) % l.dims[1],
                    i % l.dims[2],
                ];
                let frac: f64 = (0..axes)
                    .map(|a| {
                        let lo = idx[a] * l.stride[a];
                        let hi = (lo + l.stride[a]).min(l.voxels[a]);
                        (hi - lo) as f64 / l.voxels[a] as f64
                    })
                    .product();
                weighted += m * frac;
            }
            let crossings: f64 = (0..axes)
                .map(|a| {
                    let edge = (l.stride[a].min(l.voxels[a]) as f64) * voxels.cell[a];
                    // One block along the axis: no inner faces.
                    if l.dims[a] == 1 || volume(a) == 0.0 {
                        0.0
                    } else {
                        mean_abs / edge
                    }
                })
                .sum();
            let cost = 1.0 + Self::SETUP + per_flight(weighted + crossings);
            if best.as_ref().is_none_or(|(_, c)| cost < *c) {
                best = Some((cells, cost));
            }
            b *= 2;
        }
        match best {
            Some((cells, cost)) if cost < global => (Some(cells), cost, global),
            _ => (None, global, global),
        }
    }

    /// A flight along `x + t dir`, `t` in `[t0, t1]` inside the box: the distance to the first
    /// real collision, `None` past `t1`. `sigma_t(t)` is the extinction at `x + t dir`.
    pub fn flight(
        &self,
        x: DVec3,
        dir: DVec3,
        t0: f64,
        t1: f64,
        sigma_t: impl Fn(f64) -> f64,
        next: &mut dyn FnMut() -> f64,
    ) -> Option<f64> {
        let l = &self.lattice;
        let mut tau = -(1.0 - next()).ln();
        let mut hit = None;
        self.lattice.walk(x, dir, t0, t1, |b, t_in, t_out| {
            let m = self.majorant[(b[0] * l.dims[1] + b[1]) * l.dims[2] + b[2]];
            let mut t = t_in;
            loop {
                let room = m * (t_out - t);
                let inside = tau < room;
                if !inside {
                    // Through this block (also where m = 0): carry what is left of tau.
                    tau -= room.max(0.0);
                    return true;
                }
                t = (t + tau / m).clamp(t, t_out);
                let st = sigma_t(t);
                // Real with probability sigma_t / majorant; certain (no variate) where equal.
                if st >= m || next() * m < st {
                    hit = Some(t);
                    return false;
                }
                tau = -(1.0 - next()).ln();
            }
        });
        hit.filter(|&t| t < t1)
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Material, Tracking, VoxelGrid};
    use super::*;
    use crate::testing::{KS_CRITICAL_0_001, ks_distance, uniform_stream};
    use crate::{Aabb, Medium};

    /// A 6 x 5 x 4 grid of high contrast: extinctions from 0.05 to 20 (a tenth of the voxels at
    /// the top, some empty), scattering half of it.
    fn contrast_grid(seed: u64) -> VoxelGrid {
        let mut next = uniform_stream(seed);
        let b = Aabb::new(DVec3::new(-1.0, -2.0, 0.5), DVec3::new(3.0, 1.0, 2.5)).unwrap();
        let n = 6 * 5 * 4;
        let density: Vec<f64> = (0..n)
            .map(|i| match i % 10 {
                0 => 20.0 * next(),
                1 => 0.0,
                _ => 0.05 + 0.5 * next(),
            })
            .collect();
        VoxelGrid::from_densities(b, [6, 5, 4], density, Material::single(0.5, 0.5), 0.0).unwrap()
    }

    #[test]
    fn majorants_are_the_largest_extinction_of_their_blocks() {
        let g = contrast_grid(1);
        for stride in [[1, 1, 1], [2, 3, 1], [4, 4, 4], [6, 5, 4], [9, 9, 9]] {
            let c = MacroCells::with_stride(&g.voxels(), &g.sigma_t, stride);
            let l = &c.lattice;
            let mut expect = vec![0.0f64; c.majorant.len()];
            for (i, &st) in g.sigma_t.iter().enumerate() {
                let (ix, iy, iz) = (i / 20, (i / 4) % 5, i % 4);
                let b = ((ix / l.stride[0]) * l.dims[1] + iy / l.stride[1]) * l.dims[2]
                    + iz / l.stride[2];
                expect[b] = expect[b].max(st);
            }
            assert_eq!(c.majorant, expect, "{stride:?}");
        }
    }

    /// Flights with blocks of 1, 2, 3 (partial blocks) and 6 voxels (one block: global delta
    /// tracking) from 40 random points and directions, 2000 each: the escape probability
    /// `exp(-tau)` (pooled: observed escapes against `sum p`, within 4 SE of `sum p (1 - p)`)
    /// and the first-collision distance, whose CDF given a collision is `(1 - e^-tau(t)) /
    /// (1 - e^-tau)` with the exact (DDA) optical depths: the transformed distances of all
    /// flights pooled must be uniform (KS at the 0.001 level).
    #[test]
    fn local_flights_have_the_exact_distribution() {
        let g = contrast_grid(2);
        let mut pick = uniform_stream(3);
        let b = *g.bounds();
        let starts: Vec<(DVec3, DVec3)> = (0..40)
            .map(|_| {
                let x = b.min() + DVec3::new(pick(), pick(), pick()) * b.size();
                let z = 1.0 - 2.0 * pick();
                let phi = std::f64::consts::TAU * pick();
                let r = (1.0 - z * z).sqrt();
                (x, DVec3::new(r * phi.cos(), r * phi.sin(), z))
            })
            .collect();
        for stride in [1, 2, 3, 6] {
            let mut l = g.clone().with_tracking(Tracking::Local);
            l.macro_cells = Some(Box::new(MacroCells::with_stride(
                &g.voxels(),
                &g.sigma_t,
                [stride; 3],
            )));
            let mut next = uniform_stream(10 + stride as u64);
            let (mut escaped, mut expect, mut var) = (0.0, 0.0, 0.0);
            let mut u = Vec::new();
            for &(x, dir) in &starts {
                let exit = b.exit_distance(x, dir);
                let total = g.optical_depth(x, x + exit * dir);
                let p = (-total).exp();
                expect += 2000.0 * p;
                var += 2000.0 * p * (1.0 - p);
                for _ in 0..2000 {
                    match l.sample_flight(x, dir, &mut next) {
                        None => escaped += 1.0,
                        Some(t) => {
                            let tau = g.optical_depth(x, x + t * dir);
                            u.push(-(-tau).exp_m1() / -(-total).exp_m1());
                        }
                    }
                }
            }
            let z = (escaped - expect) / var.sqrt();
            let ks = ks_distance(u, |v| v);
            eprintln!("blocks of {stride}: escapes z = {z:+.2}, KS sqrt(n) D = {ks:.3}");
            assert!(z.abs() < 4.0, "blocks of {stride}: z = {z}");
            assert!(ks < KS_CRITICAL_0_001, "blocks of {stride}: KS {ks}");
        }
    }

    #[test]
    fn the_cost_model_keeps_one_block_for_a_uniform_grid_and_splits_a_dense_layer() {
        let b = Aabb::new(DVec3::ZERO, DVec3::new(4.0, 4.0, 4.0)).unwrap();
        let m = Material::single(0.9, 0.1);
        let uniform =
            VoxelGrid::from_densities(b, [16, 16, 16], vec![1.0; 4096], m.clone(), 0.0).unwrap();
        let (edge, cost, global) = uniform.local_majorant_plan();
        assert_eq!((edge, cost), (None, global));
        // One layer of 16 along z is 50 times denser: blocks of a few voxels win.
        let layered: Vec<f64> = (0..4096)
            .map(|i| if i % 16 == 5 { 50.0 } else { 1.0 })
            .collect();
        let g = VoxelGrid::from_densities(b, [16, 16, 16], layered, m, 0.0).unwrap();
        let (edge, cost, global) = g.local_majorant_plan();
        eprintln!("dense layer: blocks of {edge:?}, cost {cost:.2} against {global:.2} per flight");
        assert!(
            edge.is_some() && cost < 0.5 * global,
            "{edge:?} {cost} {global}"
        );
    }
}
