//! The spatio-temporal covariance of moving scatterers (`render_correlation`, Bar et al. 2023):
//! exact identities and closed forms.
//!
//! - a zero lag is bitwise the static covariance (all entries) and intensity (diagonal);
//! - Hermitian symmetry in time, `C[j, k](t) = conj(C[k, j](-t))`, to rounding (it holds path
//!   by path);
//! - single scattering between far-field endpoints, Brownian motion: `g1(t) = exp(-k^2 D |t|
//!   |v - i|^2)` exactly (every path has the same factor);
//! - uniform lateral drift with far-field endpoints and `D = 0`: the phase of every path's
//!   contribution is `k t (v - i) . U` (the drift telescopes), for all orders of scattering, so
//!   `C(t) exp(-i k t (v - i) . U)` is real, positive and at most `C(0)` (paths through
//!   scatterers that leave the box in time contribute nothing);
//! - with `U = 0` the correlation depends on `D` and `t` through `D |t|` only;
//! - positive semi-definite matrices over (pair, time), within the standard errors (Weyl), for a
//!   drifting medium with far-field endpoints and a diffusing and drifting one with two point
//!   sources and two point sensors;
//! - tracking: with a uniform drift `U`, the correlation of `(i, v)` at `t1` with
//!   `(i + tU, v + tU)` at `t1 + t` equals the correlation of a medium at rest with the same
//!   `D`, within 4 combined standard errors;
//! - the spatio-temporal ridge: `|C[(i, v), (i + dx, v + dx)](t)|` peaks at `dx = U t`.
//!
//! Tolerances: rounding (`1e-12` relative) for identities, 4 combined standard errors for the
//! statistical comparisons. Run time: about 20 s in release on 2 cores.

use speckle::estimators::{
    Coherence, CorrelationEstimate, CovarianceOptions, Entries, NoProgress, Pair, Scene, Sensor,
    Source, render_correlation, render_covariance, render_intensity,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel};
use speckle::paths::TracerConfig;
use speckle::phase::{Complex64, Phase};
use speckle::stats::MatrixEstimate;

fn bits(m: &MatrixEstimate) -> Vec<(u64, u64)> {
    m.value
        .as_slice()
        .iter()
        .chain(m.std_error.as_slice())
        .map(|z| (z.re.to_bits(), z.im.to_bits()))
        .collect()
}

/// A slab with two plane waves and three far-field sensors (`J = 6`).
fn far_scene() -> Scene<HomogeneousBox, Phase> {
    let slab = Aabb::centered(DVec3::ZERO, DVec3::new(12.0, 12.0, 4.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(slab, 2.0, 0.95).unwrap();
    let tilt = |n: usize| DVec3::new(0.05 * n as f64, 0.0, 1.0);
    let src = (0..2)
        .map(|n| Source::plane_wave(tilt(n)).unwrap())
        .collect();
    let sen = vec![
        Sensor::far_field(tilt(0)).unwrap(),
        Sensor::far_field(DVec3::new(0.6, 0.1, 1.0)).unwrap(),
        Sensor::far_field(DVec3::new(0.3, 0.0, -1.0)).unwrap(),
    ];
    Scene::new(m, Phase::hg(0.3).unwrap(), 1.0, src, sen, Pair::all(2, 3)).unwrap()
}

/// A slab with two point sources in front and two point sensors behind it (`J = 4`).
fn point_scene() -> Scene<HomogeneousBox, Phase> {
    let slab = Aabb::centered(DVec3::ZERO, DVec3::new(30.0, 30.0, 4.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(slab, 2.0, 1.0).unwrap();
    let src = vec![
        Source::point(DVec3::new(-1.0, 0.0, -6.0)),
        Source::point(DVec3::new(1.0, 0.5, -6.0)),
    ];
    let sen = vec![
        Sensor::point(DVec3::new(0.0, 0.0, 6.0)),
        Sensor::point(DVec3::new(2.0, -1.0, 6.0)),
    ];
    Scene::new(m, Phase::hg(0.5).unwrap(), 1.0, src, sen, Pair::all(2, 2)).unwrap()
}

/// Paths of the ridge test.
const PATHS: u64 = 30_000;

fn opts(paths: u64, seed: u64, coherence: Coherence) -> CovarianceOptions {
    CovarianceOptions {
        paths,
        seed,
        coherence,
        ..Default::default()
    }
}

#[test]
fn zero_lag_is_bitwise_the_static_covariance() {
    let model = MotionModel::uniform(Motion::new(0.02, DVec3::new(0.3, -0.1, 0.05)).unwrap());
    for scene in [far_scene(), point_scene()] {
        for coherence in [Coherence::ForwardAndReversed, Coherence::ForwardOnly] {
            let o = opts(1501, 3, coherence);
            let full =
                render_correlation(&scene, &model, &[0.0, 0.7], &Entries::Full, &o, &NoProgress)
                    .unwrap();
            let c = render_covariance(&scene, &o, &NoProgress).unwrap();
            let z = &full.per_lag[0];
            assert_eq!(bits(&z.total), bits(&c.total));
            assert_eq!(bits(&z.single), bits(&c.single));
            assert_eq!(bits(&z.multiple), bits(&c.multiple));
            let diag = render_correlation(
                &scene,
                &model,
                &[0.7, 0.0],
                &Entries::Diagonal,
                &o,
                &NoProgress,
            )
            .unwrap();
            let i = render_intensity(&scene, &o, &NoProgress).unwrap();
            assert_eq!(bits(&diag.per_lag[1].total), bits(&i.total));
            assert_eq!(bits(&diag.per_lag[1].multiple), bits(&i.multiple));
            // The general (entry by entry) route at a vanishing lag agrees to rounding, and the
            // diagonal render's lags are the full render's diagonal.
            let tiny = render_correlation(
                &scene,
                &model,
                &[1e-300, 0.7],
                &Entries::Full,
                &o,
                &NoProgress,
            )
            .unwrap();
            let j = scene.len();
            let scale = c.total.value.get(0, 0).re;
            for r in 0..j {
                for q in 0..j {
                    let (a, b) = (
                        tiny.per_lag[0].total.value.get(r, q),
                        c.total.value.get(r, q),
                    );
                    assert!((a - b).norm() < 1e-12 * scale, "({r},{q}) {a} {b}");
                }
                let (a, b) = (
                    full.per_lag[1].total.value.get(r, r),
                    diag.per_lag[0].total.value.get(r, 0),
                );
                assert!((a - b).norm() < 1e-12 * scale, "{a} {b}");
            }
        }
    }
}

#[test]
fn hermitian_symmetry_in_time() {
    let model = MotionModel::uniform(Motion::new(0.01, DVec3::new(0.2, 0.1, -0.1)).unwrap());
    for scene in [far_scene(), point_scene()] {
        let o = opts(1001, 8, Coherence::ForwardAndReversed);
        let lags = [0.8, -0.8, 2.5, -2.5];
        let c = render_correlation(&scene, &model, &lags, &Entries::Full, &o, &NoProgress).unwrap();
        let j = scene.len();
        let scale = c.per_lag[0].total.value.get(0, 0).norm().max(1e-300);
        for (a, b) in [(0, 1), (2, 3)] {
            for r in 0..j {
                for q in 0..j {
                    let x = c.per_lag[a].total.value.get(r, q);
                    let y = c.per_lag[b].total.value.get(q, r).conj();
                    assert!(
                        (x - y).norm() < 1e-12 * scale,
                        "({r},{q}) lag {a}: {x} vs {y}"
                    );
                }
            }
        }
        // It decorrelates: |C(2.5)| < |C(0.8)| < C(0) on the diagonal.
        let z = render_correlation(&scene, &model, &[0.0], &Entries::Diagonal, &o, &NoProgress)
            .unwrap();
        let (c0, _) = z.total(0, 0);
        assert!(
            c.per_lag[2].total.value.get(0, 0).norm() < c.per_lag[0].total.value.get(0, 0).norm()
        );
        assert!(c.per_lag[0].total.value.get(0, 0).norm() < c0.re);
    }
}

/// Single scattering (paths stopped after `x1`) between plane waves and far-field sensors,
/// Brownian motion: every path carries the same factor, so the estimate is exactly `C(0)` times
/// it.
#[test]
fn single_scattering_far_field_closed_form() {
    let scene = far_scene();
    let d = 0.004;
    let model = MotionModel::uniform(Motion::brownian(d).unwrap());
    let o = CovarianceOptions {
        sampling: TracerConfig {
            max_vertices: 1,
            ..TracerConfig::default()
        },
        ..opts(4000, 2, Coherence::ForwardAndReversed)
    };
    let lags = [0.0, 0.5, -1.5, 3.0];
    let c = render_correlation(&scene, &model, &lags, &Entries::Diagonal, &o, &NoProgress).unwrap();
    let k = scene.wavenumber();
    for (e, p) in scene.pairs().iter().enumerate() {
        let Source::PlaneWave { direction: i } = scene.sources()[p.source] else {
            panic!()
        };
        let Sensor::FarField { direction: v } = scene.sensors()[p.sensor] else {
            panic!()
        };
        let q = v - i;
        let (c0, _) = c.total(0, e);
        for (l, &t) in lags.iter().enumerate() {
            let want = c0 * (-k * k * d * t.abs() * q.length_squared()).exp();
            let (got, _) = c.total(l, e);
            assert!(
                (got - want).norm() < 1e-12 * c0.re,
                "pair {e}, t = {t}: {got} vs {want}"
            );
        }
    }
}

/// Uniform lateral drift, no diffusion, far-field endpoints, forward paths: the drift phase
/// telescopes to `k t (v - i) . U` for every path, single and multiple scattering alike; the
/// rest is real, positive and at most `C(0)` (a path whose scatterers leave the box in time
/// contributes nothing), and close to `C(0)` for shifts small against the box. (With reversed
/// paths the cross terms of a forward and a reversed copy keep the Doppler phase but are real
/// only in pairs of equal moduli, which the box's side faces break near them.)
#[test]
fn uniform_drift_is_a_doppler_rotation() {
    let scene = far_scene();
    let u = DVec3::new(0.04, 0.02, 0.0);
    let model = MotionModel::uniform(Motion::new(0.0, u).unwrap());
    let lags = [0.0, 0.25, -1.0, 4.0];
    let k = scene.wavenumber();
    {
        let o = opts(2001, 6, Coherence::ForwardOnly);
        let c =
            render_correlation(&scene, &model, &lags, &Entries::Diagonal, &o, &NoProgress).unwrap();
        for (e, p) in scene.pairs().iter().enumerate() {
            let Source::PlaneWave { direction: i } = scene.sources()[p.source] else {
                panic!()
            };
            let Sensor::FarField { direction: v } = scene.sensors()[p.sensor] else {
                panic!()
            };
            let (c0, _) = c.total(0, e);
            for (l, &t) in lags.iter().enumerate() {
                let (got, _) = c.total(l, e);
                let rest = got * Complex64::from_polar(1.0, -k * t * (v - i).dot(u));
                assert!(
                    rest.im.abs() < 1e-12 * c0.re,
                    "pair {e}, t = {t}: {got} has not the Doppler phase"
                );
                assert!(
                    rest.re > 0.9 * c0.re && rest.re <= c0.re * (1.0 + 1e-12),
                    "pair {e}, t = {t}: {rest} against C(0) = {c0}"
                );
            }
        }
    }
}

#[test]
fn brownian_correlation_depends_on_d_times_t() {
    let scene = point_scene();
    let o = opts(1001, 12, Coherence::ForwardAndReversed);
    let a = MotionModel::uniform(Motion::brownian(0.01).unwrap());
    let b = MotionModel::uniform(Motion::brownian(0.04).unwrap());
    let ca = render_correlation(&scene, &a, &[2.0, -4.0], &Entries::Full, &o, &NoProgress).unwrap();
    let cb = render_correlation(&scene, &b, &[0.5, -1.0], &Entries::Full, &o, &NoProgress).unwrap();
    let scale = ca.per_lag[0].total.value.get(0, 0).norm();
    for l in 0..2 {
        for (x, y) in ca.per_lag[l]
            .total
            .value
            .as_slice()
            .iter()
            .zip(cb.per_lag[l].total.value.as_slice())
        {
            assert!((x - y).norm() < 1e-12 * scale, "{x} vs {y}");
        }
    }
}

/// Without drift, lags that are whole multiples of one step are taken as powers of one
/// exponential per term (a running product); with one irregular lag added, every lag is
/// evaluated directly. The same paths give the same values to rounding, lag by lag (each lag
/// accumulates on its own), for every entry, Brownian motion per material included.
#[test]
fn powers_of_regular_lags_equal_the_direct_factors() {
    let model = MotionModel::uniform(Motion::brownian(0.02).unwrap());
    for scene in [far_scene(), point_scene()] {
        for coherence in [Coherence::ForwardAndReversed, Coherence::ForwardOnly] {
            let o = opts(701, 21, coherence);
            let regular = [0.0, 0.4, -0.8, 1.2, 2.0, 0.4];
            let mut irregular = regular.to_vec();
            irregular.push(1000.0 * std::f64::consts::PI);
            let a = render_correlation(&scene, &model, &regular, &Entries::Full, &o, &NoProgress)
                .unwrap();
            let b = render_correlation(&scene, &model, &irregular, &Entries::Full, &o, &NoProgress)
                .unwrap();
            let scale = a.per_lag[0].total.value.get(0, 0).norm();
            for l in 0..regular.len() {
                for part in ["single", "multiple", "total"] {
                    let pick = |c: &CorrelationEstimate| {
                        let e = &c.per_lag[l];
                        let m = match part {
                            "single" => &e.single,
                            "multiple" => &e.multiple,
                            _ => &e.total,
                        };
                        (m.value.as_slice().to_vec(), m.std_error.as_slice().to_vec())
                    };
                    let ((va, sa), (vb, sb)) = (pick(&a), pick(&b));
                    for (x, y) in va.iter().zip(&vb).chain(sa.iter().zip(&sb)) {
                        assert!(
                            (x - y).norm() <= 1e-12 * scale,
                            "lag {l} {part}: {x} vs {y}"
                        );
                    }
                }
            }
            // The decay is there: |C(2.0)| < |C(0.4)| < C(0) on the diagonal.
            let d = |l: usize| a.per_lag[l].total.value.get(0, 0).norm();
            assert!(d(4) < d(1) && d(1) < d(0), "{} {} {}", d(0), d(1), d(4));
        }
    }
}

/// Lag grids as correlators give them take powers too (issue 30): a grid written to seven
/// significant digits (multiples of one step to within `3e-7`, interpolated between two steps)
/// and a multi-tau grid of six levels (eight lags each, the step doubling, 504 steps: split into
/// runs of their own steps). Against the direct factors (the same grids with an irregular lag
/// added, which takes none): equal to `1e-12` of the zero lag, entries full and diagonal, far
/// field and point endpoints; the nearest whole multiples instead of the interpolation differ
/// by up to `3e-7 m x` of a term.
#[test]
fn rounded_and_multi_tau_lags_equal_the_direct_factors() {
    let model = MotionModel::uniform(Motion::brownian(0.02).unwrap());
    let digits: Vec<f64> = (0..16)
        .map(|i| format!("{:.6e}", i as f64 * 2.0 / 63.0).parse().unwrap())
        .collect();
    let mut multi_tau = vec![0.0];
    let (mut m, mut step) = (0.0, 1.0);
    for _ in 0..6 {
        for _ in 0..8 {
            m += step;
            multi_tau.push(m * 0.01);
        }
        step *= 2.0;
    }
    for scene in [far_scene(), point_scene()] {
        for entries in [Entries::Full, Entries::Diagonal] {
            for lags in [&digits, &multi_tau] {
                let o = opts(501, 29, Coherence::ForwardAndReversed);
                let mut irregular = lags.clone();
                irregular.push(1000.0 * std::f64::consts::PI);
                let a =
                    render_correlation(&scene, &model, lags, &entries, &o, &NoProgress).unwrap();
                let b = render_correlation(&scene, &model, &irregular, &entries, &o, &NoProgress)
                    .unwrap();
                let scale = a.total(0, 0).0.norm();
                for l in 0..lags.len() {
                    for e in 0..a.entries.len() {
                        let ((va, sa), (vb, sb)) = (a.total(l, e), b.total(l, e));
                        assert!(
                            (va - vb).norm() <= 1e-12 * scale && (sa - sb).norm() <= 1e-12 * scale,
                            "lag {l} entry {e}: {va} vs {vb}"
                        );
                    }
                }
                assert!(a.total(lags.len() - 1, 0).0.norm() < 0.9 * scale);
            }
        }
    }
}

/// Drift with plane waves and far-field sensors in a box takes each term as one exponential in
/// the lag (the copies' connections along the drift line, `correlation/linear.rs`); legs that
/// change exit face within the lags' reach (near the box's edges) are taken lag by lag. Against
/// every lag connected copy by copy (the same grids with an irregular lag added, which takes no
/// powers): equal to `1e-12` of the zero lag, every entry and both coherence modes, regular and
/// multi-tau grids, drift with diffusion; also a voxel grid of one extinction (exponential legs
/// too) whose two halves drift differently (an interior drift phase).
#[test]
fn exponential_drift_equals_the_per_lag_connections() {
    use speckle::medium::{Material, Medium, VoxelGrid};
    let regular: Vec<f64> = (0..8).map(|l| l as f64 * 0.5).collect();
    let mut multi_tau = vec![0.0];
    let (mut m, mut step) = (0.0, 1.0);
    for _ in 0..4 {
        for _ in 0..4 {
            m += step;
            multi_tau.push(m * 0.1);
        }
        step *= 2.0;
    }
    fn compare<M: Medium>(scene: &Scene<M, Phase>, model: &MotionModel, lags: &[f64]) {
        for coherence in [Coherence::ForwardAndReversed, Coherence::ForwardOnly] {
            for entries in [Entries::Full, Entries::Diagonal] {
                let o = opts(1501, 31, coherence);
                let mut irregular = lags.to_vec();
                irregular.push(std::f64::consts::PI / 7.0);
                let a = render_correlation(scene, model, lags, &entries, &o, &NoProgress).unwrap();
                let b = render_correlation(scene, model, &irregular, &entries, &o, &NoProgress)
                    .unwrap();
                let scale = a.total(0, 0).0.norm();
                for l in 0..lags.len() {
                    for e in 0..a.entries.len() {
                        let at = |c: &CorrelationEstimate| {
                            let p = &c.per_lag[l];
                            [&p.single, &p.multiple, &p.total]
                                .map(|m| (m.value.as_slice()[e], m.std_error.as_slice()[e]))
                        };
                        for (x, y) in at(&a).iter().zip(at(&b)) {
                            assert!(
                                (x.0 - y.0).norm() <= 1e-12 * scale
                                    && (x.1 - y.1).norm() <= 1e-12 * scale,
                                "lag {l} entry {e}: {x:?} vs {y:?}"
                            );
                        }
                    }
                }
                // The drift turns the phases: the last lag's correlation is well below C(0).
                let last = a.total(lags.len() - 1, 0).0.norm();
                assert!(last < 0.9 * scale, "{last} vs {scale}");
            }
        }
    }
    let model = MotionModel::uniform(Motion::new(0.02, DVec3::new(0.5, -0.2, 0.1)).unwrap());
    let far = far_scene();
    for lags in [&regular, &multi_tau] {
        compare(&far, &model, lags);
    }
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(12.0, 12.0, 4.0)).unwrap();
    let mats = vec![Material::single(0.45, 0.05), Material::single(0.5, 0.0)];
    let grid = VoxelGrid::from_materials(b, [2, 1, 1], vec![0, 1], mats).unwrap();
    let voxel = Scene::new(
        grid,
        far.phases()[0].clone(),
        1.0,
        far.sources().to_vec(),
        far.sensors().to_vec(),
        Pair::all(2, 3),
    )
    .unwrap();
    let two = MotionModel::per_material(vec![
        Motion::new(0.02, DVec3::new(0.5, -0.2, 0.1)).unwrap(),
        Motion::new(0.01, DVec3::new(-0.3, 0.4, 0.0)).unwrap(),
    ])
    .unwrap();
    compare(&voxel, &two, &regular);
}

/// The diagonal entries' own path (`Entries::Diagonal` without drift: the Brownian exponents
/// formed per source, sensor and path, the powers of every entry formed together, one lane
/// each) against the general one (the same entries as a list), far-field and point endpoints,
/// with and without reversed paths: equal to rounding. The two form the same terms and powers
/// by different products and add them in a different order, so they differ by a few ulps of
/// the terms (measured: at most 4e-16 of the value plus its standard error); a term with a
/// wrong exponent or weight moves an entry by a good part of its value.
#[test]
fn diagonal_entries_match_the_general_path_to_rounding() {
    let model = MotionModel::uniform(Motion::brownian(0.02).unwrap());
    let mut worst: f64 = 0.0;
    for scene in [far_scene(), point_scene()] {
        let list = Entries::List((0..scene.len()).map(|j| (j, j)).collect());
        // (Without a zero lag, single scattering forms its values itself rather than take
        // the connector's.)
        let grids: [&[f64]; 2] = [&[0.0, 0.4, 0.8, 1.2, 2.0], &[0.4, 0.8, 1.2, 2.0]];
        for (coherence, lags) in [Coherence::ForwardAndReversed, Coherence::ForwardOnly]
            .into_iter()
            .flat_map(|c| grids.map(|g| (c, g)))
        {
            let o = opts(701, 23, coherence);
            let a = render_correlation(&scene, &model, lags, &Entries::Diagonal, &o, &NoProgress)
                .unwrap();
            let b = render_correlation(&scene, &model, lags, &list, &o, &NoProgress).unwrap();
            let first = lags.iter().position(|&t| t != 0.0).unwrap();
            for l in first..lags.len() {
                for j in 0..scene.len() {
                    let (x, y) = (a.total(l, j), b.total(l, j));
                    let scale = x.0.norm() + x.1.norm();
                    worst = worst.max((x.0 - y.0).norm() / scale);
                    assert!(
                        (x.0 - y.0).norm() <= 1e-13 * scale && (x.1 - y.1).norm() <= 1e-13 * scale,
                        "lag {l}, entry {j}: {x:?} vs {y:?}"
                    );
                }
            }
            assert!(a.total(lags.len() - 1, 0).0.re < a.total(first, 0).0.re);
        }
    }
    println!("largest difference: {worst:.2e} of value plus standard error");
}

/// The smallest eigenvalue of the Hermitian matrix `m` (n x n, row-major).
fn min_eigenvalue(m: &[Complex64], n: usize) -> f64 {
    let a = faer::Mat::<faer::c64>::from_fn(n, n, |r, c| {
        let z = m[r * n + c];
        faer::c64::new(z.re, z.im)
    });
    let ev = a.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    ev.into_iter().fold(f64::INFINITY, f64::min)
}

/// The (pair, time) matrix `M[(j, a), (k, b)] = C[j, k](t_b - t_a)` for times `times`, from a
/// render at the lags `t_b - t_a` (looked up in `c.lags`), with its standard errors.
fn pair_time_matrix(c: &CorrelationEstimate, j: usize, times: &[f64]) -> (Vec<Complex64>, f64) {
    let n = j * times.len();
    let mut m = vec![Complex64::ZERO; n * n];
    let mut se2 = 0.0;
    for (a, ta) in times.iter().enumerate() {
        for (b, tb) in times.iter().enumerate() {
            let l = c
                .lags
                .iter()
                .position(|t| (t - (tb - ta)).abs() < 1e-12)
                .expect("lag rendered");
            for r in 0..j {
                for q in 0..j {
                    let (v, s) = c.total(l, r * j + q);
                    m[(r * times.len() + a) * n + q * times.len() + b] = v;
                    se2 += s.norm_sqr();
                }
            }
        }
    }
    (m, se2.sqrt())
}

/// Positive semi-definite matrices over (pair, time).
#[test]
fn pair_time_matrices_are_positive_semidefinite() {
    let times = [0.0, 0.6, 1.5, 2.0];
    let lags: Vec<f64> = {
        let mut l = vec![];
        for a in &times {
            for b in &times {
                let t: f64 = b - a;
                if !l.iter().any(|x: &f64| (x - t).abs() < 1e-12) {
                    l.push(t);
                }
            }
        }
        l
    };
    // Drift with far-field endpoints and diffusion with drift between point endpoints: PSD
    // within the standard errors (Weyl: the eigenvalues move by at most the Frobenius norm of
    // the error). A drift sign inconsistent between positive and negative lags would make the
    // first clearly indefinite.
    let scene = far_scene();
    let model = MotionModel::uniform(Motion::new(0.0, DVec3::new(0.5, 0.3, 0.0)).unwrap());
    let o = opts(20_000, 2, Coherence::ForwardAndReversed);
    let c = render_correlation(&scene, &model, &lags, &Entries::Full, &o, &NoProgress).unwrap();
    let (m, se) = pair_time_matrix(&c, scene.len(), &times);
    let n = scene.len() * times.len();
    let lo = min_eigenvalue(&m, n);
    let scale = m.iter().map(|z| z.norm()).fold(0.0, f64::max);
    println!("drifting: smallest eigenvalue {lo:.3e}, largest entry {scale:.3e}, |SE|_F {se:.3e}");
    assert!(
        lo > -4.0 * se,
        "drifting: smallest eigenvalue {lo} below -4 |SE|_F = {}",
        -4.0 * se
    );
    // Diffusion with drift, point endpoints: PSD within the standard errors (Weyl: the
    // eigenvalues move by at most the Frobenius norm of the error).
    let scene = point_scene();
    let model = MotionModel::uniform(Motion::new(0.01, DVec3::new(0.2, 0.0, 0.1)).unwrap());
    let o = opts(20_000, 5, Coherence::ForwardAndReversed);
    let c = render_correlation(&scene, &model, &lags, &Entries::Full, &o, &NoProgress).unwrap();
    let (m, se) = pair_time_matrix(&c, scene.len(), &times);
    let n = scene.len() * times.len();
    let lo = min_eigenvalue(&m, n);
    let scale = m.iter().map(|z| z.norm()).fold(0.0, f64::max);
    println!("diffusing: smallest eigenvalue {lo:.3e}, largest entry {scale:.3e}, |SE|_F {se:.3e}");
    assert!(
        lo > -4.0 * se,
        "smallest eigenvalue {lo} below -4 |SE|_F = {}",
        -4.0 * se
    );
}

/// Tracking (Eqs. 38-39, Fig. 9): shifting source and sensor with a uniform flow gives the
/// correlation of a medium at rest with the same diffusion.
#[test]
fn tracking_the_flow_removes_the_drift() {
    let slab = Aabb::centered(DVec3::ZERO, DVec3::new(200.0, 200.0, 4.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(slab, 2.0, 1.0).unwrap();
    let u = DVec3::new(0.5, 0.0, 0.0);
    let d = 0.002;
    let lags = [0.0, 1.0, 2.0, 3.0];
    let (i, v) = (DVec3::new(0.0, 0.0, -5.0), DVec3::new(1.0, 0.0, 5.0));
    // Sources and sensors shifted by t U for each lag.
    let src: Vec<Source> = lags.iter().map(|t| Source::point(i + *t * u)).collect();
    let sen: Vec<Sensor> = lags.iter().map(|t| Sensor::point(v + *t * u)).collect();
    let pairs = (0..lags.len())
        .map(|n| Pair {
            source: n,
            sensor: n,
        })
        .collect();
    let scene = Scene::new(m.clone(), Phase::hg(0.6).unwrap(), 1.0, src, sen, pairs).unwrap();
    let entries = Entries::List((0..lags.len()).map(|n| (0, n)).collect());
    let o = opts(60_000, 21, Coherence::ForwardAndReversed);
    let flow = MotionModel::uniform(Motion::new(d, u).unwrap());
    let tracked = render_correlation(&scene, &flow, &lags, &entries, &o, &NoProgress).unwrap();
    let rest = MotionModel::uniform(Motion::brownian(d).unwrap());
    let still = render_correlation(&scene, &rest, &lags, &entries, &o, &NoProgress).unwrap();
    let (c0, _) = still.total(0, 0);
    for (l, t) in lags.iter().enumerate().skip(1) {
        // Entry (0, l) tracks the flow over the lag t = lags[l]; entry (0, 0) does not.
        let (a, sa) = tracked.total(l, l);
        let (b, sb) = still.total(l, 0);
        let (n, _) = tracked.total(l, 0);
        let tol = |x: f64, y: f64| 4.0 * (x * x + y * y).sqrt();
        println!(
            "t = {t}: tracked {a:.4e}, at rest {b:.4e}, untracked {n:.4e} (C(0) = {:.4e})",
            c0.re
        );
        assert!(
            (a.re - b.re).abs() < tol(sa.re, sb.re),
            "t = {t}: {a} vs {b}"
        );
        assert!(
            (a.im - b.im).abs() < tol(sa.im, sb.im),
            "t = {t}: {a} vs {b}"
        );
        // And without tracking the drift decorrelates much more.
        assert!(n.norm() < 0.5 * b.norm(), "untracked {n} vs {b}");
    }
}

/// The vertex of the parabola through `(x - h, a)`, `(x, b)`, `(x + h, c)` and its standard
/// error from the standard errors `(sa, sb, sc)` of the three values (first-order propagation,
/// errors taken as independent).
fn parabola_vertex(x: f64, h: f64, [a, b, c]: [f64; 3], [sa, sb, sc]: [f64; 3]) -> (f64, f64) {
    let (num, den) = (a - c, a - 2.0 * b + c);
    let vertex = x + 0.5 * h * num / den;
    let da = 0.5 * h * (1.0 / den - num / (den * den));
    let db = 0.5 * h * (2.0 * num / (den * den));
    let dc = 0.5 * h * (-1.0 / den - num / (den * den));
    let se = ((da * sa).powi(2) + (db * sb).powi(2) + (dc * sc).powi(2)).sqrt();
    (vertex, se)
}

/// The spatio-temporal ridge (Fig. 9): with a uniform drift `U` along x, the magnitude of
/// `C[(i, v), (i + dx, v + dx)](t)` over the offset `dx` peaks at `dx = U t` (at `dx = 0` for
/// `t = 0`). In a slab wide against the paths' spread, moving the medium by `U t` is moving
/// the endpoints by `-U t`, so `C = g(dx - U t)`, and `|g(d)| = |g(-d)|` (translation
/// invariance and the exchange of the two configurations), so the ridge is symmetric about
/// `U t`. The grid (step `h`) holds `U t`, so the parabola through the largest value and its
/// two neighbours has its vertex at `U t` up to noise: the tolerance is 4 standard errors of
/// the vertex, propagated from those of the three values, and the test also asks that this
/// tolerance be under one grid step `h`, so that a ridge misplaced by a step or more is caught
/// (a flipped drift puts it at `-U t`, `2 U t / h` = 4 to 12 steps away for `t >= 1`).
#[test]
fn the_spatio_temporal_ridge_sits_at_u_t() {
    let slab = Aabb::centered(DVec3::ZERO, DVec3::new(200.0, 200.0, 4.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(slab, 2.0, 1.0).unwrap();
    let u = DVec3::new(0.5, 0.0, 0.0);
    let d = 0.002;
    let lags = [0.0, 1.0, 2.0, 3.0];
    let h = 0.25;
    let offsets: Vec<f64> = (0..15).map(|n| -1.75 + h * n as f64).collect();
    let reference = offsets.iter().position(|x| *x == 0.0).unwrap();
    let (i, v) = (DVec3::new(0.0, 0.0, -5.0), DVec3::new(1.0, 0.0, 5.0));
    let shift = |dx: f64| DVec3::new(dx, 0.0, 0.0);
    let src: Vec<Source> = offsets
        .iter()
        .map(|x| Source::point(i + shift(*x)))
        .collect();
    let sen: Vec<Sensor> = offsets
        .iter()
        .map(|x| Sensor::point(v + shift(*x)))
        .collect();
    let pairs = (0..offsets.len())
        .map(|n| Pair {
            source: n,
            sensor: n,
        })
        .collect();
    let scene = Scene::new(m, Phase::hg(0.6).unwrap(), 1.0, src, sen, pairs).unwrap();
    let entries = Entries::List((0..offsets.len()).map(|n| (reference, n)).collect());
    let o = opts(PATHS, 33, Coherence::ForwardAndReversed);
    let flow = MotionModel::uniform(Motion::new(d, u).unwrap());
    let c = render_correlation(&scene, &flow, &lags, &entries, &o, &NoProgress).unwrap();
    for (l, t) in lags.iter().enumerate() {
        let ridge: Vec<(f64, f64)> = (0..offsets.len())
            .map(|e| {
                let (z, s) = c.total(l, e);
                (z.norm(), s.norm())
            })
            .collect();
        let top = (0..offsets.len())
            .max_by(|a, b| ridge[*a].0.total_cmp(&ridge[*b].0))
            .unwrap();
        assert!(
            top > 0 && top + 1 < offsets.len(),
            "t = {t}: the largest |C| is at the edge of the grid ({})",
            offsets[top]
        );
        let three =
            |f: fn(&(f64, f64)) -> f64| [f(&ridge[top - 1]), f(&ridge[top]), f(&ridge[top + 1])];
        let (peak, se) = parabola_vertex(offsets[top], h, three(|r| r.0), three(|r| r.1));
        let want = t * u.x;
        println!(
            "t = {t}: ridge at dx = {peak:.4} +- {se:.4} (U t = {want}), |C| max {:.4e} +- {:.1e}",
            ridge[top].0, ridge[top].1
        );
        assert!(
            4.0 * se < h,
            "t = {t}: the vertex is too noisy to locate the ridge ({se})"
        );
        assert!(
            (peak - want).abs() < 4.0 * se,
            "t = {t}: the ridge is at dx = {peak} +- {se}, not at U t = {want}"
        );
    }
}

/// Bad input is refused naming the field, before any path is traced.
#[test]
fn bad_input_names_the_field() {
    let scene = point_scene();
    let model = MotionModel::uniform(Motion::brownian(0.01).unwrap());
    let o = opts(100, 1, Coherence::ForwardAndReversed);
    let field = |lags: &[f64], entries: &Entries, model: &MotionModel, o: &CovarianceOptions| {
        match render_correlation(&scene, model, lags, entries, o, &NoProgress) {
            Err(speckle::estimators::EstimatorError::InvalidInput { field, .. }) => field,
            other => panic!("expected an invalid input, got {other:?}"),
        }
    };
    assert_eq!(field(&[], &Entries::Diagonal, &model, &o), "lags");
    assert_eq!(
        field(&[0.0, f64::NAN], &Entries::Diagonal, &model, &o),
        "lags[1]"
    );
    assert_eq!(field(&[1.0], &Entries::List(vec![]), &model, &o), "entries");
    assert_eq!(
        field(&[1.0], &Entries::List(vec![(0, 1), (4, 0)]), &model, &o),
        "entries[1]"
    );
    let two = MotionModel::per_material(vec![Motion::STATIC; 2]).unwrap();
    assert_eq!(
        field(&[1.0], &Entries::Diagonal, &two, &o),
        "motion.materials"
    );
    // Absurd sizes are refused before anything is allocated.
    let many = vec![1.0; 1 << 23];
    assert_eq!(field(&many, &Entries::Full, &model, &o), "lags");
    let one = opts(1, 1, Coherence::ForwardAndReversed);
    assert_eq!(field(&[1.0], &Entries::Diagonal, &model, &one), "paths");
}
