//! Multi-slice beam propagation (split-step angular spectrum): a second, *approximate* wave
//! reference, run through the same random scatterer configurations as the Foldy-Lax solver
//! (Bar et al. 2020, Sec. 8 and Fig. 11 right; Schott et al. 2015).
//!
//! # Method
//!
//! A plane wave `e^{ik z}` at normal incidence on the box (along one of its axes; `z` is the
//! depth along that axis, `x` the transverse coordinate, `(x, y)` in 3D) crosses the box as a
//! stack of slices `[z_a, z_b]`, `z_b - z_a = dz`. Only the *scattered* field `u_s` lives on the
//! grid (the incident wave is kept analytically, so the absorbing layers never eat it): samples
//! on a periodic transverse grid of spacing `h <= lambda / 4` and width `L`, with Fourier
//! coefficients `c_m`, `u_s(x, z) = sum_m c_m(z) e^{i q_m . (x - x_lo)}`, `q_m = 2 pi m / L`
//! (signed `m`).
//!
//! **Free propagation** between slices is exact for each plane wave: `c_m(z_b) = c_m(z_a)
//! e^{i k_z dz}` with `k_z = sqrt(k^2 - |q_m|^2)` (the angular-spectrum propagator); where
//! `|q_m| > k`, `k_z = i sqrt(|q_m|^2 - k^2)` and the evanescent components decay.
//!
//! **The screen of a slice.** A point scatterer at `o = (x_o, z_o)` with t-matrix `tau` (4i in
//! flatland, `4 pi i / k` in 3D; [`crate::Kernel::t_matrix`]) excited by `psi(o)` radiates
//! `tau G(x - o) psi(o)`. Its exciting field is the incident wave, the grid's field at `z_a`
//! carried to it, and (below) the scatterers just ahead of it:
//!
//! `psi(o) = e^{i k z_o} + sum_m c_m(z_a) e^{i k_z (z_o - z_a)} e^{i q_m . (x_o - x_lo)} +
//! sum_{p pending} tau G(o - p) psi(p)`
//!
//! (the grid's sum is its exact band-limited interpolation off the grid). The Weyl expansion
//! `G(x, z) = (i / (4 pi)) int e^{i q x + i k_z |z|} / k_z dq` in flatland
//! (`H0^(1)(kr) = (1/pi) int e^{i q x + i k_z |z|} / k_z dq`) and
//! `(i / (8 pi^2)) int e^{i q.x + i k_z |z|} / k_z d^2q` in 3D gives the spectrum of the
//! scatterer's forward-going part (`z > z_o`), `U(q) = int G e^{-i q x} dx = (i / (2 k_z))
//! e^{-i q x_o} e^{i k_z (z - z_o)}` in both dimensions: the forward half of the Green's
//! function is the Green's function itself for `z > z_o`, so the single scattering (Born) of
//! the slice, carried to a plane `z_e > z_o`, is `tau psi(o) G(x - o)` sampled there. That is
//! how a screen joins the grid: at the first slice boundary `z_e >= z_o + ` [`EMISSION_DEPTH`]
//! wavelengths, in real space, over the emission window (1 in the kept region, the box widened
//! by `margin`, falling as `cos^2` to 0 over the absorbers' inner [`WINDOW_ROLLOFF`]
//! wavelengths). Until then the scatterer is *pending*: the scatterers of later slices between
//! `z_o` and `z_e` are excited by it directly, through `G`.
//!
//! Why not add `U / A` to the spectrum at `z_b` (the textbook screen)? Sampled at `q_m`, that
//! spectrum is the *periodic* Green's function: the scatterer's images `L` apart are added at
//! once, without ever crossing the absorbers, and in flatland their fields decay only as
//! `r^{-1/2}`. With `L = 400` wavelengths the exit field 3.2 wavelengths behind one scatterer
//! was 10.7% off (the alternating lattice sum, `2 * 0.605 sqrt(r / L)`), with the absorbers
//! still 4 to 10%. Sampling `G` in real space instead needs its evanescent part to have decayed
//! below the grid's band limit (`|q| <= 2k` at spacing `lambda / 4`: `e^{-sqrt(3) k delta}`) and
//! its near-grazing part, which a finite grid resolves poorly, to stay small: the exit field's
//! error within 45 degrees of one scatterer falls from 4% at an emission depth of 1 wavelength
//! to 1% at 3 (and to 0.5% at 4; a box of 8 x 4 wavelengths, margin 4, absorbers 8). Its
//! forward spectrum, which the far field reads, is good to `1e-4` to `1e-3`.
//!
//! # Approximations
//!
//! - **Forward only** (the method's defining approximation): a scatterer's backward-going
//!   half (`z < z_o`) is dropped, so a scatterer never excites one upstream of it, and no light
//!   returns. Isotropic point scatterers send half their power backwards, and light scattered
//!   back and then forward again is missing. Each scatterer still extinguishes its full
//!   cross-section (the forward amplitude is the exact one): the dropped backward power is
//!   lost. So the slab transmits less power than the exact solution, more so the deeper it is
//!   (`tests/multislice.rs` measures it), and reflects nothing: reflection sensors are refused.
//! - **Thin slices**: scatterers in the same slice do not excite each other (each sees the
//!   field at `z_a`); those of earlier slices do, directly or through the grid. As `dz` falls
//!   below the scatterers' depth spacing every scatterer has a slice of its own and the method
//!   tends to the forward-only scattering series.
//! - **Wide angles**: light leaving the kept region is damped in absorbing layers (`absorber`
//!   wide, damping rate `alpha(d) = alpha_max (d / absorber)^2` at depth `d` into the layer,
//!   applied as `e^{-alpha dz}` after each slice, damping a wave crossing one layer at 80
//!   degrees by `e^{-15}`); waves within a few degrees of grazing are resolved poorly by the
//!   finite grid, cross the layers barely damped, and wrap around. The width is rounded up to
//!   `L = (M + 1/2) lambda`, so that no flatland grid mode is exactly grazing. A screen's field
//!   joins the grid only within its aperture ([`MultisliceOptions::aperture`], 85 degrees from
//!   the axis by default, full up to 75) and the emission window: light scattered wider is
//!   dropped, except between pairs less than the emission depth apart, which are coupled
//!   directly at any angle. (At 60 to 75 degrees or with no aperture the one-scatterer checks
//!   below were unchanged; the aperture makes a screen cost `O(depth tan(aperture) / h)` grid
//!   points instead of the whole window.)
//!
//! # Far field
//!
//! The far-field amplitude in the Foldy-Lax solver's convention (`u(R v) = A e^{ikR} /
//! sqrt(R)` in flatland, `A e^{ikR} / R` in 3D) from the spectrum `U_e(q)` of the exit plane
//! `z_e`, by stationary phase of `u = (1/2pi) int U_e(q) e^{i q x + i k_z (z - z_e)} dq` at `q =
//! k v_x` (the phase's second derivative there is `-R / (k v_z^2)`):
//!
//! `A(v) = sqrt(k / (2 pi)) e^{-i pi/4} v_z U_e(k v_x) e^{-i k v_z z_e}` (flatland),
//! `A(v) = -i k v_z U_e(k v_perp) e^{-i k v_z z_e} / (2 pi)` (3D, a 2D stationary phase with
//! Hessian determinant `R^2 / (k v_z)^2`).
//!
//! The exit spectrum is the sum of the screens' forward waves, `U_e(q) = sum_n tau psi_n (i /
//! (2 k_z)) e^{-i q x_n} e^{i k_z (z_e - z_n)}`, so `A(v) = f sum_n e^{-i k v . o_n} psi_n` with
//! `f = tau g` the scattering amplitude ([`crate::Kernel::scattering_amplitude`]): the
//! Foldy-Lax sensor's formula with the multi-slice exciting fields. The renders evaluate it so,
//! each screen's spectrum kept exactly instead of sampled on the grid; [`ExitField::far_field`]
//! evaluates the first formula from the grid's exit field (a direct Fourier sum at `q = k v_x`),
//! which the tests compare with it. A plane wave has no far-field amplitude in a direction (as in
//! the Foldy-Lax solver): with no scatterers every field is zero.
//!
//! # Cost
//!
//! Per configuration and source: two FFTs of the grid per slice, one Green's function per grid
//! point of a screen's aperture (its emission), one complex exponential per grid mode per
//! scatterer (its exciting field) and one Green's function per pending pair: `O(slices P log P
//! + N P + N n W lambda)` for `P` grid points, `N` scatterers and `n W lambda` pending ones
//! (density times width times emission depth); memory `O(P)` per thread. Measured: 100
//! configurations of a flatland 200 x 70 wavelength slab (940 scatterers, 1440 grid points, 292
//! slices) in 8.3 s on 2 cores, where the dense solve takes 8.7 s; multi-slice grows as `N P`
//! against the dense solve's `N^3`. No dense matrix, so
//! slabs far beyond the Foldy-Lax solver's `N` run (limits: [`MAX_GRID_POINTS`],
//! [`MAX_MULTISLICE_SCATTERERS`], [`MAX_MULTISLICE_WORK`]).

mod grid;

pub use grid::GridInfo;
use grid::{Frame, Grid};

use crate::render::WaveEstimate;
use crate::solve::{check_scene, number_density, sample_expected};
use crate::{Kernel, WaveError, WaveScene};
use glam::DVec3;
use num_complex::Complex64;
use speckle_endpoints::{Sensor, Source};
use speckle_medium::{Dimension, Medium};
use speckle_stats::{CMatrix, PathRng, Progress, empirical_moments, run_ordered_range};
use std::f64::consts::{FRAC_PI_4, TAU};

/// Largest number of transverse grid points (per slice) a propagation may use.
pub const MAX_GRID_POINTS: usize = 1 << 22;

/// Largest expected number of scatterers per configuration.
pub const MAX_MULTISLICE_SCATTERERS: f64 = 2.0e6;

/// Largest estimated work per configuration and source, in grid-mode updates
/// (`slices P log2 P + N (P + window)`): about a minute of one core.
pub const MAX_MULTISLICE_WORK: f64 = 2.0e10;

/// The depth, in wavelengths, beyond a scatterer at which its field joins the grid (module
/// docs): there its evanescent components beyond the grid's band limit (`|q| >= 2k` at spacing
/// `lambda / 4`) have decayed by `e^{-6 pi sqrt(3)}`, and its near-grazing part is small.
pub const EMISSION_DEPTH: f64 = 3.0;

/// The width, in degrees, of the aperture's roll-off ([`MultisliceOptions::aperture`]).
pub const APERTURE_ROLLOFF: f64 = 10.0;

/// The width, in wavelengths, over which the emission window falls to 0 in the absorbers.
pub const WINDOW_ROLLOFF: f64 = 4.0;

/// Damping (nepers of amplitude) of a wave crossing one absorbing layer at 80 degrees.
const LAYER_DAMPING: f64 = 15.0;

/// Options of the multi-slice solver (lengths in the scene's units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultisliceOptions {
    /// Number `R >= 2` of configurations ([`render_multislice`] only).
    pub configurations: usize,
    /// Seed: configuration `r` draws the Foldy-Lax solver's configuration `r`
    /// ([`crate::sample_scatterers`] on the stream `PathRng::new(seed, r)`).
    pub seed: u64,
    /// Largest transverse grid spacing, in `(0, lambda / 4]`.
    pub spacing: f64,
    /// Largest slice thickness `dz` (positive); the depth is split into equal slices.
    pub slice: f64,
    /// Unabsorbed padding beside the box on each side (`>= 0`): a wave scattered at angle
    /// `theta` from the back of a box of depth `D` stays on the grid up to `D tan(theta) <=
    /// margin`.
    pub margin: f64,
    /// Width of the absorbing layer beyond the margin on each side (`>= 0`; 0 makes the grid
    /// purely periodic: the box's periodic images then scatter into each other).
    pub absorber: f64,
    /// The widest angle from the axis, in degrees, at which a screen's field joins the grid, in
    /// `(APERTURE_ROLLOFF, 90]`: full up to [`APERTURE_ROLLOFF`] degrees less, falling as
    /// `cos^2` in the angle to 0 at this one.
    pub aperture: f64,
}

impl MultisliceOptions {
    /// The defaults for `scene`: spacing and slice `lambda / 4`, a margin of the box's depth
    /// along its first source (waves up to 45 degrees from the box's back edge stay on the
    /// grid; the largest box size if that source is not an axis-aligned plane wave), at least 4
    /// wavelengths, absorbers of 8 wavelengths.
    pub fn new(scene: &WaveScene, configurations: usize, seed: u64) -> Self {
        let lambda = scene.wavelength();
        let size = scene.medium().bounds().size();
        let depth = scene
            .sources()
            .first()
            .and_then(|s| match s {
                Source::PlaneWave { direction } => Frame::of(*direction, false),
                _ => None,
            })
            .map_or(size.max_element(), |f| size[f.axis]);
        Self {
            configurations,
            seed,
            spacing: 0.25 * lambda,
            slice: 0.25 * lambda,
            margin: depth.max(4.0 * lambda),
            absorber: 8.0 * lambda,
            aperture: 85.0,
        }
    }
}

fn invalid(field: impl Into<String>, reason: impl Into<String>) -> WaveError {
    WaveError::InvalidInput {
        field: field.into(),
        reason: reason.into(),
    }
}

/// The scattered field on the grid at the exit plane (the box's back face) of one source.
#[derive(Debug, Clone, PartialEq)]
pub struct ExitField {
    /// The grid's points on the exit plane (global coordinates), row-major with the first
    /// transverse axis fastest.
    pub positions: Vec<DVec3>,
    /// The scattered field at each point (the incident plane wave excluded: the total field is
    /// this plus `e^{ik d . x}`).
    pub scattered: Vec<Complex64>,
    /// The grid's spacings along its transverse axes (the second is 1 in flatland).
    pub spacing: [f64; 2],
    /// The source's propagation direction.
    pub direction: DVec3,
    /// The wavenumber.
    pub wavenumber: f64,
    /// `true` in flatland.
    pub flat: bool,
}

impl ExitField {
    /// The far-field amplitude `A(v)` from this sampled exit field: its spectrum `U_e(q) =
    /// h sum_j u_j e^{-i q . x_j}` (a direct sum at `q = k v_perp`) and the stationary-phase
    /// factor of the module docs. `None` unless `v` is a unit vector into transmission
    /// (`v . d > 0`). Waves absorbed at the grid's sides are missing from it, so it agrees
    /// with the render's amplitude ([`multislice_solve`]) only in directions whose light leaves
    /// the back face inside the kept region.
    pub fn far_field(&self, v: DVec3) -> Option<Complex64> {
        let vz = v.dot(self.direction);
        let unit_into_transmission = vz > 0.0 && (v.length() - 1.0).abs() < 1e-9;
        if !unit_into_transmission {
            return None;
        }
        let k = self.wavenumber;
        let perp = v - vz * self.direction;
        let z_e = self.positions.first()?.dot(self.direction);
        let sum: Complex64 = self
            .positions
            .iter()
            .zip(&self.scattered)
            .map(|(x, u)| u * Complex64::from_polar(1.0, -k * perp.dot(*x)))
            .sum();
        let spectrum = sum * self.spacing[0] * self.spacing[1];
        let factor = if self.flat {
            Complex64::from_polar((k / TAU).sqrt() * vz, -FRAC_PI_4)
        } else {
            Complex64::new(0.0, -k * vz / TAU)
        };
        Some(factor * spectrum * Complex64::from_polar(1.0, -k * vz * z_e))
    }
}

/// One source's propagation through one configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Propagation {
    /// The exciting field `psi_n` of each scatterer (in the order given).
    pub exciting: Vec<Complex64>,
    /// The scattered field on the grid at the exit plane.
    pub exit: ExitField,
    /// The grid.
    pub grid: GridInfo,
}

/// Everything checked once per render: the kernel, the grid of each source, and the expected
/// number of scatterers.
struct Plan {
    kernel: Kernel,
    grids: Vec<Grid>,
    expected: f64,
}

fn plan(scene: &WaveScene, o: &MultisliceOptions) -> Result<Plan, WaveError> {
    let kernel = check_scene(scene)?;
    let lambda = scene.wavelength();
    if !(o.spacing > 0.0 && o.spacing <= 0.25 * lambda * (1.0 + 1e-12)) {
        return Err(invalid(
            "spacing",
            format!(
                "must be in (0, lambda / 4] = (0, {}] (got {})",
                0.25 * lambda,
                o.spacing
            ),
        ));
    }
    if !(o.slice > 0.0 && o.slice.is_finite()) {
        return Err(invalid(
            "slice",
            format!("must be positive and finite (got {})", o.slice),
        ));
    }
    if !(o.aperture > APERTURE_ROLLOFF && o.aperture <= 90.0) {
        return Err(invalid(
            "aperture",
            format!(
                "must be in ({APERTURE_ROLLOFF}, 90] degrees (got {})",
                o.aperture
            ),
        ));
    }
    for (name, v) in [("margin", o.margin), ("absorber", o.absorber)] {
        if !(v >= 0.0 && v.is_finite()) {
            return Err(invalid(
                name,
                format!("must be non-negative and finite (got {v})"),
            ));
        }
    }
    let flat = scene.medium().dimension() == Dimension::Two;
    let mut grids = Vec::with_capacity(scene.sources().len());
    for (s, source) in scene.sources().iter().enumerate() {
        let frame = match source {
            Source::PlaneWave { direction } => Frame::of(*direction, flat),
            _ => None,
        }
        .ok_or_else(|| {
            invalid(
                format!("sources[{s}]"),
                "multi-slice propagation takes plane waves at normal incidence on the box (along \
                 one of its axes)",
            )
        })?;
        grids.push(Grid::new(scene, frame, o)?);
    }
    for (j, p) in scene.pairs().iter().enumerate() {
        let d = match scene.sources()[p.source] {
            Source::PlaneWave { direction } => direction,
            _ => unreachable!("every source was checked to be a plane wave"),
        };
        match scene.sensors()[p.sensor] {
            Sensor::FarField { direction } if direction.dot(d) > 0.0 => {}
            Sensor::FarField { .. } => {
                return Err(invalid(
                    format!("pairs[{j}]"),
                    "multi-slice propagation is forward only: a far-field sensor must look \
                     into transmission (v . d > 0)",
                ));
            }
            _ => {
                return Err(invalid(
                    format!("pairs[{j}]"),
                    "multi-slice propagation reads far-field sensors only",
                ));
            }
        }
    }
    let expected = number_density(scene)? * scene.medium().bounds().measure();
    if expected.is_nan() || expected > MAX_MULTISLICE_SCATTERERS {
        return Err(invalid(
            "medium",
            format!(
                "the box holds {expected:.0} scatterers on average, more than the multi-slice \
                 limit of {MAX_MULTISLICE_SCATTERERS}"
            ),
        ));
    }
    for (s, g) in grids.iter().enumerate() {
        let work = g.work(expected);
        if work > MAX_MULTISLICE_WORK {
            return Err(invalid(
                "medium",
                format!(
                    "one configuration of source {s} costs about {work:.1e} grid-mode updates \
                     ({} x {} points, {} slices, {expected:.0} scatterers), more than the limit \
                     of {MAX_MULTISLICE_WORK:.0e}: use a smaller box, a longer mean free path or \
                     thicker slices",
                    g.axes[0].n, g.axes[1].n, g.slices
                ),
            ));
        }
    }
    Ok(Plan {
        kernel,
        grids,
        expected,
    })
}

fn check_positions(plan: &Plan, scatterers: &[DVec3]) -> Result<(), WaveError> {
    let flat = plan.kernel.dimension() == Dimension::Two;
    for (n, o) in scatterers.iter().enumerate() {
        if !o.is_finite() || (flat && o.z != 0.0) {
            return Err(invalid(
                format!("scatterers[{n}]"),
                format!("position {o} must be finite (and have z = 0 in flatland)"),
            ));
        }
    }
    for g in &plan.grids {
        for (n, o) in scatterers.iter().enumerate() {
            let [_, _, z] = g.frame.local(*o);
            let end = g.z0 + g.slices as f64 * g.dz;
            if z < g.z0 - 1e-9 * g.dz || z > end + 1e-9 * g.dz {
                return Err(invalid(
                    format!("scatterers[{n}]"),
                    format!("position {o} lies outside the box's depth"),
                ));
            }
            for (a, axis) in g.axes.iter().enumerate().take(if flat { 1 } else { 2 }) {
                let x = o[g.frame.across[a]];
                if x < axis.lo || x > axis.lo + axis.len {
                    return Err(invalid(
                        format!("scatterers[{n}]"),
                        format!("position {o} lies outside the transverse grid"),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Propagates source `source` of `grid` through `scatterers` (checked).
fn propagate_checked(
    plan: &Plan,
    source: usize,
    scatterers: &[DVec3],
    cancelled: &dyn Fn() -> bool,
) -> Option<Propagation> {
    let g = &plan.grids[source];
    let mut order: Vec<(usize, [f64; 3])> = scatterers
        .iter()
        .enumerate()
        .map(|(n, o)| {
            let [x, y, z] = g.frame.local(*o);
            (n, [x - g.axes[0].lo, y - g.axes[1].lo, z])
        })
        .collect();
    order.sort_by(|a, b| a.1[2].total_cmp(&b.1[2]).then(a.0.cmp(&b.0)));
    let local: Vec<[f64; 3]> = order.iter().map(|p| p.1).collect();
    let (psi, field) = g.propagate(&plan.kernel, &local, cancelled)?;
    let mut exciting = vec![Complex64::new(0.0, 0.0); scatterers.len()];
    for (p, v) in order.iter().zip(psi) {
        exciting[p.0] = v;
    }
    let z_e = g.z0 + g.boundaries as f64 * g.dz;
    let (a0, a1) = (&g.axes[0], &g.axes[1]);
    let mut positions = Vec::with_capacity(a0.n * a1.n);
    for l in 0..a1.n {
        for m in 0..a0.n {
            let (x, y) = (a0.lo + m as f64 * a0.h, a1.lo + l as f64 * a1.h);
            positions.push(g.frame.global(x, y, z_e));
        }
    }
    let direction = g.frame.global(0.0, 0.0, 1.0);
    Some(Propagation {
        exciting,
        exit: ExitField {
            positions,
            scattered: field,
            spacing: [a0.h, a1.h],
            direction,
            wavenumber: g.k,
            flat: g.frame.flat,
        },
        grid: g.info(),
    })
}

/// Propagates the plane wave of source `source` through scatterers at the given positions:
/// their exciting fields, the scattered field at the exit plane, and the grid.
///
/// Errors name the offending input: the scene (`medium.sigma_a`, `phase`, `sources[s]` not a
/// normal-incidence plane wave, `pairs[j]` not a far-field sensor in transmission), the options
/// (`spacing`, `slice`, `margin`, `absorber`), `source` (out of range) or a position
/// (`scatterers[n]`: non-finite, off the plane in flatland, outside the box's depth or the
/// grid).
///
/// ```
/// use glam::DVec2;
/// use speckle_endpoints::{Pair, Sensor, Source};
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_phase::Phase;
/// use speckle_scene::Scene;
/// use speckle_wave::{MultisliceOptions, multislice_propagate};
/// let b = Aabb::flat(DVec2::new(-4.0, -1.0), DVec2::new(4.0, 1.0)).unwrap();
/// let m = HomogeneousBox::from_mean_free_path(b, 10.0, 1.0).unwrap();
/// let scene = Scene::new(m, Phase::FlatIsotropic, 1.0,
///     vec![Source::plane_wave(DVec3::Y).unwrap()],
///     vec![Sensor::far_field(DVec3::Y).unwrap()], Pair::all(1, 1)).unwrap();
/// let options = MultisliceOptions::new(&scene, 2, 1);
/// let o = DVec3::new(0.3, -0.5, 0.0);
/// let p = multislice_propagate(&scene, 0, &[o], &options).unwrap();
/// // A lone scatterer sees the incident wave only.
/// assert!((p.exciting[0] - num_complex::Complex64::from_polar(1.0, -0.5 * scene.wavenumber()))
///     .norm() < 1e-12);
/// ```
pub fn multislice_propagate(
    scene: &WaveScene,
    source: usize,
    scatterers: &[DVec3],
    options: &MultisliceOptions,
) -> Result<Propagation, WaveError> {
    let plan = plan(scene, options)?;
    if source >= plan.grids.len() {
        return Err(invalid(
            "source",
            format!("index {source} out of range ({} sources)", plan.grids.len()),
        ));
    }
    check_positions(&plan, scatterers)?;
    Ok(propagate_checked(&plan, source, scatterers, &|| false).expect("never cancelled"))
}

/// The far-field amplitudes of a configuration's pairs from each source's exciting fields.
fn pair_fields(
    scene: &WaveScene,
    plan: &Plan,
    scatterers: &[DVec3],
    exciting: &[Vec<Complex64>],
) -> Vec<Complex64> {
    let f = plan.kernel.scattering_amplitude();
    let k = scene.wavenumber();
    scene
        .pairs()
        .iter()
        .map(|p| {
            let v = match scene.sensors()[p.sensor] {
                Sensor::FarField { direction } => direction,
                _ => unreachable!("every pair was checked to read a far-field sensor"),
            };
            // A(v) = f sum_n e^{-ik v.o_n} psi_n: the exit-plane spectrum (module docs).
            f * scatterers
                .iter()
                .zip(&exciting[p.source])
                .map(|(o, psi)| psi * Complex64::from_polar(1.0, -k * v.dot(*o)))
                .sum::<Complex64>()
        })
        .collect()
}

/// The far-field amplitudes of all pairs of `scene` (in pair order) by multi-slice propagation
/// through scatterers at the given positions (see the module docs): the counterpart of
/// [`crate::solve`]. Errors as [`multislice_propagate`].
pub fn multislice_solve(
    scene: &WaveScene,
    scatterers: &[DVec3],
    options: &MultisliceOptions,
) -> Result<Vec<Complex64>, WaveError> {
    let plan = plan(scene, options)?;
    check_positions(&plan, scatterers)?;
    let exciting: Vec<Vec<Complex64>> = (0..plan.grids.len())
        .map(|s| {
            propagate_checked(&plan, s, scatterers, &|| false)
                .expect("never cancelled")
                .exciting
        })
        .collect();
    Ok(pair_fields(scene, &plan, scatterers, &exciting))
}

/// The grid of each source of `scene` under `options` (checked as [`multislice_propagate`]).
pub fn multislice_grids(
    scene: &WaveScene,
    options: &MultisliceOptions,
) -> Result<Vec<GridInfo>, WaveError> {
    Ok(plan(scene, options)?.grids.iter().map(Grid::info).collect())
}

/// Rough single-thread seconds per unit of [`MAX_MULTISLICE_WORK`]'s work (measured on a
/// 2-core x86-64 machine: 2000 configurations of a 20 x 2.5 wavelength flatland slab in 0.4 s).
const SECONDS_PER_WORK: f64 = 1.5e-8;

/// The rough cost of [`render_multislice`] on `threads` threads, to tell a user before it
/// starts: memory (each thread's grids, the fields and their covariance, `staged` bytes of
/// output files), named after `medium` when the grids dominate and after
/// `render.configurations` otherwise; time from the work estimate, named after `medium`.
/// Errors as [`multislice_propagate`].
pub fn estimate_multislice_cost(
    scene: &WaveScene,
    options: &MultisliceOptions,
    threads: usize,
    staged: f64,
) -> Result<speckle_scene::cost::Estimate, WaveError> {
    let plan = plan(scene, options)?;
    let (rr, j) = (options.configurations as f64, scene.len() as f64);
    let in_flight = (threads.max(1) as f64).min(rr.max(1.0));
    let grid_bytes: f64 = plan
        .grids
        .iter()
        .map(|g| 16.0 * 4.0 * g.kz.len() as f64 + 24.0 * plan.expected)
        .fold(0.0, f64::max);
    let grids = in_flight * grid_bytes;
    let results = 16.0 * (2.0 * rr * j + 3.0 * j * j);
    let work: f64 = plan.grids.iter().map(|g| g.work(plan.expected)).sum();
    Ok(speckle_scene::cost::Estimate {
        bytes: grids + results + staged,
        memory_field: if grids > results + staged {
            "medium"
        } else {
            "render.configurations"
        }
        .into(),
        seconds: work * SECONDS_PER_WORK * rr / in_flight,
        time_field: "medium".into(),
        vertices_per_path: 0.0,
    })
}

/// The fields of one configuration and its number of scatterers.
type Solved = (Vec<Complex64>, usize);

/// Renders `R` configurations by multi-slice propagation: the same configurations as
/// [`crate::render_wave`] with the same seed (configuration `r` from the stream `(seed, r)`),
/// their fields (far-field sensors in transmission only) and empirical moments, in the same
/// [`WaveEstimate`]. Bitwise the same for any number of threads (the batch driver of
/// `speckle-stats`, configurations merged in order). `progress` advances by one per
/// configuration; cancellation is asked before each slice.
///
/// Errors as [`multislice_propagate`], `configurations` (fewer than 2), or
/// [`WaveError::Cancelled`].
pub fn render_multislice(
    scene: &WaveScene,
    options: &MultisliceOptions,
    progress: &dyn Progress,
) -> Result<WaveEstimate, WaveError> {
    let plan = plan(scene, options)?;
    let r = options.configurations;
    if r < 2 {
        return Err(invalid(
            "configurations",
            format!("at least 2 configurations are needed for a covariance (got {r})"),
        ));
    }
    let j = scene.len();
    let mut fields = CMatrix::zeros(r, j);
    let mut counts = Vec::with_capacity(r);
    let work = |c: usize| -> Option<Solved> {
        if progress.cancelled() {
            return None;
        }
        let o = sample_expected(
            scene,
            plan.expected,
            &mut PathRng::new(options.seed, c as u64),
        );
        let cancelled = || progress.cancelled();
        let mut exciting = Vec::with_capacity(plan.grids.len());
        for s in 0..plan.grids.len() {
            exciting.push(propagate_checked(&plan, s, &o, &cancelled)?.exciting);
        }
        progress.advance(1);
        Some((pair_fields(scene, &plan, &o, &exciting), o.len()))
    };
    let done = run_ordered_range(0..r, 16 * j, work, |c, (u, n): Solved| {
        fields.as_mut_slice()[c * j..(c + 1) * j].copy_from_slice(&u);
        counts.push(n);
    });
    if !done {
        return Err(WaveError::Cancelled);
    }
    let moments = empirical_moments(&fields)?;
    let mean_scatterers = counts.iter().sum::<usize>() as f64 / r as f64;
    Ok(WaveEstimate {
        fields,
        mean: moments.mean,
        mean_std_error: moments.mean_std_error,
        covariance: moments.covariance,
        configurations: r as u64,
        scatterer_counts: counts,
        mean_scatterers,
        expected_scatterers: plan.expected,
    })
}

#[cfg(test)]
mod tests;
