//! One configuration: Poisson-distributed scatterers and the dense Foldy-Lax solve.

use crate::lu;
use crate::{Kernel, WaveError};
use faer::Mat;
use glam::DVec3;
use num_complex::Complex64;
use speckle_endpoints::{FreeSpace, direct_field, incident_field, sensor_response};
use speckle_medium::{Dimension, HomogeneousBox, Medium};
use speckle_phase::Phase;
use speckle_scene::Scene;
use speckle_stats::PathRng;

/// The scenes the wave solver accepts: a homogeneous lossless box of isotropic scatterers.
pub type WaveScene = Scene<HomogeneousBox, Phase>;

/// Largest expected number of scatterers `n |V|` a scene may have. The dense solve costs
/// `O(N^3)` time (`(8/3) N^3` real flops for the complex LU) and
/// `16 N^2` bytes: 6.4 GB at this limit.
pub const MAX_EXPECTED_SCATTERERS: f64 = 20_000.0;

/// Largest number of explicit scatterers [`solve`] accepts (a Poisson draw may exceed the
/// expected number a little).
pub const MAX_SCATTERERS: usize = 25_000;

fn invalid(field: impl Into<String>, reason: impl Into<String>) -> WaveError {
    WaveError::InvalidInput {
        field: field.into(),
        reason: reason.into(),
    }
}

/// Checks that the scene is one the solver models (lossless medium, isotropic scatterers of
/// the medium's dimension) and returns its kernel.
pub fn check_scene(scene: &WaveScene) -> Result<Kernel, WaveError> {
    let m = scene.medium();
    if m.absorption() != 0.0 {
        return Err(invalid(
            "medium.sigma_a",
            format!(
                "must be 0 (got {}): the wave solver models lossless scatterers, whose \
                 extinction is all scattering",
                m.absorption()
            ),
        ));
    }
    let dimension = m.dimension();
    if scene.phases().len() != 1 {
        return Err(invalid(
            "phases",
            format!(
                "the wave solver models one kind of scatterer (got {} particle types)",
                scene.phases().len()
            ),
        ));
    }
    if *scene.phase() != Phase::isotropic(dimension) {
        return Err(invalid(
            "phase",
            format!(
                "the wave solver models isotropic point scatterers: the phase function must be \
                 isotropic in {dimension} (got {:?})",
                scene.phase()
            ),
        ));
    }
    Ok(Kernel::new(dimension, scene.wavenumber()))
}

/// The number density of scatterers `n = sigma_s / c_s` (per volume in 3D, per area in
/// flatland), with `c_s` the cross-section of [`Kernel::cross_section`].
pub fn number_density(scene: &WaveScene) -> Result<f64, WaveError> {
    Ok(scene.medium().scattering() / check_scene(scene)?.cross_section())
}

/// The expected number of scatterers in the medium, `n |V|` (`|V|` the volume, or the area in
/// flatland); an error naming `medium` when it exceeds [`MAX_EXPECTED_SCATTERERS`].
///
/// ```
/// use speckle_endpoints::{Pair, Sensor, Source};
/// use speckle_scene::Scene;
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_phase::Phase;
/// // 10 x 10 x 5 wavelengths, mean free path 10: n = sigma_s / (4 pi / k^2) = 0.1 pi per
/// // cubic wavelength.
/// let b = Aabb::centered(DVec3::ZERO, DVec3::new(10.0, 10.0, 5.0)).unwrap();
/// let m = HomogeneousBox::from_mean_free_path(b, 10.0, 1.0).unwrap();
/// let scene = Scene::new(m, Phase::Isotropic, 1.0, vec![Source::plane_wave(DVec3::Z).unwrap()],
///     vec![Sensor::far_field(DVec3::Z).unwrap()], Pair::all(1, 1))
///     .unwrap();
/// let n = speckle_wave::expected_scatterers(&scene).unwrap();
/// assert!((n - 50.0 * std::f64::consts::PI).abs() < 1e-9);
/// ```
pub fn expected_scatterers(scene: &WaveScene) -> Result<f64, WaveError> {
    let expected = number_density(scene)? * scene.medium().bounds().measure();
    if expected.is_nan() || expected > MAX_EXPECTED_SCATTERERS {
        return Err(invalid(
            "medium",
            format!(
                "the box holds {expected:.0} scatterers on average (sigma_s |V| / c_s), more \
                 than the dense solver's limit of {MAX_EXPECTED_SCATTERERS}: its cost grows as \
                 N^3 and its memory as 16 N^2 bytes; use a smaller box or a longer mean free \
                 path"
            ),
        ));
    }
    Ok(expected)
}

/// Draws one configuration: a Poisson number of scatterers with mean
/// [`expected_scatterers`], each uniform in the medium's box (`z = 0` in flatland).
///
/// The count is the number of arrivals of a unit-rate Poisson process in `[0, n |V|]`
/// (exponential spacings `-ln(1 - u)`), then three uniforms place each scatterer. Positions are
/// independent, so pairs of scatterers may come arbitrarily close (point scatterers allow it:
/// the Foldy-Lax matrix of a close pair stays regular).
pub fn sample_scatterers(scene: &WaveScene, rng: &mut PathRng) -> Result<Vec<DVec3>, WaveError> {
    Ok(sample_expected(scene, expected_scatterers(scene)?, rng))
}

/// [`sample_scatterers`] with the expected count given (checked by the caller against its own
/// limit): the same draws, so the multi-slice solver sees the Foldy-Lax configurations.
pub(crate) fn sample_expected(scene: &WaveScene, expected: f64, rng: &mut PathRng) -> Vec<DVec3> {
    let mut count = 0usize;
    let mut t = -(1.0 - rng.next_f64()).ln();
    while t <= expected {
        count += 1;
        t -= (1.0 - rng.next_f64()).ln();
    }
    let m = scene.medium();
    (0..count)
        .map(|_| m.sample_scatterer(rng.next_3()))
        .collect()
}

fn check_positions(scene: &WaveScene, scatterers: &[DVec3]) -> Result<(), WaveError> {
    if scatterers.len() > MAX_SCATTERERS {
        return Err(invalid(
            "scatterers",
            format!(
                "{} scatterers exceed the dense solver's limit of {MAX_SCATTERERS}",
                scatterers.len()
            ),
        ));
    }
    let flat = scene.medium().dimension() == Dimension::Two;
    for (n, o) in scatterers.iter().enumerate() {
        if !o.is_finite() {
            return Err(invalid(
                format!("scatterers[{n}]"),
                format!("position {o} must be finite"),
            ));
        }
        if flat && o.z != 0.0 {
            return Err(invalid(
                format!("scatterers[{n}]"),
                format!("position {o} must have z = 0 in a flatland scene"),
            ));
        }
    }
    Ok(())
}

/// The fields of all pairs of `scene` (in pair order) for scatterers at the given positions:
/// the exact solution of the Foldy-Lax equations (see the crate docs).
///
/// Errors name the offending input: the scene (`medium.sigma_a`, `phase`), a position
/// (`scatterers[n]`: non-finite, off the plane in flatland, coinciding with another scatterer,
/// a point source or a point sensor), or a pair whose point source and point sensor coincide
/// (`pairs[j]`).
///
/// ```
/// use speckle_endpoints::{Pair, Sensor, Source};
/// use speckle_scene::Scene;
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_phase::Phase;
/// let b = Aabb::centered(DVec3::ZERO, DVec3::splat(2.0)).unwrap();
/// let m = HomogeneousBox::from_mean_free_path(b, 10.0, 1.0).unwrap();
/// let v = DVec3::new(0.0, 0.6, 0.8);
/// let scene = Scene::new(m, Phase::Isotropic, 1.0, vec![Source::plane_wave(DVec3::Z).unwrap()],
///     vec![Sensor::far_field(v).unwrap()], Pair::all(1, 1)).unwrap();
/// // One scatterer at o: A(v) = (i / k) e^{ik (i - v).o}.
/// let o = DVec3::new(0.1, -0.3, 0.2);
/// let u = speckle_wave::solve(&scene, &[o]).unwrap();
/// let k = scene.wavenumber();
/// let expect = num_complex::Complex64::new(0.0, 1.0 / k)
///     * num_complex::Complex64::from_polar(1.0, k * (DVec3::Z - v).dot(o));
/// assert!((u[0] - expect).norm() < 1e-15);
/// ```
pub fn solve(scene: &WaveScene, scatterers: &[DVec3]) -> Result<Vec<Complex64>, WaveError> {
    let kernel = check_scene(scene)?;
    check_positions(scene, scatterers)?;
    solve_checked(scene, kernel, scatterers, &|| false)
}

/// [`solve`] after the checks of the scene and of the positions' values.
/// `cancelled` is asked before each column of the assembly and between the steps of the
/// factorisation ([`crate::lu`]).
pub(crate) fn solve_checked(
    scene: &WaveScene,
    kernel: Kernel,
    scatterers: &[DVec3],
    cancelled: &dyn Fn() -> bool,
) -> Result<Vec<Complex64>, WaveError> {
    let n = scatterers.len();
    let space = Space::new(kernel);
    let tau = space.tau;
    let sources = scene.sources();
    // Incident fields at the scatterers; a scatterer on a point source is refused.
    let mut u_inc = Vec::with_capacity(n * sources.len());
    for (s, source) in sources.iter().enumerate() {
        for (at, o) in scatterers.iter().enumerate() {
            u_inc.push(incident_field(source, &space, *o).ok_or_else(|| {
                invalid(
                    format!("scatterers[{at}]"),
                    format!("coincides with the point source {s} at {o}"),
                )
            })?);
        }
    }

    // Exciting fields psi (N x S, one column per source): (I - tau G_offdiag) psi = u_inc.
    let mut psi = Mat::<Complex64>::from_fn(n, sources.len(), |i, s| u_inc[s * n + i]);
    if n > 0 {
        // The identity, a column at a time: touching 16 N^2 bytes (5.8 GB at N = 19 000) takes
        // seconds, asked for cancellation every 64 columns.
        let mut a = Mat::<Complex64>::with_capacity(n, n);
        for j in 0..n {
            if j % 64 == 0 && cancelled() {
                return Err(WaveError::Cancelled);
            }
            let one = Complex64::new(1.0, 0.0);
            a.resize_with(n, j + 1, |r, c| {
                if r == c {
                    one
                } else {
                    Complex64::new(0.0, 0.0)
                }
            });
        }
        for j in 0..n {
            // Up to N Green's functions per column (2 ms at N = 19 000): asked per column.
            if cancelled() {
                return Err(WaveError::Cancelled);
            }
            for i in (j + 1)..n {
                let r = (scatterers[i] - scatterers[j]).length();
                if r == 0.0 {
                    return Err(invalid(
                        format!("scatterers[{i}]"),
                        format!("coincides with scatterers[{j}] at {}", scatterers[i]),
                    ));
                }
                let v = -tau * kernel.green(r);
                a[(i, j)] = v;
                a[(j, i)] = v;
            }
        }
        let swaps = lu::factorise(&mut a, cancelled).ok_or(WaveError::Cancelled)?;
        lu::solve(&a, &swaps, psi.as_mut());
        if let Some((i, s)) = (0..n)
            .flat_map(|i| (0..sources.len()).map(move |s| (i, s)))
            .find(|&(i, s)| !psi[(i, s)].is_finite())
        {
            return Err(invalid(
                "scatterers",
                format!(
                    "the Foldy-Lax system is singular for this configuration (non-finite \
                     exciting field at scatterer {i} for source {s})"
                ),
            ));
        }
    }

    // Pairs grouped by sensor, so that each sensor's weights are formed once.
    let mut by_sensor = vec![Vec::new(); scene.sensors().len()];
    for (j, p) in scene.pairs().iter().enumerate() {
        by_sensor[p.sensor].push(j);
    }
    let mut fields = vec![Complex64::new(0.0, 0.0); scene.len()];
    let mut weights = vec![Complex64::new(0.0, 0.0); n];
    for (v, pairs) in by_sensor.iter().enumerate() {
        if pairs.is_empty() {
            continue;
        }
        let sensor = scene.sensors()[v];
        // u_scat(sensor) = sum_n w_n psi_n, w_n the sensor's reading of scatterer n.
        for (at, (w, o)) in weights.iter_mut().zip(scatterers).enumerate() {
            *w = sensor_response(&sensor, &space, *o).ok_or_else(|| {
                invalid(
                    format!("scatterers[{at}]"),
                    format!("coincides with the point sensor {v} at {o}"),
                )
            })?;
        }
        for &j in pairs {
            let s = scene.pairs()[j].source;
            let column = psi.col_as_slice(s);
            let scattered: Complex64 = weights.iter().zip(column).map(|(w, p)| w * p).sum();
            let direct = direct_field(&sources[s], &sensor, &space).ok_or_else(|| {
                let at = match sensor {
                    speckle_endpoints::Sensor::Point { position } => position,
                    speckle_endpoints::Sensor::FarField { direction } => direction,
                    speckle_endpoints::Sensor::GaussianBeam(b) => b.focus,
                };
                invalid(
                    format!("pairs[{j}]"),
                    format!("the point source and the point sensor coincide at {at}"),
                )
            })?;
            fields[j] = scattered + direct;
        }
    }
    Ok(fields)
}

/// The free-space physics of a [`Kernel`] as the endpoints see it, with the scatterer's
/// t-matrix and far-field amplitude formed once.
struct Space {
    kernel: Kernel,
    tau: Complex64,
    far: Complex64,
}

impl Space {
    fn new(kernel: Kernel) -> Self {
        Self {
            kernel,
            tau: kernel.t_matrix(),
            far: kernel.scattering_amplitude(),
        }
    }
}

impl FreeSpace for Space {
    fn wavenumber(&self) -> f64 {
        self.kernel.wavenumber()
    }
    fn dimension(&self) -> speckle_medium::Dimension {
        self.kernel.dimension()
    }
    #[inline]
    fn point_source(&self, r: f64) -> Complex64 {
        self.kernel.point_source(r)
    }
    #[inline]
    fn scattered(&self, r: f64) -> Complex64 {
        self.tau * self.kernel.green(r)
    }
    fn scattering_amplitude(&self) -> Complex64 {
        self.far
    }
}
