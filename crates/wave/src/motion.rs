//! Moving scatterers: the exact reference for spatio-temporal covariances (Bar et al. 2023,
//! Fig. 7).
//!
//! Each configuration is a Poisson set of scatterers in the box grown by a margin, moved along
//! trajectories sampled at the requested times (drift `U` plus Brownian increments
//! `N(0, 2 D dt)` per axis between consecutive times, so any two times differ by Eq. 1's
//! displacement), and solved exactly (Foldy-Lax) at every time with the scatterers then inside
//! the box. Independently displaced points of a homogeneous Poisson process form a homogeneous
//! Poisson process again, so the configuration in the box is one of the static solver's at
//! every time; the margin (the largest drift plus eight standard deviations of the Brownian
//! displacement over the whole time span) makes a scatterer that starts outside it and enters
//! the box negligible (probability below `1e-15` per scatterer).
//!
//! The fields of all (time, pair) entries, `R x (T J)` (time-major: column `a J + j` is pair `j`
//! at time `a`), give the covariance `C[(a, j), (b, k)] = E[u_j(t_a) conj(u_k(t_b))] -
//! E[u_j] conj(E[u_k])`, which the Monte Carlo estimates as `C[j, k](t_b - t_a)`
//! (`speckle_estimators::render_correlation`; `docs/conventions.md`).

use crate::solve::{check_scene, expected_scatterers, number_density, solve_checked};
use crate::{WaveError, WaveOptions, WaveScene};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::{Aabb, Dimension, Medium};
use speckle_motion::MotionModel;
use speckle_stats::{CMatrix, MatrixEstimate, PathRng, Progress, empirical_moments, run_ordered};

/// The exact fields of `R` configurations of moving scatterers at `T` times, and their
/// statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct WaveMotionEstimate {
    /// The times, in the order given.
    pub times: Vec<f64>,
    /// Number of pairs `J` of the scene.
    pub pairs: usize,
    /// Fields, one configuration per row, `R x (T J)`: column `a J + j` is pair `j` at time
    /// `times[a]`.
    pub fields: CMatrix,
    /// The covariance of the `T J` entries with standard errors.
    pub covariance: MatrixEstimate,
    /// Number of configurations `R`.
    pub configurations: u64,
    /// Mean number of scatterers inside the box over configurations and times.
    pub mean_scatterers: f64,
    /// Expected number of scatterers in the box, `n |V|`.
    pub expected_scatterers: f64,
}

impl WaveMotionEstimate {
    /// `C[j, k]` between pair `j` at time `times[a]` and pair `k` at time `times[b]` (the lag
    /// `times[b] - times[a]`), with its standard error.
    pub fn correlation(&self, a: usize, j: usize, b: usize, k: usize) -> (Complex64, Complex64) {
        let (r, c) = (a * self.pairs + j, b * self.pairs + k);
        (
            self.covariance.value.get(r, c),
            self.covariance.std_error.get(r, c),
        )
    }
}

/// The most field values (configurations x times x pairs) a render holds (1 GB).
pub const MAX_FIELD_ENTRIES: usize = 1 << 26;

/// The margin around the box from which scatterers can enter it during `span`.
fn margin(model: &MotionModel, span: f64) -> f64 {
    model.max_speed() * span + 8.0 * (2.0 * model.max_diffusion() * span).sqrt()
}

/// A standard normal variate (Box-Muller on two uniforms of the stream).
fn normal(rng: &mut PathRng) -> f64 {
    let [a, b] = rng.next_2();
    (-2.0 * (1.0 - a).ln()).sqrt() * (std::f64::consts::TAU * b).cos()
}

/// Solves `R` configurations of `scene` whose scatterers move as `model` says, at every time of
/// `times` (strictly increasing), and returns the fields with their empirical covariance
/// (see the module docs).
///
/// The scene's medium must be a lossless box of isotropic scatterers ([`crate::render_wave`]);
/// the motion is uniform (one [`speckle_motion::Motion`] for the box). Configuration `r` draws
/// from the stream `PathRng::new(seed, r)`; the result is bitwise the same for any number of
/// threads.
///
/// Errors name the input: `times` (fewer than two, not finite, not increasing), `motion`
/// (not uniform, or not fitting the medium), `configurations`, and those of
/// [`crate::render_wave`].
pub fn render_wave_motion(
    scene: &WaveScene,
    model: &MotionModel,
    times: &[f64],
    options: &WaveOptions,
    progress: &dyn Progress,
) -> Result<WaveMotionEstimate, WaveError> {
    let kernel = check_scene(scene)?;
    let expected = expected_scatterers(scene)?;
    let invalid = |field: &str, reason: String| WaveError::InvalidInput {
        field: field.into(),
        reason,
    };
    if times.len() < 2 {
        return Err(invalid("times", "needs at least two times".into()));
    }
    if let Some((i, t)) = times.iter().enumerate().find(|(_, t)| !t.is_finite()) {
        return Err(invalid(
            &format!("times[{i}]"),
            format!("must be finite (got {t})"),
        ));
    }
    if times
        .windows(2)
        .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
    {
        return Err(invalid("times", "must increase strictly".into()));
    }
    if model.motions().len() != 1 {
        return Err(invalid(
            "motion",
            "the wave solver's box is one material: give one motion".into(),
        ));
    }
    let model = scene
        .motion_fits(model)
        .map_err(|e| invalid("motion", e.to_string()))?;
    let motion = model.motions()[0];
    let r = options.configurations;
    if r < 2 {
        return Err(invalid(
            "configurations",
            format!("at least 2 configurations are needed for a covariance (got {r})"),
        ));
    }
    let b = *scene.medium().bounds();
    let flat = b.dimension() == Dimension::Two;
    let span = times[times.len() - 1] - times[0];
    let pad = margin(&model, span);
    let outer = if flat {
        Aabb::flat(
            b.min().truncate() - glam::DVec2::splat(pad),
            b.max().truncate() + glam::DVec2::splat(pad),
        )
    } else {
        Aabb::new(b.min() - DVec3::splat(pad), b.max() + DVec3::splat(pad))
    }
    .map_err(|e| {
        invalid(
            "motion",
            format!("the box grown by the motion's reach {pad} is invalid: {e}"),
        )
    })?;
    let n = number_density(scene)?;
    let outer_expected = n * outer.measure();
    if outer_expected > crate::MAX_EXPECTED_SCATTERERS * 4.0 {
        return Err(invalid(
            "motion",
            format!(
                "scatterers can move {pad} over the time span, so {outer_expected:.0} scatterers \
                 must be followed around the box; shorten the times or slow the motion"
            ),
        ));
    }
    let (nt, j) = (times.len(), scene.len());
    let cols = nt.saturating_mul(j);
    if r.saturating_mul(cols) > MAX_FIELD_ENTRIES {
        return Err(invalid(
            "configurations",
            format!(
                "{r} configurations of {nt} times x {j} pairs exceed the {MAX_FIELD_ENTRIES} \
                 field values a render holds"
            ),
        ));
    }
    let work = |c: usize| -> Option<Result<(Vec<Complex64>, usize), WaveError>> {
        if progress.cancelled() {
            return None;
        }
        let rng = &mut PathRng::new(options.seed, c as u64);
        // Poisson count in the grown box, uniform positions.
        let mut count = 0usize;
        let mut acc = -(1.0 - rng.next_f64()).ln();
        while acc <= outer_expected {
            count += 1;
            acc -= (1.0 - rng.next_f64()).ln();
        }
        let mut pos: Vec<DVec3> = (0..count)
            .map(|_| {
                let u = rng.next_3();
                outer.lerp(if flat { [u[0], u[1], 0.0] } else { u })
            })
            .collect();
        let mut row = Vec::with_capacity(cols);
        let mut inside_total = 0usize;
        let mut inside = Vec::with_capacity(count);
        for (a, &t) in times.iter().enumerate() {
            if a > 0 {
                let dt = t - times[a - 1];
                let sd = (2.0 * motion.diffusion * dt).sqrt();
                for p in &mut pos {
                    let g = DVec3::new(
                        normal(rng),
                        normal(rng),
                        if flat { 0.0 } else { normal(rng) },
                    );
                    *p += dt * motion.drift + sd * g;
                }
            }
            inside.clear();
            inside.extend(pos.iter().copied().filter(|p| b.contains(*p)));
            inside_total += inside.len();
            let cancelled = || progress.cancelled();
            match solve_checked(scene, kernel, &inside, &cancelled) {
                Ok(u) => row.extend(u),
                Err(e) => return Some(Err(e)),
            }
        }
        progress.advance(1);
        Some(Ok((row, inside_total)))
    };
    let mut fields = CMatrix::zeros(r, cols);
    let mut counts = 0usize;
    let mut failure = None;
    let done = run_ordered(r, 16 * cols, work, |row, solved| match solved {
        Ok((u, n)) => {
            fields.as_mut_slice()[row * cols..(row + 1) * cols].copy_from_slice(&u);
            counts += n;
        }
        Err(e) => {
            failure.get_or_insert(e);
        }
    });
    if let Some(e) = failure {
        return Err(e);
    }
    if !done {
        return Err(WaveError::Cancelled);
    }
    let moments = empirical_moments(&fields)?;
    Ok(WaveMotionEstimate {
        times: times.to_vec(),
        pairs: j,
        fields,
        covariance: moments.covariance,
        configurations: r as u64,
        mean_scatterers: counts as f64 / (r * nt) as f64,
        expected_scatterers: expected,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_endpoints::{Pair, Sensor, Source};
    use speckle_medium::HomogeneousBox;
    use speckle_motion::Motion;
    use speckle_phase::Phase;
    use speckle_stats::NoProgress;

    fn scene() -> WaveScene {
        let b = Aabb::flat(glam::DVec2::new(-5.0, -2.0), glam::DVec2::new(5.0, 2.0)).unwrap();
        let m = HomogeneousBox::from_mean_free_path(b, 4.0, 1.0).unwrap();
        WaveScene::new(
            m,
            Phase::FlatIsotropic,
            1.0,
            vec![Source::plane_wave(DVec3::Y).unwrap()],
            vec![Sensor::far_field(DVec3::new(0.3, 1.0, 0.0)).unwrap()],
            Pair::all(1, 1),
        )
        .unwrap()
    }

    /// At rest, every time sees the same configuration: the fields repeat exactly. Moving, the
    /// number of scatterers in the box stays Poisson with the static mean.
    #[test]
    fn static_motion_repeats_the_fields_and_density_is_kept() {
        let s = scene();
        let opts = WaveOptions {
            configurations: 40,
            seed: 3,
        };
        let w = render_wave_motion(&s, &MotionModel::at_rest(), &[0.0, 1.0], &opts, &NoProgress)
            .unwrap();
        for r in 0..40 {
            assert_eq!(w.fields.get(r, 0), w.fields.get(r, 1));
        }
        let moving = MotionModel::uniform(Motion::new(0.5, DVec3::new(2.0, 0.0, 0.0)).unwrap());
        let opts = WaveOptions {
            configurations: 400,
            seed: 3,
        };
        let w = render_wave_motion(&s, &moving, &[0.0, 1.0, 3.0], &opts, &NoProgress).unwrap();
        // Mean count over 1200 Poisson draws of mean ~ 8: SE ~ 0.08.
        let se = (w.expected_scatterers / 1200.0).sqrt();
        assert!(
            (w.mean_scatterers - w.expected_scatterers).abs() < 5.0 * se,
            "{} vs {}",
            w.mean_scatterers,
            w.expected_scatterers
        );
        // The fields decorrelate with time.
        let (c00, _) = w.correlation(0, 0, 0, 0);
        let (c02, _) = w.correlation(0, 0, 2, 0);
        assert!(c02.norm() < 0.5 * c00.re, "{c02} vs {c00}");
        // Bad times and models are refused, naming the field.
        let e = render_wave_motion(&s, &moving, &[1.0, 0.0], &opts, &NoProgress).unwrap_err();
        assert_eq!(e.field(), Some("times"));
        let two = MotionModel::per_material(vec![Motion::STATIC; 2]).unwrap();
        let e = render_wave_motion(&s, &two, &[0.0, 1.0], &opts, &NoProgress).unwrap_err();
        assert_eq!(e.field(), Some("motion"));
    }
}
