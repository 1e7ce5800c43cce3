//! Field sequences of moving scatterers (`render_field_sequence`, Bar et al. 2023 Sec. 5):
//!
//! - the empirical covariance of sampled sequences over realizations, between every pair at
//!   every two times, equals `render_correlation`'s `C[j, k](t_b - t_a)` (an independent
//!   estimator: analytic gammas from traced paths, no sampled displacements), in absolute units,
//!   for two values of `N` (the `1/sqrt(N)` normalisation);
//! - Siegert: `<I(t_a) I(t_a + t)> / <I>^2 = 1 + |g1(t)|^2` with `g1` from `render_correlation`;
//! - speckle contrast: the contrast of the intensity integrated over an exposure `T` (sampled at
//!   16 midpoints of `[0, T]`) is `K(T)` of `speckle_motion::correlation::contrast` from the
//!   same `g1`;
//! - without motion every frame is bitwise the static `render_fields` realization, and with
//!   motion the frame at time 0 is; the same seed gives bitwise the same sequences on 1 and 3
//!   threads; bad inputs are refused naming the field.
//!
//! Tolerances: 4.5 combined standard errors (sample standard deviations over `sqrt(R)` for the
//! sequences, delta-method for ratios; batch means for the renders); fixed seeds. Run time:
//! about 45 s for the file in release on 2 busy cores (the Siegert and contrast tests share one
//! render of about 25 s, the covariance test about 12 s).

use num_complex::Complex64;
use speckle::estimators::{
    Coherence, CorrelationEstimate, CovarianceOptions, Entries, FieldOptions, FieldSequence,
    NoProgress, Pair, Scene, Sensor, Source, render_correlation, render_field_sequence,
    render_fields,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel, correlation};
use speckle::phase::Phase;
use speckle::stats::empirical_moments;

/// The tolerance, in combined standard errors.
const Z: f64 = 4.5;

/// The unit direction in the x-z plane tilted from `+z` by `asin(sx)`.
fn tilted(sx: f64) -> DVec3 {
    DVec3::new(sx, 0.0, (1.0 - sx * sx).sqrt())
}

/// A slab 4 x 4 x 2 (mean free path `mfp`, albedo 0.9, HG g = 0.5), wavelength 0.1 (k = 62.8),
/// lit by the plane waves tilted by `sources` and seen in transmission by far-field sensors
/// tilted by `sensors`.
fn slab(mfp: f64, sources: &[f64], sensors: &[f64]) -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap();
    let medium = HomogeneousBox::from_mean_free_path(b, mfp, 0.9).unwrap();
    let src = sources
        .iter()
        .map(|&s| Source::plane_wave(tilted(s)).unwrap())
        .collect();
    let sen = sensors
        .iter()
        .map(|&s| Sensor::far_field(tilted(s)).unwrap())
        .collect();
    let pairs = Pair::all(sources.len(), sensors.len());
    Scene::new(medium, Phase::hg(0.5).unwrap(), 0.1, src, sen, pairs).unwrap()
}

fn brownian(d: f64) -> MotionModel {
    MotionModel::uniform(Motion::brownian(d).unwrap())
}

/// Mean and standard error (sample SD over `sqrt(n)`).
fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0);
    (m, (v / n).sqrt())
}

/// Every entry `(j at t_a, k at t_b)` of the empirical covariance of `R` sampled sequences
/// against `C[j, k](t_b - t_a)` of `render_correlation` (all entries, lags `0, 0.5, 1`), for
/// real and imaginary parts: `|C_emp - C| < 4.5 sqrt(SE_emp^2 + SE_render^2)`.
fn compare(seq: &FieldSequence, corr: &CorrelationEstimate, label: &str) {
    let (t, j) = (seq.times.len(), seq.pairs());
    let moments = empirical_moments(&seq.fields).unwrap();
    let mut max_z: f64 = 0.0;
    let mut count = 0;
    for a in 0..t {
        for b in a..t {
            let lag = seq.times[b] - seq.times[a];
            let l = corr.lags.iter().position(|x| *x == lag).unwrap();
            for p in 0..j {
                for q in 0..j {
                    let (emp, se) = moments.covariance.get(a * j + p, b * j + q);
                    let (val, rse) = corr.total(l, p * j + q);
                    let zr = (emp.re - val.re) / se.re.hypot(rse.re);
                    let zi = if a == b && p == q {
                        0.0
                    } else {
                        (emp.im - val.im) / se.im.hypot(rse.im)
                    };
                    let g = val.norm() / corr.total(0, p * j + p).0.re;
                    if p == q || a == 0 {
                        eprintln!(
                            "{label}: C[{p}, {q}]({lag}) (|C| / C[{p},{p}](0) = {g:.3}): \
                             sequences {emp:.5} +- {se:.5} vs render {val:.5} +- {rse:.5}: \
                             z = ({zr:+.2}, {zi:+.2})"
                        );
                    }
                    max_z = max_z.max(zr.abs()).max(zi.abs());
                    count += 1;
                    assert!(
                        zr.abs() < Z && zi.abs() < Z,
                        "{label}: C[{p},{q}]({lag}) at times {a}, {b}: sequences {emp} +- {se} \
                         vs render {val} +- {rse}: z = ({zr}, {zi})"
                    );
                }
            }
        }
    }
    eprintln!("{label}: max |z| over {count} entries (re and im): {max_z:.2}");
}

/// The empirical spatio-temporal covariance of sampled sequences is `render_correlation`'s, in
/// absolute units. Scene: the slab with mean free path 0.5 (optical depth 4), two plane waves
/// (normal and tilted by `lambda / (2 W)`, memory-effect partners) and two far-field sensors
/// 0.2 and 0.2125 rad off axis (`J = 4`), forward and reversed paths; Brownian motion with
/// `D = 2e-5`, times `0, 0.5, 1` (`g1` of a pair drops to about 0.5 at `t = 1`). Sequences:
/// `R = 12000` realizations of `N = 20` sub-paths, and `R = 3000` of `N = 80`; render 400 000
/// paths. 96 entries (all pairs of pairs at all two times `t_a <= t_b`), real and imaginary parts.
#[test]
fn empirical_covariance_of_sequences_is_the_spatio_temporal_covariance() {
    let delta = 0.5 * 0.1 / 4.0;
    let scene = slab(0.5, &[0.0, delta], &[0.2, 0.2 + delta]);
    let model = brownian(2e-5);
    let times = [0.0, 0.5, 1.0];
    let corr = render_correlation(
        &scene,
        &model,
        &times,
        &Entries::Full,
        &CovarianceOptions {
            paths: 400_000,
            seed: 3,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    for (r, n, seed) in [(12_000, 20, 4), (3000, 80, 5)] {
        let opts = FieldOptions {
            realizations: r,
            paths_per_realization: n,
            seed,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        };
        let seq = render_field_sequence(&scene, &model, &times, &opts, &NoProgress).unwrap();
        compare(&seq, &corr, &format!("R = {r}, N = {n}"));
    }
}

/// The same with focused Gaussian beams (Bar et al. 2020). A slab 4 x 4 x 0.5 (mean free path
/// 0.5, albedo 0.9, isotropic), wavelength 0.1; two sources focused at the slab's centre 0.05
/// apart, propagating along `+z` with apertures of concentration 3 (half-width about 0.6 rad);
/// a Gaussian sensor focused there too looking along `+z`, and a far-field sensor along `+z`.
/// Every scatterer diffuses (`D = 2.5e-4`, `k^2 D = 1`) and drifts (`U = 0.02` along x). Light
/// scattered once near the axis is where a beam's spread of directions matters: it
/// decorrelates forward single scattering, which one direction per beam would leave intact.
/// The sequences displace every vertex along sampled trajectories; the render samples only
/// the end vertices' displacements and takes the interior ones in closed form:
/// `R = 4000` realizations of `N = 20` sub-paths against 100 000 paths.
#[test]
fn empirical_covariance_of_beam_sequences_is_the_spatio_temporal_covariance() {
    use speckle::endpoints::GaussianBeam;
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 4.0, 0.5)).unwrap();
    let medium = HomogeneousBox::from_mean_free_path(b, 0.5, 0.9).unwrap();
    let beam = |x: f64| GaussianBeam::new("beam", DVec3::new(x, 0.0, 0.0), DVec3::Z, 3.0).unwrap();
    let src = vec![
        Source::GaussianBeam(beam(0.0)),
        Source::GaussianBeam(beam(0.05)),
    ];
    let sen = vec![
        Sensor::GaussianBeam(beam(0.0)),
        Sensor::far_field(DVec3::Z).unwrap(),
    ];
    let scene = Scene::new(medium, Phase::Isotropic, 0.1, src, sen, Pair::all(2, 2)).unwrap();
    let model = MotionModel::uniform(Motion::new(2.5e-4, DVec3::new(0.02, 0.0, 0.0)).unwrap());
    let times = [0.0, 0.5, 1.0];
    let corr = render_correlation(
        &scene,
        &model,
        &times,
        &Entries::Full,
        &CovarianceOptions {
            paths: 100_000,
            seed: 3,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    let opts = FieldOptions {
        realizations: 4000,
        paths_per_realization: 20,
        seed: 4,
        coherence: Coherence::ForwardAndReversed,
        add_mean: false,
        ..Default::default()
    };
    let seq = render_field_sequence(&scene, &model, &times, &opts, &NoProgress).unwrap();
    compare(&seq, &corr, "beams");
}

/// The frames of a Siegert/contrast run: 16 midpoints of `[0, T]`.
const FRAMES: usize = 16;

/// Sub-paths per realization of the Siegert/contrast sequences.
const N_PATHS: u64 = 200;

/// Siegert and contrast share one render: the slab with mean free path 1 (optical depth 2), one
/// plane wave, four far-field sensors 0.2 to 0.5 rad off axis (independent speckles), forward
/// paths only; Brownian motion `D = 5e-4`; sequences at the 16 midpoints `(l + 1/2) dt` of an
/// exposure `T = 16 dt`, `dt = 0.0625`: `R = 3000` realizations of `N = 200` sub-paths, and
/// `R = 50 000` single-path sequences (`N = 1`, for the finite-`N` term); and
/// `render_correlation` of the four pairs at lags `m dt / 2`, `m = 0 .. 32` (200 000 paths).
///
/// # The finite-`N` term
///
/// A field is a sum of `N` independent path terms `x / sqrt(N)`, so its intensity statistics
/// are those of circular Gaussian fields up to the paths' fourth cumulant over `N`: for any two
/// frames `Cov_N(I_a, I_b) = (1 - 1/N) |C_ab|^2 + Cov_1(I_a, I_b) / N`, `Cov_1` that of single
/// paths. Hence `g2_N - 1 = (1 - 1/N) |g1|^2 + (g2_1 - 1) / N` and
/// `K_N^2 = (1 - 1/N) K^2 + K_1^2 / N`. For this scene the single-path `g2_1(0)` is about 4.8
/// and `K_1^2` about 3.1, so the term is about `+0.014` in `g2` and `+0.013` in `K^2` (1 SE) at
/// `N = 200` (with seed 13 of the `N = 200` sequences it was 2.3 SE): the tests compare with the Gaussian
/// prediction from `g1` plus this term measured from the `N = 1` sequences (it is not fitted,
/// and vanishes as `N` grows; both are printed).
struct Dynamic {
    seq: FieldSequence,
    single: FieldSequence,
    corr: CorrelationEstimate,
    dt: f64,
}

fn dynamic() -> Dynamic {
    let scene = slab(1.0, &[0.0], &[0.2, 0.3, 0.4, 0.5]);
    let model = brownian(5e-4);
    let dt = 0.0625;
    let times: Vec<f64> = (0..FRAMES).map(|l| (l as f64 + 0.5) * dt).collect();
    let opts = |realizations, paths_per_realization, seed| FieldOptions {
        realizations,
        paths_per_realization,
        seed,
        coherence: Coherence::ForwardOnly,
        add_mean: false,
        ..Default::default()
    };
    let render =
        |o: &FieldOptions| render_field_sequence(&scene, &model, &times, o, &NoProgress).unwrap();
    let seq = render(&opts(3000, N_PATHS, 11));
    let single = render(&opts(50_000, 1, 13));
    let lags: Vec<f64> = (0..=2 * FRAMES).map(|m| m as f64 * dt / 2.0).collect();
    let corr = render_correlation(
        &scene,
        &model,
        &lags,
        &Entries::Diagonal,
        &CovarianceOptions {
            paths: 200_000,
            seed: 12,
            coherence: Coherence::ForwardOnly,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    Dynamic {
        seq,
        single,
        corr,
        dt,
    }
}

fn dynamic_cached() -> &'static Dynamic {
    static CELL: std::sync::OnceLock<Dynamic> = std::sync::OnceLock::new();
    CELL.get_or_init(dynamic)
}

/// `|g1_j|^2` of pair `j` at lag number `l` of the render and its standard error (the SE of
/// `C(t)` over `C(0)`, doubled by the square).
fn g1_sq(corr: &CorrelationEstimate, l: usize, j: usize) -> (f64, f64) {
    let (c0, _) = corr.total(0, j);
    let (c, se) = corr.total(l, j);
    let g = c / c0.re;
    let se = se / c0.re;
    (
        g.norm_sqr(),
        2.0 * (g.re * g.re * se.re * se.re + g.im * g.im * se.im * se.im).sqrt(),
    )
}

/// A ratio `E[a] / E[b]^2` over realizations, averaged over the sensors, with its standard
/// error (delta method: the influence of each realization): `a(row, p)`, `b(row, p)`.
fn pooled_ratio(
    rows: usize,
    pairs: usize,
    a: impl Fn(usize, usize) -> f64,
    b: impl Fn(usize, usize) -> f64,
) -> (f64, f64) {
    let mut value = 0.0;
    let mut infl = vec![0.0; rows];
    for p in 0..pairs {
        let av: Vec<f64> = (0..rows).map(|r| a(r, p)).collect();
        let bv: Vec<f64> = (0..rows).map(|r| b(r, p)).collect();
        let (am, _) = mean_se(&av);
        let (bm, _) = mean_se(&bv);
        value += am / (bm * bm) / pairs as f64;
        for r in 0..rows {
            infl[r] += ((av[r] - am) / (bm * bm) - 2.0 * am * (bv[r] - bm) / (bm * bm * bm))
                / pairs as f64;
        }
    }
    (value, mean_se(&infl).1)
}

/// `<I(t_a) I(t_a + m dt)> / <I>^2` of a sequence, over the time origins and the sensors.
fn g2_of(seq: &FieldSequence, m: usize) -> (f64, f64) {
    let i = |row: usize, l: usize, p: usize| seq.get(row, l, p).norm_sqr();
    pooled_ratio(
        seq.fields.rows(),
        seq.pairs(),
        |row, p| {
            (0..FRAMES - m)
                .map(|a| i(row, a, p) * i(row, a + m, p))
                .sum::<f64>()
                / (FRAMES - m) as f64
        },
        |row, p| (0..FRAMES).map(|l| i(row, l, p)).sum::<f64>() / FRAMES as f64,
    )
}

/// `K^2 = <S^2> / <S>^2 - 1` of the exposure `S` (the mean of the frames), over the sensors.
fn contrast_of(seq: &FieldSequence) -> (f64, f64) {
    let s = |row: usize, p: usize| {
        (0..FRAMES)
            .map(|l| seq.get(row, l, p).norm_sqr())
            .sum::<f64>()
            / FRAMES as f64
    };
    let (v, se) = pooled_ratio(seq.fields.rows(), seq.pairs(), |r, p| s(r, p).powi(2), s);
    (v - 1.0, se)
}

/// Siegert: for each lag `t = m dt`, `m = 0 .. 11`, the intensity autocorrelation of the
/// sampled sequences averaged over the four sensors and over the time origins,
/// `g2 = <I(t_a) I(t_a + t)> / <I>^2`, equals `1 + (1 - 1/N) |g1(t)|^2 + (g2_1(t) - 1) / N`
/// with `|g1|^2` of `render_correlation` (averaged over the sensors) and `g2_1` of single-path
/// sequences (see [`Dynamic`]), within 4.5 combined standard errors (the sequences' by the
/// delta method over realizations). `N = 200`; the finite-`N` term is printed.
#[test]
fn intensity_autocorrelation_of_sequences_is_siegert() {
    let d = dynamic_cached();
    let j = d.seq.pairs();
    let n = N_PATHS as f64;
    let lags = 12;
    let mut max_z: f64 = 0.0;
    for m in 0..lags {
        let (emp, se) = g2_of(&d.seq, m);
        let (one, one_se) = g2_of(&d.single, m);
        let (mut g, mut g_var) = (0.0, 0.0);
        for p in 0..j {
            let (v, s) = g1_sq(&d.corr, 2 * m, p);
            g += v / j as f64;
            g_var += s * s / (j * j) as f64;
        }
        let finite = (one - 1.0 - g) / n;
        let expect = 1.0 + g + finite;
        let expect_se = ((1.0 - 1.0 / n).powi(2) * g_var + (one_se / n).powi(2)).sqrt();
        let z = (emp - expect) / se.hypot(expect_se);
        eprintln!(
            "t = {:.4}: g2 of sequences {emp:.4} +- {se:.4}; 1 + |g1|^2 = {:.4} +- {:.4}, plus \
             the finite-N term (g2_1 - 1 - |g1|^2) / N = {finite:+.4} (g2_1 = {one:.2} +- \
             {one_se:.2}): {expect:.4}; z = {z:+.2}",
            m as f64 * d.dt,
            1.0 + g,
            g_var.sqrt()
        );
        max_z = max_z.max(z.abs());
        assert!(z.abs() < Z, "lag {m}: {emp} +- {se} vs {expect}: z = {z}");
    }
    // The test resolves the decorrelation: |g1|^2 falls well below 1 over the lags.
    let (g, _) = g1_sq(&d.corr, 2 * (lags - 1), 0);
    assert!(g < 0.6, "|g1|^2 at the last lag is {g}");
    eprintln!("max |z| over {lags} lags: {max_z:.2}");
}

/// Speckle contrast: the contrast `K^2 = Var(S) / <S>^2` of the intensity `S` integrated over
/// the exposure `T = 16 dt` (the mean of the 16 midpoint frames), averaged over the four
/// sensors, equals `(1 - 1/N) K(T)^2 + K_1^2 / N`, with `K_j(T)` of
/// `speckle_motion::correlation::contrast` applied to `|g1_j|^2` of `render_correlation` at the
/// 33 lags `m dt / 2` and `K_1^2` the contrast of single-path sequences (see [`Dynamic`]),
/// within 4.5 combined standard errors. The midpoint rule's own bias,
/// `(1/M^2) sum_ab |g1(t_a - t_b)|^2` against the integral, is evaluated from the rendered `g1`
/// and asserted to be below half a standard error; the render's SE of `K^2` is propagated from
/// the SEs of `|g1|^2` (conservatively, as if fully correlated over lags).
#[test]
fn contrast_of_integrated_sequences_matches_k_of_t() {
    let d = dynamic_cached();
    let j = d.seq.pairs();
    let n = N_PATHS as f64;
    let exposure = FRAMES as f64 * d.dt;
    let (emp, se) = contrast_of(&d.seq);
    let (one, one_se) = contrast_of(&d.single);
    let mut gauss = 0.0;
    let mut gauss_se = 0.0;
    let mut discrete = 0.0;
    for p in 0..j {
        let (g, gse): (Vec<f64>, Vec<f64>) =
            (0..d.corr.lags.len()).map(|l| g1_sq(&d.corr, l, p)).unzip();
        let k = correlation::contrast(&d.corr.lags, &g, exposure, 1.0).unwrap();
        let hi: Vec<f64> = g.iter().zip(&gse).map(|(g, s)| g + s).collect();
        let k_hi = correlation::contrast(&d.corr.lags, &hi, exposure, 1.0).unwrap();
        gauss += k * k / j as f64;
        gauss_se += (k_hi * k_hi - k * k) / j as f64;
        // The midpoint rule on the rendered |g1|^2 (frames a, b are |a - b| dt apart, the
        // render's lag 2 |a - b|).
        let sum: f64 = (0..FRAMES)
            .flat_map(|a| (0..FRAMES).map(move |b| a.abs_diff(b)))
            .map(|m| g[2 * m])
            .sum();
        discrete += sum / (FRAMES * FRAMES) as f64 / j as f64;
    }
    let expect = (1.0 - 1.0 / n) * gauss + one / n;
    let expect_se = ((1.0 - 1.0 / n) * gauss_se).hypot(one_se / n);
    let z = (emp - expect) / se.hypot(expect_se);
    eprintln!(
        "K^2 (T = {exposure}) of sequences {emp:.4} +- {se:.4}; K(T)^2 from g1 {gauss:.4} +- \
         {gauss_se:.4}, single-path K_1^2 = {one:.3} +- {one_se:.3}: expected {expect:.4} \
         (finite-N term {:+.4}); z = {z:+.2}; the 16-frame midpoint sum of the same g1 gives \
         {discrete:.4}",
        expect - gauss
    );
    assert!(
        (discrete - gauss).abs() < 0.5 * se,
        "the midpoint rule's bias {} is not small against the SE {se}",
        discrete - gauss
    );
    assert!(z.abs() < Z, "K^2: {emp} +- {se} vs {expect}: z = {z}");
    // A frozen speckle would give K^2 = 1, a fully averaged one 1 / 16: the exposure resolves
    // the decorrelation.
    assert!(gauss < 0.8 && gauss > 0.2, "K^2 = {gauss}");
}

fn bits(z: &[Complex64]) -> Vec<(u64, u64)> {
    z.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// Without motion every frame of a sequence is bitwise the static `render_fields` realization
/// (same options, speckle mean added); with motion (diffusion and a drift) the frame at time 0
/// still is, later frames are not; and the same seed gives bitwise the same sequences on 1 and
/// 3 threads. Mixed point and far-field endpoints, forward and reversed paths.
#[test]
fn zero_motion_and_time_zero_are_the_static_fields_bitwise() {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap();
    let medium = HomogeneousBox::from_mean_free_path(b, 1.0, 0.9).unwrap();
    let scene = Scene::new(
        medium,
        Phase::hg(0.5).unwrap(),
        0.5,
        vec![
            Source::plane_wave(DVec3::Z).unwrap(),
            Source::Point {
                position: DVec3::new(0.3, 0.0, -3.0),
            },
        ],
        vec![
            Sensor::far_field(tilted(0.2)).unwrap(),
            Sensor::Point {
                position: DVec3::new(0.0, 0.5, 3.0),
            },
            Sensor::far_field(tilted(-0.1)).unwrap(),
        ],
        Pair::all(2, 3),
    )
    .unwrap();
    let opts = FieldOptions {
        realizations: 5,
        paths_per_realization: 700,
        seed: 9,
        coherence: Coherence::ForwardAndReversed,
        add_mean: true,
        ..Default::default()
    };
    let fields = render_fields(&scene, &opts, &NoProgress).unwrap();
    let times = [0.0, 0.7, 2.0, 0.0];
    let j = scene.len();
    let rest =
        render_field_sequence(&scene, &MotionModel::at_rest(), &times, &opts, &NoProgress).unwrap();
    assert_eq!(rest.mean, fields.mean);
    for r in 0..opts.realizations {
        let row = &fields.fields.as_slice()[r * j..(r + 1) * j];
        for l in 0..times.len() {
            assert_eq!(
                bits(rest.frame(r, l)),
                bits(row),
                "realization {r}, frame {l}"
            );
        }
    }
    let moving = MotionModel::uniform(Motion::new(1e-3, DVec3::new(0.2, -0.1, 0.05)).unwrap());
    let seq = |threads| {
        in_pool(threads, || {
            render_field_sequence(&scene, &moving, &times, &opts, &NoProgress).unwrap()
        })
    };
    let (one, three) = (seq(1), seq(3));
    assert_eq!(bits(one.fields.as_slice()), bits(three.fields.as_slice()));
    for r in 0..opts.realizations {
        let row = &fields.fields.as_slice()[r * j..(r + 1) * j];
        assert_eq!(bits(one.frame(r, 0)), bits(row), "realization {r}, time 0");
        assert_eq!(
            bits(one.frame(r, 3)),
            bits(row),
            "realization {r}, time 0 again"
        );
        assert_ne!(
            bits(one.frame(r, 1)),
            bits(row),
            "realization {r}, time 0.7"
        );
    }
}

/// Bad inputs are refused with an error naming the field, before anything large is allocated.
#[test]
fn bad_sequence_inputs_name_the_field() {
    let scene = slab(1.0, &[0.0], &[0.2]);
    let opts = FieldOptions {
        realizations: 2,
        paths_per_realization: 10,
        ..Default::default()
    };
    let model = brownian(1e-3);
    let err = |times: &[f64], model: &MotionModel, opts: &FieldOptions| {
        render_field_sequence(&scene, model, times, opts, &NoProgress)
            .unwrap_err()
            .to_string()
    };
    assert!(err(&[], &model, &opts).starts_with("times:"));
    assert!(err(&[0.0, f64::NAN], &model, &opts).starts_with("times[1]:"));
    assert!(err(&[0.0, -1.0], &model, &opts).starts_with("times[1]:"));
    assert!(err(&[f64::INFINITY], &model, &opts).starts_with("times[0]:"));
    let many = vec![0.0; 5000];
    assert!(err(&many, &model, &opts).starts_with("times:"));
    // 2^40 realizations of 2 times: refused before any allocation.
    let huge = FieldOptions {
        realizations: 1 << 40,
        ..opts
    };
    assert!(err(&[0.0, 1.0], &model, &huge).starts_with("times:"));
    let two = MotionModel::per_material(vec![Motion::STATIC, Motion::STATIC]).unwrap();
    assert!(err(&[0.0], &two, &opts).starts_with("motion.materials:"));
    let none = FieldOptions {
        realizations: 0,
        ..opts
    };
    assert!(err(&[0.0], &model, &none).starts_with("realizations:"));
    // Gaussian beams: taken with vMF-lobed amplitudes only (their closed-form connections).
    let b = speckle::endpoints::GaussianBeam::new("source", DVec3::ZERO, DVec3::Z, 16.0).unwrap();
    let beams = Scene::new(
        scene.medium().clone(),
        Phase::hg(0.5).unwrap(),
        1.0,
        vec![Source::GaussianBeam(b)],
        scene.sensors().to_vec(),
        Pair::all(1, scene.sensors().len()),
    )
    .unwrap();
    let e = render_field_sequence(&beams, &model, &[0.0], &opts, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("sources[0]: ") && e.contains("phase"), "{e}");
}
