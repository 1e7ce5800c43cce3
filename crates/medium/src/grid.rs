//! Heterogeneous media on a regular voxel grid.

use crate::{Aabb, Medium, MediumError, TypeMix};
use glam::DVec3;
use lattice::Lattice;
use macro_cells::MacroCells;

mod lattice;
mod macro_cells;

/// The most voxels a [`VoxelGrid`] may hold, `2^27` (about 134 million). The grid keeps about
/// 24 bytes per voxel (`sigma_s`, `sigma_t` and a sampling table, plus 4 for a material id), so
/// the limit is near 3.5 GB.
pub const MAX_VOXELS: usize = 1 << 27;

/// Largest `f64` below one: the top of the half-open unit interval.
const ONE_BELOW: f64 = 1.0 - f64::EPSILON / 2.0;

/// The bulk coefficients of one material and the particle types it is made of.
///
/// `types` uses the scene's global type indices: a material made only of particles of type 2 is
/// `TypeMix::single(2)`. `sigma_s = 0` is allowed in a grid (absorbing or vacuum voxels).
/// A plain description, validated by the grid constructors, which name the offending field
/// (`materials[3].sigma_a`).
///
/// ```
/// use speckle_medium::{Material, TypeMix};
/// let fat = Material::new(0.8, 0.01, TypeMix::single(2).unwrap());
/// assert_eq!(fat.sigma_t(), 0.81);
/// let ink = Material::single(0.0, 5.0); // absorbs, does not scatter
/// assert_eq!(ink.types.type_count(), 1);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Scattering coefficient `sigma_s >= 0` (Eq. 43).
    pub sigma_s: f64,
    /// Absorption coefficient `sigma_a >= 0` (Eq. 43).
    pub sigma_a: f64,
    /// Probabilities `beta_iota` of the particle types hit by a scattering event (Eq. 44).
    pub types: TypeMix,
}

impl Material {
    /// A material from its fields (validated by the grid constructors).
    pub fn new(sigma_s: f64, sigma_a: f64, types: TypeMix) -> Self {
        Self {
            sigma_s,
            sigma_a,
            types,
        }
    }

    /// A material of particle type 0 alone.
    pub fn single(sigma_s: f64, sigma_a: f64) -> Self {
        Self::new(sigma_s, sigma_a, TypeMix::one())
    }

    /// Vacuum: no scattering, no absorption.
    pub fn vacuum() -> Self {
        Self::single(0.0, 0.0)
    }

    /// Extinction coefficient `sigma_s + sigma_a`.
    pub fn sigma_t(&self) -> f64 {
        self.sigma_s + self.sigma_a
    }
}

/// Delta tracking's tentative collisions across the box (the majorant times its diagonal)
/// above which a grid tracks regularly by default: a grid with one voxel (or layer) far
/// denser than the rest, 1e15 /cm of absorption in a head's CSF, would otherwise take 1e16
/// null collisions per flight (a hang).
pub const MAX_DELTA_COLLISIONS: f64 = 1e6;

/// How a [`VoxelGrid`] samples free flights ([`Medium::sample_flight`]); by default delta
/// tracking, unless its majorant times the box's diagonal exceeds [`MAX_DELTA_COLLISIONS`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tracking {
    /// Delta (Woodcock) tracking against the global majorant `sigma_bar = max sigma_t`: tentative
    /// collisions at rate `sigma_bar`, each accepted as real with probability
    /// `sigma_t(x) / sigma_bar` (no variate is drawn where the ratio is one). Unbiased; costs
    /// about `sigma_bar` times the distance flown, independent of the voxel count.
    #[default]
    Delta,
    /// Regular tracking: one variate `tau = -ln(1 - u)`, then a walk through the voxels (3D-DDA)
    /// until the optical depth reaches `tau`. Exact; costs one step per voxel crossed, whatever
    /// the contrast of the grid.
    Regular,
    /// Delta tracking against local majorants: the largest `sigma_t` of each block of voxels
    /// (macro cell), the block's edge chosen by a cost model when the grid is built
    /// ([`VoxelGrid::with_tracking`]; `macro_cells.rs`). Unbiased, the same flight distribution
    /// as [`Tracking::Delta`]; costs the blocks crossed plus the tentative collisions at each
    /// block's own majorant, so a small dense region no longer sets the rate everywhere. Where
    /// the model finds no block size cheaper than one global majorant it is [`Tracking::Delta`]
    /// (the same flights, bitwise).
    Local,
}

/// A heterogeneous medium on an `nx x ny x nz` grid of equal voxels filling an axis-aligned box;
/// each voxel has its own `sigma_s`, `sigma_a` and particle-type mix (Bar et al. 2019, Eqs. 7-8
/// and 43-44 with spatially varying `N_iota(x)`). Outside the box is vacuum.
///
/// # Data layout
/// Voxel values are given in C order of a numpy array of shape `(nx, ny, nz)`: `x` slowest, `z`
/// fastest, voxel `(ix, iy, iz)` at index `(ix * ny + iy) * nz + iz`; voxel `(ix, iy, iz)`
/// spans `[min + i * size / n, min + (i + 1) * size / n]` on each axis. A flatland grid has
/// flat bounds ([`Aabb::flat`]) and `nz = 1`: the numpy shape `(nx, ny)`. A point on a face
/// between two voxels belongs to the voxel above it (floor convention); a point on the box's
/// upper face to the last voxel.
///
/// # Algorithms
/// - `sigma_s(x)`, `sigma_t(x)`: voxel lookup.
/// - Optical depths: exact, by 3D-DDA traversal (Amanatides and Woo 1987) of the part of the
///   segment or ray inside the box, summing `sigma_t` times the length in each voxel (runs of
///   equal `sigma_t` are merged, so a constant grid reproduces the homogeneous value).
/// - Flights: delta tracking with the global majorant by default (regular tracking where that
///   would take more than [`MAX_DELTA_COLLISIONS`] steps across the box), or as chosen
///   ([`Tracking`], [`VoxelGrid::with_tracking`]). `None` when the flight leaves the box.
/// - `scattering_volume = sum_voxels sigma_s * voxel measure` (Eq. 35); `sample_scatterer`
///   picks a voxel with probability `sigma_s * measure / V` with `u[0]`, then reuses the
///   rescaled remainder of `u[0]` and `u[1]`, `u[2]` for the position inside the voxel.
/// - `uniform_sigma_t()` is `Some` only when every voxel has the same `sigma_t`.
/// - `particle_types()` is the largest [`TypeMix::type_count`] over the materials.
///
/// ```
/// use speckle_medium::{Aabb, DVec3, Material, Medium, VoxelGrid};
/// // Two layers along z: sigma_t = 1 below z = 1, sigma_t = 3 above.
/// let b = Aabb::new(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap();
/// let g = VoxelGrid::from_densities(b, [1, 1, 2], vec![1.0, 3.0], Material::single(0.9, 0.1), 0.0)
///     .unwrap();
/// let od = g.optical_depth(DVec3::new(1.0, 1.0, -1.0), DVec3::new(1.0, 1.0, 3.0));
/// assert!((od - 4.0).abs() < 1e-12);
/// assert_eq!(g.sigma_t(DVec3::new(1.0, 1.0, 1.5)), 3.0);
/// assert!((g.scattering_volume() - 0.9 * 16.0 * 4.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelGrid {
    bounds: Aabb,
    dims: [usize; 3],
    /// Voxel edge lengths `size / dims` (zero along `z` in flatland).
    cell: DVec3,
    /// `dims / size` (zero along `z` in flatland).
    inv_cell: DVec3,
    sigma_s: Vec<f64>,
    sigma_t: Vec<f64>,
    /// Per-voxel index into `mixes`; empty when there is a single mix.
    mix_id: Vec<u32>,
    mixes: Vec<TypeMix>,
    particle_types: usize,
    majorant: f64,
    uniform_sigma_t: Option<f64>,
    scattering_volume: f64,
    /// Normalised cumulative `sigma_s` over voxels, exactly 1 from `last_scatterer` on.
    scatter_cdf: Vec<f64>,
    last_scatterer: usize,
    tracking: Tracking,
    /// The macro cells of [`Tracking::Local`] (built when it is chosen and pays).
    macro_cells: Option<Box<MacroCells>>,
}

fn shape(flat: bool, dims: [usize; 3]) -> String {
    if flat {
        format!("(nx, ny) = ({}, {})", dims[0], dims[1])
    } else {
        format!("(nx, ny, nz) = ({}, {}, {})", dims[0], dims[1], dims[2])
    }
}

fn coefficient(field: impl FnOnce() -> String, value: f64) -> Result<f64, MediumError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(MediumError::param(
            field(),
            format!("must be finite and >= 0 (got {value})"),
        ))
    }
}

/// Checks `dims` against the bounds and the data length; returns the voxel count.
fn check_dims(
    bounds: &Aabb,
    dims: [usize; 3],
    len: usize,
    what: &str,
) -> Result<usize, MediumError> {
    let flat = bounds.dimension() == crate::Dimension::Two;
    if dims.contains(&0) {
        return Err(MediumError::param(
            "dims",
            format!("every dimension must be >= 1 (got {dims:?})"),
        ));
    }
    if flat && dims[2] != 1 {
        return Err(MediumError::param(
            "dims",
            format!("a flatland grid (flat bounds, zero z extent) has nz = 1 (got {dims:?})"),
        ));
    }
    let count = dims
        .iter()
        .try_fold(1usize, |acc, &n| acc.checked_mul(n))
        .filter(|&c| c <= MAX_VOXELS)
        .ok_or_else(|| {
            MediumError::param(
                "dims",
                format!("{dims:?} exceeds the limit of {MAX_VOXELS} voxels (about 28 bytes each)"),
            )
        })?;
    if len != count {
        return Err(MediumError::param(
            what,
            format!(
                "expected {count} values, the C-order data (x slowest, z fastest) of a numpy \
                 array of shape {}, got {len}",
                shape(flat, dims)
            ),
        ));
    }
    let size = bounds.size();
    for a in 0..if flat { 2 } else { 3 } {
        let (c, inv) = (size[a] / dims[a] as f64, dims[a] as f64 / size[a]);
        if !(c > 0.0 && inv.is_finite()) {
            return Err(MediumError::param(
                "bounds",
                format!(
                    "extent {} along axis {a} is too small for {} voxels",
                    size[a], dims[a]
                ),
            ));
        }
    }
    Ok(count)
}

impl VoxelGrid {
    /// A grid whose voxel `i` holds the base material scaled by `densities[i]` (a relative
    /// particle concentration, `>= 0`, zero for a vacuum voxel), in a host of absorption
    /// `host_sigma_a >= 0` that is not scaled (Eq. 43 with `N_iota(x) = density(x) N_iota`):
    ///
    /// `sigma_s(x) = d(x) base.sigma_s`, `sigma_a(x) = d(x) base.sigma_a + host_sigma_a`,
    /// `beta_iota(x) = base.types` everywhere.
    ///
    /// `densities` is in C order of a numpy array of shape `(nx, ny, nz)` (`(nx, ny)` in
    /// flatland, where `dims[2] = 1`); see the type's docs. For a particle mixture, pass
    /// [`crate::ParticleMix::particle_material`] and [`crate::ParticleMix::host_sigma_a`].
    ///
    /// ```
    /// use glam::DVec2;
    /// use speckle_medium::{Aabb, DVec3, Material, Medium, VoxelGrid};
    /// // Flatland 3 x 2 grid with an empty voxel.
    /// let b = Aabb::flat(DVec2::ZERO, DVec2::new(3.0, 2.0)).unwrap();
    /// let d = vec![1.0, 0.0, 2.0, 2.0, 1.0, 1.0]; // numpy shape (3, 2)
    /// let g = VoxelGrid::from_densities(b, [3, 2, 1], d, Material::single(1.0, 0.0), 0.0).unwrap();
    /// assert_eq!(g.sigma_s(DVec3::new(0.5, 1.5, 0.0)), 0.0); // voxel (0, 1)
    /// assert_eq!(g.sigma_s(DVec3::new(1.5, 0.5, 0.0)), 2.0); // voxel (1, 0)
    /// assert!(VoxelGrid::from_densities(b, [3, 2, 1], vec![1.0; 5], Material::single(1.0, 0.0), 0.0).is_err());
    /// ```
    pub fn from_densities(
        bounds: Aabb,
        dims: [usize; 3],
        densities: Vec<f64>,
        base: Material,
        host_sigma_a: f64,
    ) -> Result<Self, MediumError> {
        let ss = coefficient(|| "base.sigma_s".into(), base.sigma_s)?;
        let sa = coefficient(|| "base.sigma_a".into(), base.sigma_a)?;
        let host = coefficient(|| "host_sigma_a".into(), host_sigma_a)?;
        if ss == 0.0 {
            return Err(MediumError::param(
                "base.sigma_s",
                "is 0: the grid would not scatter anywhere",
            ));
        }
        let count = check_dims(&bounds, dims, densities.len(), "densities")?;
        let mut sigma_s = densities;
        let mut sigma_t = Vec::with_capacity(count);
        for (i, d) in sigma_s.iter_mut().enumerate() {
            let value = *d;
            let bad = |reason: String| {
                MediumError::param(
                    format!("densities[{i}]"),
                    format!("voxel {:?}: {reason}", unflatten(dims, i)),
                )
            };
            if !(value.is_finite() && value >= 0.0) {
                return Err(bad(format!("must be finite and >= 0 (got {value})")));
            }
            // Eq. 43 with N(x) = d(x) N.
            let (s, a) = (value * ss, value * sa + host);
            let t = s + a;
            if !t.is_finite() {
                return Err(bad(format!(
                    "density {value} times the base coefficients overflows"
                )));
            }
            *d = s;
            sigma_t.push(t);
        }
        if sigma_s.iter().all(|&s| s == 0.0) {
            return Err(MediumError::param(
                "densities",
                "all zero: no voxel scatters, so there is no speckle",
            ));
        }
        Self::build(bounds, dims, sigma_s, sigma_t, Vec::new(), vec![base.types])
    }

    /// A grid whose voxel `i` is made of `materials[ids[i]]`. Materials may have `sigma_s = 0`
    /// (absorbing or vacuum voxels), but some voxel must scatter. `ids` is in C order of a
    /// numpy array of shape `(nx, ny, nz)` (`(nx, ny)` in flatland, where `dims[2] = 1`).
    ///
    /// ```
    /// use speckle_medium::{Aabb, DVec3, Material, Medium, TypeMix, VoxelGrid};
    /// let b = Aabb::new(DVec3::ZERO, DVec3::new(2.0, 1.0, 1.0)).unwrap();
    /// // Left half: type 0 particles; right half: type 2 particles.
    /// let mats = vec![
    ///     Material::single(1.0, 0.1),
    ///     Material::new(2.0, 0.0, TypeMix::single(2).unwrap()),
    /// ];
    /// let g = VoxelGrid::from_materials(b, [2, 1, 1], vec![0, 1], mats).unwrap();
    /// assert_eq!(g.particle_types(), 3);
    /// assert_eq!(g.sample_type(DVec3::new(1.5, 0.5, 0.5), 0.3), 2);
    /// assert_eq!(g.sigma_t(DVec3::new(0.5, 0.5, 0.5)), 1.1);
    /// ```
    pub fn from_materials(
        bounds: Aabb,
        dims: [usize; 3],
        ids: Vec<u32>,
        materials: Vec<Material>,
    ) -> Result<Self, MediumError> {
        if materials.is_empty() {
            return Err(MediumError::param(
                "materials",
                "needs at least one material",
            ));
        }
        let mut table = Vec::with_capacity(materials.len());
        for (j, m) in materials.iter().enumerate() {
            let s = coefficient(|| format!("materials[{j}].sigma_s"), m.sigma_s)?;
            let a = coefficient(|| format!("materials[{j}].sigma_a"), m.sigma_a)?;
            let t = s + a;
            if !t.is_finite() {
                return Err(MediumError::param(
                    format!("materials[{j}]"),
                    format!("sigma_t = {s} + {a} overflows"),
                ));
            }
            table.push((s, t));
        }
        let count = check_dims(&bounds, dims, ids.len(), "ids")?;
        let mut sigma_s = Vec::with_capacity(count);
        let mut sigma_t = Vec::with_capacity(count);
        for (i, &id) in ids.iter().enumerate() {
            let Some(&(s, t)) = table.get(id as usize) else {
                return Err(MediumError::param(
                    format!("ids[{i}]"),
                    format!(
                        "voxel {:?} has material id {id}, but there are {} materials (ids 0 to \
                         {})",
                        unflatten(dims, i),
                        materials.len(),
                        materials.len() - 1
                    ),
                ));
            };
            sigma_s.push(s);
            sigma_t.push(t);
        }
        if sigma_s.iter().all(|&s| s == 0.0) {
            return Err(MediumError::param(
                "ids",
                "no voxel holds a scattering material (sigma_s > 0), so there is no speckle",
            ));
        }
        let mix_id = if materials.len() > 1 { ids } else { Vec::new() };
        let mixes = materials.into_iter().map(|m| m.types).collect();
        Self::build(bounds, dims, sigma_s, sigma_t, mix_id, mixes)
    }

    fn build(
        bounds: Aabb,
        dims: [usize; 3],
        sigma_s: Vec<f64>,
        sigma_t: Vec<f64>,
        mix_id: Vec<u32>,
        mixes: Vec<TypeMix>,
    ) -> Result<Self, MediumError> {
        let flat = bounds.dimension() == crate::Dimension::Two;
        let n = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
        let mut cell = bounds.size() / n;
        let mut inv_cell = n / bounds.size();
        if flat {
            cell.z = 0.0;
            inv_cell.z = 0.0;
        }
        let voxel_measure = bounds.measure() / sigma_s.len() as f64;

        let majorant = sigma_t.iter().fold(0.0f64, |m, &t| m.max(t));
        let uniform_sigma_t = sigma_t
            .iter()
            .all(|&t| t == sigma_t[0])
            .then_some(sigma_t[0]);

        // Cumulative sigma_s for sampling scatterers (Eq. 35).
        let total: f64 = sigma_s.iter().sum();
        let scattering_volume = total * voxel_measure;
        if !(total.is_finite() && scattering_volume.is_finite() && scattering_volume > 0.0) {
            return Err(MediumError::param(
                "sigma_s",
                format!(
                    "the scattering volume (sum of sigma_s times the voxel measure) must be \
                     finite and > 0 (got {scattering_volume})"
                ),
            ));
        }
        let last_scatterer = sigma_s.iter().rposition(|&s| s > 0.0).unwrap_or(0);
        let mut acc = 0.0;
        let scatter_cdf = sigma_s
            .iter()
            .enumerate()
            .map(|(i, &s)| {
                acc += s;
                if i >= last_scatterer {
                    1.0
                } else {
                    (acc / total).min(1.0)
                }
            })
            .collect();
        let particle_types = mixes.iter().map(TypeMix::type_count).max().unwrap_or(1);
        Ok(Self {
            bounds,
            dims,
            cell,
            inv_cell,
            sigma_s,
            sigma_t,
            mix_id,
            mixes,
            particle_types,
            majorant,
            uniform_sigma_t,
            scattering_volume,
            scatter_cdf,
            last_scatterer,
            tracking: if majorant * bounds.size().length() > MAX_DELTA_COLLISIONS {
                Tracking::Regular
            } else {
                Tracking::Delta
            },
            macro_cells: None,
        })
    }

    /// The same grid with another flight sampler (by default delta tracking, or regular
    /// tracking where delta tracking would take more than [`MAX_DELTA_COLLISIONS`] steps).
    /// [`Tracking::Local`] builds its macro cells here (one pass over the voxels per block size
    /// tried, `log2` of the largest voxel count of them).
    pub fn with_tracking(mut self, tracking: Tracking) -> Self {
        self.tracking = tracking;
        self.macro_cells = (tracking == Tracking::Local)
            .then(|| {
                let flat = self.bounds.dimension() == crate::Dimension::Two;
                MacroCells::build(&self.voxels(), &self.sigma_t, flat).0
            })
            .flatten()
            .map(Box::new);
        self
    }

    /// [`Tracking::Local`]'s cost model for this grid: `(block edge in voxels, or None for one
    /// global majorant; expected work per flight with it; with one global majorant)`, the work
    /// counted in tentative collisions (module `macro_cells`).
    pub fn local_majorant_plan(&self) -> (Option<usize>, f64, f64) {
        let flat = self.bounds.dimension() == crate::Dimension::Two;
        let (cells, cost, global) = MacroCells::build(&self.voxels(), &self.sigma_t, flat);
        (cells.map(|c| c.lattice.stride[0]), cost, global)
    }

    /// The flight sampler in use.
    pub fn tracking(&self) -> Tracking {
        self.tracking
    }

    /// Voxel counts `[nx, ny, nz]`.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Voxel edge lengths (zero along `z` in flatland).
    pub fn voxel_size(&self) -> DVec3 {
        self.cell
    }

    /// The majorant `max sigma_t` used by delta tracking.
    pub fn majorant(&self) -> f64 {
        self.majorant
    }

    /// Per-voxel scattering coefficients, in C order (see the type's docs).
    pub fn voxel_sigma_s(&self) -> &[f64] {
        &self.sigma_s
    }

    /// Per-voxel extinction coefficients, in C order.
    pub fn voxel_sigma_t(&self) -> &[f64] {
        &self.sigma_t
    }

    /// The C-order index of the voxel holding `x`, `None` outside the box.
    pub fn voxel_of(&self, x: DVec3) -> Option<usize> {
        self.bounds.contains(x).then(|| self.voxel_clamped(x))
    }

    /// Index of `x` along axis `a`: floor of the voxel coordinate, clamped to `[0, n - 1]`.
    #[inline]
    fn axis_index(&self, a: usize, x: f64) -> usize {
        let f = (x - self.bounds.min()[a]) * self.inv_cell[a];
        // `as` saturates (and maps NaN to 0).
        (f as usize).min(self.dims[a] - 1)
    }

    #[inline]
    fn linear(&self, i: [usize; 3]) -> usize {
        (i[0] * self.dims[1] + i[1]) * self.dims[2] + i[2]
    }

    /// The voxel of `x`, clamped to the grid.
    #[inline]
    fn voxel_clamped(&self, x: DVec3) -> usize {
        self.linear([
            self.axis_index(0, x.x),
            self.axis_index(1, x.y),
            self.axis_index(2, x.z),
        ])
    }

    /// The voxels as a lattice of blocks of one voxel.
    fn voxels(&self) -> Lattice {
        Lattice::new(
            self.bounds.min(),
            self.bounds.max(),
            self.dims,
            self.cell,
            self.inv_cell,
            [1, 1, 1],
        )
    }

    /// Walks the voxels crossed by `o + t d` for `t` in `[t0, t1]` (an interval inside the box,
    /// from [`Aabb::clip`]) by 3D-DDA (Amanatides and Woo 1987), calling `f(voxel, t_in, t_out)`
    /// for each, in order, until `f` returns `false`. Stretches are contiguous and
    /// non-decreasing; rounding may make some of zero length.
    fn walk(
        &self,
        o: DVec3,
        d: DVec3,
        t0: f64,
        t1: f64,
        mut f: impl FnMut(usize, f64, f64) -> bool,
    ) {
        self.voxels().walk(o, d, t0, t1, |idx, t_in, t_out| {
            f(self.linear(idx), t_in, t_out)
        });
    }

    /// `int sigma_t dt` over `t` in `[t0, t1]` along `o + t d` (multiply by `|d|` for a length).
    /// Runs of voxels with equal `sigma_t` are summed as one stretch.
    fn depth_along(&self, o: DVec3, d: DVec3, t0: f64, t1: f64) -> f64 {
        if t1.is_nan() || t0.is_nan() || t1 <= t0 {
            return 0.0;
        }
        let mut sum = 0.0;
        let mut run: Option<(f64, f64)> = None;
        self.walk(o, d, t0, t1, |v, t_in, _| {
            let s = self.sigma_t[v];
            match run {
                Some((rs, _)) if rs == s => {}
                Some((rs, start)) => {
                    sum += rs * (t_in - start);
                    run = Some((s, t_in));
                }
                None => run = Some((s, t_in)),
            }
            true
        });
        if let Some((rs, start)) = run {
            sum += rs * (t1 - start);
        }
        sum
    }

    fn flight_delta(
        &self,
        x: DVec3,
        dir: DVec3,
        t0: f64,
        t1: f64,
        next: &mut dyn FnMut() -> f64,
    ) -> Option<f64> {
        let mut t = t0;
        loop {
            // Tentative collision in the majorant medium: d = -ln(1 - u) / sigma_bar.
            t += -(1.0 - next()).ln() / self.majorant;
            if t.is_nan() || t >= t1 {
                return None;
            }
            let st = self.sigma_t[self.voxel_clamped(x + t * dir)];
            // Real with probability sigma_t / sigma_bar; certain (no variate) where they agree.
            if st >= self.majorant || next() * self.majorant < st {
                return Some(t);
            }
        }
    }

    fn flight_regular(
        &self,
        x: DVec3,
        dir: DVec3,
        t0: f64,
        t1: f64,
        next: &mut dyn FnMut() -> f64,
    ) -> Option<f64> {
        // Target optical depth tau = -ln(1 - u); walk until int sigma_t reaches it.
        let tau = -(1.0 - next()).ln();
        let mut acc = 0.0;
        let mut hit = None;
        self.walk(x, dir, t0, t1, |v, t_in, t_out| {
            let s = self.sigma_t[v];
            let step = s * (t_out - t_in);
            if acc + step > tau {
                // s > 0 here: the stretch has positive optical depth.
                hit = Some((t_in + (tau - acc) / s).clamp(t_in, t_out));
                false
            } else {
                acc += step;
                true
            }
        });
        hit.filter(|&t| t < t1)
    }
}

/// `(ix, iy, iz)` of C-order index `i`.
fn unflatten(dims: [usize; 3], i: usize) -> (usize, usize, usize) {
    (
        i / (dims[1] * dims[2]),
        (i / dims[2]) % dims[1],
        i % dims[2],
    )
}

impl Medium for VoxelGrid {
    fn bounds(&self) -> &Aabb {
        &self.bounds
    }

    #[inline]
    fn sigma_s(&self, x: DVec3) -> f64 {
        if self.bounds.contains(x) {
            self.sigma_s[self.voxel_clamped(x)]
        } else {
            0.0
        }
    }

    #[inline]
    fn sigma_t(&self, x: DVec3) -> f64 {
        if self.bounds.contains(x) {
            self.sigma_t[self.voxel_clamped(x)]
        } else {
            0.0
        }
    }

    fn optical_depth(&self, a: DVec3, b: DVec3) -> f64 {
        let d = b - a;
        match self.bounds.clip(a, d, 0.0, 1.0) {
            Some((t0, t1)) => self.depth_along(a, d, t0, t1) * d.length(),
            None => 0.0,
        }
    }

    fn optical_depth_to_infinity(&self, x: DVec3, dir: DVec3) -> f64 {
        match self.bounds.clip(x, dir, 0.0, f64::INFINITY) {
            Some((t0, t1)) => self.depth_along(x, dir, t0, t1),
            None => 0.0,
        }
    }

    fn scattering_volume(&self) -> f64 {
        self.scattering_volume
    }

    fn sample_scatterer(&self, u: [f64; 3]) -> DVec3 {
        // The voxel: first with cumulative probability > u[0].
        let k = self
            .scatter_cdf
            .partition_point(|&c| c <= u[0])
            .min(self.last_scatterer);
        let lo = if k == 0 { 0.0 } else { self.scatter_cdf[k - 1] };
        let hi = self.scatter_cdf[k];
        // The remainder of u[0], rescaled to [0, 1): uniform given the voxel.
        let r = if hi > lo {
            ((u[0] - lo) / (hi - lo)).clamp(0.0, ONE_BELOW)
        } else {
            0.5
        };
        let (ix, iy, iz) = unflatten(self.dims, k);
        let idx = [ix, iy, iz];
        let w = [r, u[1], u[2]];
        let mut x = DVec3::ZERO;
        for a in 0..3 {
            let lo = self.bounds.min()[a] + idx[a] as f64 * self.cell[a];
            x[a] = lo + w[a] * self.cell[a];
            if self.axis_index(a, x[a]) != idx[a] {
                // Rounding put the point across a face: use the voxel's centre on this axis
                // (a measure-zero event) so that sigma_s(x) is the sampled voxel's.
                x[a] = lo + 0.5 * self.cell[a];
            }
        }
        x
    }

    fn sample_flight(
        &self,
        x: DVec3,
        dir: DVec3,
        next_uniform: &mut dyn FnMut() -> f64,
    ) -> Option<f64> {
        let (t0, t1) = if self.bounds.contains(x) {
            (0.0, self.bounds.exit_distance(x, dir))
        } else {
            // From outside: fly through the vacuum up to the box.
            self.bounds.clip(x, dir, 0.0, f64::INFINITY)?
        };
        match (self.tracking, &self.macro_cells) {
            (Tracking::Regular, _) => self.flight_regular(x, dir, t0, t1, next_uniform),
            (Tracking::Local, Some(cells)) => {
                let st = |t: f64| self.sigma_t[self.voxel_clamped(x + t * dir)];
                cells.flight(x, dir, t0, t1, st, next_uniform)
            }
            _ => self.flight_delta(x, dir, t0, t1, next_uniform),
        }
    }

    fn uniform_sigma_t(&self) -> Option<f64> {
        self.uniform_sigma_t
    }

    fn particle_types(&self) -> usize {
        self.particle_types
    }

    #[inline]
    fn sample_type(&self, x: DVec3, u: f64) -> usize {
        self.mix_at(x).sample(u)
    }

    fn type_probabilities(&self, x: DVec3, out: &mut [f64]) {
        self.mix_at(x).probabilities(out);
    }

    fn materials(&self) -> usize {
        self.mixes.len()
    }

    #[inline]
    fn material(&self, x: DVec3) -> usize {
        if self.mix_id.is_empty() {
            0
        } else {
            self.mix_id[self.voxel_clamped(x)] as usize
        }
    }
}

impl VoxelGrid {
    /// The type mix of the voxel holding `x` (clamped to the grid).
    #[inline]
    fn mix_at(&self, x: DVec3) -> &TypeMix {
        if self.mix_id.is_empty() {
            &self.mixes[0]
        } else {
            &self.mixes[self.mix_id[self.voxel_clamped(x)] as usize]
        }
    }
}

#[cfg(test)]
mod tests;
