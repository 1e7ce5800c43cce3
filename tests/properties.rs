//! Structural properties of rendered covariances on random small scenes (proptest):
//! reciprocity, Hermitian symmetry, positive semi-definiteness.
//!
//! Reciprocity per sample. With forward and reversed paths, the estimator of a scene and of its
//! reciprocal (`scene.reciprocal()`: pairs `(i, v)` become `(-v, -i)`) are equal path by path,
//! up to rounding, when the same seed is used, because
//! - the sub-path sampler (first vertex, first direction, flights, roulette) depends only on the
//!   medium, the phase function and the sampling configuration, which both renders share
//!   (`paths/src/tracer.rs`, `paths/src/first.rs`: `ExponentialDepth` and `Phase { axis }` take
//!   their direction from the configuration, not from the endpoints), so both renders trace the
//!   same paths;
//! - in `estimators/src/connect.rs` the forward term of the reciprocal pair,
//!   `upsilon(-v -> x_1) s(-v . w12) upsilon(x_B -> -i) s(w_in . -i)`, is the reversed term of the
//!   original pair, `upsilon(x_1 -> v) s(-w12 . v) upsilon(i -> x_B) s(-i . w_in)`, and vice
//!   versa: in `estimators/src/endpoints.rs` a plane wave along `-v` has the leg
//!   `exp(-ik v.x)` attenuated along `+v`, exactly the far-field leg towards `v`, and a point
//!   source and a point sensor at the same position have the same `e^{ikr}/r` leg with the
//!   optical depth of the same segment; the single-scattering term `F` is symmetric likewise.
//!
//! The only differences are rounding: directions are normalised again when the reciprocal scene
//! is validated, and the optical depth of a segment is clipped from its other end. So the
//! renders must agree to `1e-9` of the entry's scale `sqrt(C_ii C_jj)` (observed: about 1e-15).
//! Forward-only renders are reciprocal only in expectation (the reciprocal scene's forward term
//! is the original's reversed term); that is checked statistically on one scene.
//!
//! Run time (release, 2 cores): under 1 s.

use num_complex::Complex64;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use speckle::estimators::{
    CMatrix, Coherence, CovarianceEstimate, CovarianceOptions, MatrixEstimate, NoProgress, Pair,
    Scene, Sensor, Source, render_covariance, render_single_scattering,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle::phase::Phase;

/// An endpoint before it is made a source or a sensor: a direction (plane wave / far field) or
/// a point outside the box.
#[derive(Debug, Clone, Copy)]
enum End {
    Dir(DVec3),
    Point(DVec3),
}

/// Parameters of a random small scene.
#[derive(Debug, Clone)]
struct Params {
    center: DVec3,
    size: DVec3,
    mfp: f64,
    albedo: f64,
    g: f64,
    wavelength: f64,
    sources: Vec<End>,
    sensors: Vec<End>,
    first_vertex: Option<DVec3>,
    first_direction: Option<DVec3>,
    paths: u64,
    seed: u64,
}

fn unit() -> impl Strategy<Value = DVec3> {
    (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU)
        .prop_map(|(t, p)| DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()))
}

/// A direction, or a point at distance `0.2..3` beyond the bounding sphere of the box (so
/// outside it): `(is_point, direction, margin)`, resolved against the box in [`params`].
fn end() -> impl Strategy<Value = (bool, DVec3, f64)> {
    (any::<bool>(), unit(), 0.2..3.0)
}

fn params() -> impl Strategy<Value = Params> {
    (
        (
            (-1.0..1.0, -1.0..1.0, -1.0..1.0),
            (0.5..4.0, 0.5..4.0, 0.5..4.0),
            0.3..3.0,
            0.5..=1.0,
            -0.8..0.9,
            0.05..1.0,
        ),
        (
            prop::collection::vec(end(), 1..=3),
            prop::collection::vec(end(), 1..=3),
            prop::option::of(unit()),
            prop::option::of(unit()),
            200u64..1500,
            any::<u64>(),
        ),
    )
        .prop_map(
            |((c, s, mfp, albedo, g, wavelength), (src, sen, fv, fd, paths, seed))| {
                let center = DVec3::new(c.0, c.1, c.2);
                let size = DVec3::new(s.0, s.1, s.2);
                let resolve = |(is_point, d, margin): (bool, DVec3, f64)| {
                    if is_point {
                        End::Point(center + d * (0.5 * size.length() + margin))
                    } else {
                        End::Dir(d)
                    }
                };
                Params {
                    center,
                    size,
                    mfp,
                    albedo,
                    g,
                    wavelength,
                    sources: src.into_iter().map(resolve).collect(),
                    sensors: sen.into_iter().map(resolve).collect(),
                    first_vertex: fv,
                    first_direction: fd,
                    paths,
                    seed,
                }
            },
        )
}

fn build(p: &Params) -> Scene<HomogeneousBox, Phase> {
    let medium = HomogeneousBox::from_mean_free_path(
        Aabb::centered(p.center, p.size).unwrap(),
        p.mfp,
        p.albedo,
    )
    .unwrap();
    let sources = p
        .sources
        .iter()
        .map(|e| match *e {
            End::Dir(d) => Source::plane_wave(d).unwrap(),
            End::Point(position) => Source::Point { position },
        })
        .collect();
    let sensors = p
        .sensors
        .iter()
        .map(|e| match *e {
            End::Dir(d) => Sensor::far_field(d).unwrap(),
            End::Point(position) => Sensor::Point { position },
        })
        .collect();
    Scene::new(
        medium,
        Phase::hg(p.g).unwrap(),
        p.wavelength,
        sources,
        sensors,
        Pair::all(p.sources.len(), p.sensors.len()),
    )
    .unwrap()
}

/// The sampling strategies of the case: the same for a scene and its reciprocal.
fn sampling(p: &Params) -> TracerConfig {
    TracerConfig {
        first_vertex: p.first_vertex.map_or(FirstVertex::Uniform, |direction| {
            FirstVertex::ExponentialDepth { direction }
        }),
        first_direction: p.first_direction.map_or(FirstDirection::Uniform, |axis| {
            FirstDirection::Phase { axis }
        }),
        ..TracerConfig::default()
    }
}

fn render(s: &Scene<HomogeneousBox, Phase>, p: &Params, c: Coherence) -> CovarianceEstimate {
    let opts = CovarianceOptions {
        paths: p.paths,
        seed: p.seed,
        coherence: c,
        sampling: sampling(p),
    };
    render_covariance(s, &opts, &NoProgress).unwrap()
}

/// Largest `|a_ij - b_ij| / sqrt(a_ii a_jj)` (0 where the scale is 0 and the entries are equal).
fn max_scaled_difference(a: &CMatrix, b: &CMatrix) -> f64 {
    let n = a.rows();
    let mut worst: f64 = 0.0;
    for i in 0..n {
        for j in 0..n {
            let d = (a.get(i, j) - b.get(i, j)).norm();
            if d == 0.0 {
                continue;
            }
            let scale = (a.get(i, i).re * a.get(j, j).re).sqrt();
            worst = worst.max(d / scale);
        }
    }
    worst
}

/// Checks Hermitian symmetry of a value and its standard errors: off the diagonal
/// `C_ij = conj(C_ji)` exactly; on it `|Im C_ii| <= 1e-12 Re C_ii` (the rank-one updates
/// `(w a) conj(a)` leave an imaginary part of rounding size, about 1e-18 relative, on the
/// diagonal). Also every value is finite and every SE non-negative, and the 2 x 2 minors obey
/// Cauchy-Schwarz, `|C_ij|^2 <= C_ii C_jj (1 + 1e-10)`.
fn assert_hermitian(name: &str, m: &MatrixEstimate) {
    let n = m.value.rows();
    assert_eq!(n, m.value.cols());
    for i in 0..n {
        for j in 0..n {
            let (v, se) = m.get(i, j);
            assert!(
                v.re.is_finite() && v.im.is_finite(),
                "{name}: C[{i},{j}] = {v}"
            );
            assert!(se.re >= 0.0 && se.im >= 0.0, "{name}: SE[{i},{j}] = {se}");
            assert_eq!(
                se,
                m.std_error.get(j, i),
                "{name}: SE[{i},{j}] != SE[{j},{i}]"
            );
            if i == j {
                assert!(
                    v.im.abs() <= 1e-12 * v.re,
                    "{name}: C[{i},{i}] = {v} is not real"
                );
            } else {
                assert_eq!(
                    v,
                    m.value.get(j, i).conj(),
                    "{name}: C[{i},{j}] != conj(C[{j},{i}])"
                );
                let bound = m.value.get(i, i).re * m.value.get(j, j).re;
                assert!(
                    v.norm_sqr() <= bound * (1.0 + 1e-10),
                    "{name}: |C[{i},{j}]|^2 = {} > C_ii C_jj = {bound}",
                    v.norm_sqr()
                );
            }
        }
    }
}

/// `x^H C x` is real and non-negative up to rounding: `Re >= -1e-10 tr(C) |x|^2` and
/// `|Im| <= 1e-10 tr(C) |x|^2`; the diagonal is non-negative. Returns the smallest
/// `Re(x^H C x) / (tr(C) |x|^2)` over the vectors.
fn assert_psd(name: &str, c: &CMatrix, xs: &[Vec<Complex64>]) -> f64 {
    let n = c.rows();
    let trace: f64 = c.diagonal().iter().map(|z| z.re).sum();
    for (i, d) in c.diagonal().iter().enumerate() {
        assert!(d.re >= 0.0, "{name}: C[{i},{i}] = {d}");
    }
    let mut smallest = f64::INFINITY;
    for x in xs {
        let x = &x[..n];
        let norm2: f64 = x.iter().map(|z| z.norm_sqr()).sum();
        let mut q = Complex64::new(0.0, 0.0);
        for i in 0..n {
            for j in 0..n {
                q += x[i].conj() * c.get(i, j) * x[j];
            }
        }
        let tol = 1e-10 * trace * norm2;
        assert!(q.re >= -tol, "{name}: x^H C x = {q} < -{tol}");
        assert!(q.im.abs() <= tol, "{name}: Im x^H C x = {} > {tol}", q.im);
        if trace > 0.0 && norm2 > 0.0 {
            smallest = smallest.min(q.re / (trace * norm2));
        }
    }
    smallest
}

fn vectors() -> impl Strategy<Value = Vec<Vec<Complex64>>> {
    prop::collection::vec(
        prop::collection::vec(
            (-1.0..1.0, -1.0..1.0).prop_map(|(a, b)| Complex64::new(a, b)),
            9,
        ),
        8,
    )
}

/// 16 cases per property from a fixed proptest seed (override with `PROPTEST_RNG_SEED`), and
/// no failure-persistence files (a failing case is printed with its parameters).
fn config() -> ProptestConfig {
    let base = ProptestConfig::default();
    let rng_seed = match base.rng_seed {
        RngSeed::Random => RngSeed::Fixed(20_190_701),
        fixed => fixed,
    };
    ProptestConfig {
        cases: 16,
        rng_seed,
        failure_persistence: None,
        ..base
    }
}

proptest! {
    #![proptest_config(config())]

    /// Reciprocity per sample: the forward-and-reversed render of a random scene and of its
    /// reciprocal with the same seed agree to `1e-9 sqrt(C_ii C_jj)` in the total, single and
    /// multiple parts (see the module documentation for why they are equal up to rounding).
    #[test]
    fn reciprocal_scene_renders_the_same_covariance(p in params()) {
        let s = build(&p);
        let r = s.reciprocal().unwrap();
        let a = render(&s, &p, Coherence::ForwardAndReversed);
        let b = render(&r, &p, Coherence::ForwardAndReversed);
        let mut worst: f64 = 0.0;
        for (name, x, y) in [
            ("total", &a.total, &b.total),
            ("single", &a.single, &b.single),
            ("multiple", &a.multiple, &b.multiple),
        ] {
            let d = max_scaled_difference(&x.value, &y.value);
            prop_assert!(d <= 1e-9, "{}: scaled difference {:e}", name, d);
            worst = worst.max(d);
        }
        eprintln!(
            "reciprocity: J = {}, paths {}, C[0,0] = {:.4e}, max scaled difference {:.1e}",
            s.len(), p.paths, a.total.value.get(0, 0).re, worst
        );
    }

    /// Hermitian symmetry `C_ij = conj(C_ji)` (exact off the diagonal, real diagonal) of the
    /// total, single and multiple parts of the covariance render in both coherence modes and of
    /// the single-scattering render, with symmetric, non-negative standard errors and
    /// Cauchy-Schwarz 2 x 2 minors (see [`assert_hermitian`]).
    #[test]
    fn rendered_covariances_are_hermitian(p in params()) {
        let s = build(&p);
        for c in [Coherence::ForwardAndReversed, Coherence::ForwardOnly] {
            let e = render(&s, &p, c);
            assert_hermitian("total", &e.total);
            assert_hermitian("single", &e.single);
            assert_hermitian("multiple", &e.multiple);
        }
        let opts = CovarianceOptions {
            paths: p.paths,
            seed: p.seed,
            coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
        assert_hermitian("single-scattering render", &render_single_scattering(&s, &opts, &NoProgress).unwrap());
    }

    /// Positive semi-definiteness: every rendered part is a sum of `w a a^H` with `w >= 0`, so
    /// `x^H C x >= 0` up to rounding (`-1e-10 tr(C) |x|^2`) for 8 random complex vectors, and
    /// the diagonal is non-negative, for the total, single and multiple parts in both modes.
    #[test]
    fn rendered_covariances_are_positive_semidefinite(p in params(), xs in vectors()) {
        let s = build(&p);
        let mut smallest = f64::INFINITY;
        for c in [Coherence::ForwardAndReversed, Coherence::ForwardOnly] {
            let e = render(&s, &p, c);
            smallest = smallest.min(assert_psd("total", &e.total.value, &xs));
            assert_psd("single", &e.single.value, &xs);
            assert_psd("multiple", &e.multiple.value, &xs);
        }
        eprintln!("PSD: J = {}, min x^H C x / (tr C |x|^2) = {smallest:.3e}", s.len());
    }
}

/// Forward-only renders are reciprocal in expectation, not per sample: a fixed asymmetric scene
/// (oblique plane wave and point source, far-field sensor in reflection and point sensor in
/// transmission, HG g = 0.7, box 3 x 2 x 1.5 of optical depth 1.5) and its reciprocal, rendered
/// with independent seeds and 400 k paths each, agree within 4 combined SEs in the real and
/// imaginary parts of all 10 entries `i <= j` (20 statistics; family-wise false alarm rate
/// about 0.1%).
#[test]
fn forward_only_render_is_reciprocal_in_expectation() {
    let p = Params {
        center: DVec3::new(0.2, 0.0, 0.0),
        size: DVec3::new(3.0, 2.0, 1.5),
        mfp: 1.0,
        albedo: 0.9,
        g: 0.7,
        wavelength: 0.5,
        sources: vec![
            End::Dir(DVec3::new(0.4, 0.1, 1.0).normalize()),
            End::Point(DVec3::new(-0.5, 0.3, -2.0)),
        ],
        sensors: vec![
            End::Dir(DVec3::new(-0.3, 0.2, -1.0).normalize()),
            End::Point(DVec3::new(1.0, -0.5, 2.5)),
        ],
        first_vertex: None,
        first_direction: None,
        paths: 400_000,
        seed: 5,
    };
    let s = build(&p);
    let a = render(&s, &p, Coherence::ForwardOnly);
    let b = render(
        &s.reciprocal().unwrap(),
        &Params {
            seed: 6,
            ..p.clone()
        },
        Coherence::ForwardOnly,
    );
    let mut max_z: f64 = 0.0;
    for i in 0..s.len() {
        for j in i..s.len() {
            let (x, sx) = a.total.get(i, j);
            let (y, sy) = b.total.get(i, j);
            let zr = (x.re - y.re) / sx.re.hypot(sy.re);
            let zi = if i == j {
                0.0
            } else {
                (x.im - y.im) / sx.im.hypot(sy.im)
            };
            eprintln!("C[{i},{j}]: {x:.4e} vs reciprocal {y:.4e}: z = ({zr:+.2}, {zi:+.2})");
            max_z = max_z.max(zr.abs()).max(zi.abs());
            assert!(
                zr.abs() < 4.0 && zi.abs() < 4.0,
                "C[{i},{j}]: z = ({zr}, {zi})"
            );
        }
    }
    eprintln!("forward-only reciprocity: max |z| = {max_z:.2}");
}
