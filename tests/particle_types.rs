//! Media of several particle types (Bar et al. 2019, App. A.1, Alg. 3 and Alg. 4).
//!
//! Every vertex draws the type of its particle with probability `beta_iota`; the next-event
//! amplitudes at `x1` and `x_B` are those of the drawn types, and paths leave a vertex along the
//! drawn type's phase function. Checks, each against an independent computation:
//!
//! - two types with the same amplitude give the single-type covariance (coherent backscattering
//!   included), entry by entry;
//! - the forward-only intensity of two different types equals the intensity of one type whose
//!   phase function is the bulk `rho = sum beta |s_iota|^2` (an [`HgMixture`], rendered by the
//!   single-type path): intensities see only `|s|^2`, while the test has the power to see the
//!   difference from either type alone;
//! - single scattering of two types is `sum beta_iota C_iota` of the single-type renders, as
//!   `Upsilon` of Eq. 50 is linear in the types (off-diagonal memory-effect entries included,
//!   where `s_1(theta_1) s_1(theta_2)^*` differs from `sqrt(rho(theta_1) rho(theta_2))`);
//! - the empirical covariance of two-type fields (Alg. 4) equals the two-type covariance
//!   (Alg. 3), entry by entry.
//!
//! Tolerances: 4.5 combined standard errors per real or imaginary part (a few hundred statistics
//! per test; fixed seeds). Run time (release, 2 cores): about 10 s.

mod common_b;

use common_b::tilted;
use speckle::estimators::{
    Coherence, CovarianceOptions, FieldOptions, MatrixEstimate, NoProgress, Pair, Scene, Sensor,
    Source, render_covariance, render_fields, render_intensity, render_single_scattering,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::{HgMixture, Phase};
use speckle::stats::empirical_moments;
use std::sync::Arc;

const Z_MAX: f64 = 4.5;
const LAMBDA: f64 = 0.1;
const BETA: [f64; 2] = [0.4, 0.6];
const G: [f64; 2] = [0.8, -0.3];

fn slab() -> Aabb {
    Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap()
}

/// Mean free path 1, albedo 0.9.
const SIGMA_S: f64 = 0.9;
const SIGMA_A: f64 = 0.1;

/// Two plane waves (normal, and tilted by `delta = lambda / (2 W)`) and four far-field sensors
/// `0.2 + n delta` rad off the axis in transmission, `J = 8`, as in `tests/fields.rs`.
fn memory_endpoints() -> (Vec<Source>, Vec<Sensor>, Vec<Pair>) {
    let delta = 0.5 * LAMBDA / 4.0;
    let sources = (0..2)
        .map(|m| Source::plane_wave(tilted(f64::from(m) * delta)).unwrap())
        .collect();
    let sensors = (0..4)
        .map(|n| Sensor::far_field(tilted(0.2 + f64::from(n) * delta)).unwrap())
        .collect();
    (sources, sensors, Pair::all(2, 4))
}

fn typed_scene(
    phases: Vec<Phase>,
    ends: (Vec<Source>, Vec<Sensor>, Vec<Pair>),
) -> Scene<HomogeneousBox, Phase> {
    let m = HomogeneousBox::with_types(slab(), SIGMA_S, SIGMA_A, BETA.to_vec()).unwrap();
    Scene::with_types(m, phases, LAMBDA, ends.0, ends.1, ends.2).unwrap()
}

fn single_scene(
    phase: Phase,
    ends: (Vec<Source>, Vec<Sensor>, Vec<Pair>),
) -> Scene<HomogeneousBox, Phase> {
    let m = HomogeneousBox::new(slab(), SIGMA_S, SIGMA_A).unwrap();
    Scene::new(m, phase, LAMBDA, ends.0, ends.1, ends.2).unwrap()
}

fn two_types() -> Vec<Phase> {
    G.iter().map(|&g| Phase::hg(g).unwrap()).collect()
}

fn options(paths: u64, seed: u64, coherence: Coherence) -> CovarianceOptions {
    CovarianceOptions {
        paths,
        seed,
        coherence,
        ..Default::default()
    }
}

/// The largest `|z|` over the real and imaginary parts of all upper-triangle entries of two
/// independent estimates (of equal shape), printing each.
fn max_z(what: &str, a: &MatrixEstimate, b: &MatrixEstimate) -> f64 {
    let (rows, cols) = (a.value.rows(), a.value.cols());
    let mut worst: f64 = 0.0;
    for r in 0..rows {
        for c in (if cols == 1 { 0 } else { r })..cols {
            let ((va, sa), (vb, sb)) = (a.get(r, c), b.get(r, c));
            let zr = (va.re - vb.re) / sa.re.hypot(sb.re);
            let zi = if sa.im.hypot(sb.im) > 0.0 {
                (va.im - vb.im) / sa.im.hypot(sb.im)
            } else {
                0.0
            };
            eprintln!("{what} [{r},{c}]: {va:.5} vs {vb:.5}: z = ({zr:+.2}, {zi:+.2})");
            worst = worst.max(zr.abs()).max(zi.abs());
        }
    }
    eprintln!("{what}: max |z| = {worst:.2}");
    worst
}

/// Two types with the same amplitude (HG 0.5, beta 0.4 / 0.6) and one type: the same covariance,
/// forward and reversed paths included, within 4.5 SE per entry (36 entries, 400k paths each).
#[test]
fn equal_types_give_the_single_type_covariance() {
    let hg = Phase::hg(0.5).unwrap();
    let typed = typed_scene(vec![hg.clone(), hg.clone()], memory_endpoints());
    let single = single_scene(hg, memory_endpoints());
    let o = |seed| options(400_000, seed, Coherence::ForwardAndReversed);
    let a = render_covariance(&typed, &o(1), &NoProgress).unwrap();
    let b = render_covariance(&single, &o(2), &NoProgress).unwrap();
    assert!(max_z("equal types", &a.total, &b.total) < Z_MAX);
}

/// Sensors over the full circle in the x-z plane (transmission and reflection), one source.
fn circle_endpoints() -> (Vec<Source>, Vec<Sensor>, Vec<Pair>) {
    let sensors: Vec<Sensor> = (0..18)
        .map(|d| {
            let t = (5.0 + 10.0 * f64::from(d)).to_radians();
            Sensor::far_field(DVec3::new(t.sin(), 0.0, t.cos())).unwrap()
        })
        .collect();
    let n = sensors.len();
    (
        vec![Source::plane_wave(tilted(0.1)).unwrap()],
        sensors,
        Pair::all(1, n),
    )
}

/// Forward-only intensities of two different types (HG 0.8 with beta 0.4, HG -0.3 with beta 0.6)
/// equal those of one type with the bulk phase function `0.4 HG(0.8) + 0.6 HG(-0.3)`, at 18
/// angles from 5 to 175 degrees, within 4.5 SE; and the test can fail: the intensities of
/// HG(0.8) alone differ from them by many SE.
#[test]
fn intensity_of_two_types_is_that_of_the_bulk_phase_function() {
    let o = |seed| options(400_000, seed, Coherence::ForwardOnly);
    let typed = typed_scene(two_types(), circle_endpoints());
    let lobes = [(BETA[0], G[0]), (BETA[1], G[1])];
    let bulk = Phase::HgMixture(Arc::new(HgMixture::new(&lobes).unwrap()));
    let a = render_intensity(&typed, &o(3), &NoProgress).unwrap();
    let b = render_intensity(&single_scene(bulk, circle_endpoints()), &o(4), &NoProgress).unwrap();
    assert!(max_z("typed vs bulk", &a.total, &b.total) < Z_MAX);
    let one = single_scene(Phase::hg(G[0]).unwrap(), circle_endpoints());
    let c = render_intensity(&one, &o(5), &NoProgress).unwrap();
    let z = max_z("typed vs HG(0.8) alone (must differ)", &a.total, &c.total);
    assert!(z > 10.0, "the check has no power: max z {z}");
}

/// Single scattering (Eq. 41 with Eq. 50's Upsilon) of two types is `0.4 C(HG 0.8) +
/// 0.6 C(HG -0.3)` of two single-type renders, for every entry of the memory-effect covariance
/// (36 entries), within 4.5 SE.
#[test]
fn single_scattering_of_two_types_is_the_beta_weighted_sum() {
    let o = |seed| options(400_000, seed, Coherence::ForwardAndReversed);
    let typed = typed_scene(two_types(), memory_endpoints());
    let a = render_single_scattering(&typed, &o(6), &NoProgress).unwrap();
    let parts: Vec<MatrixEstimate> = G
        .iter()
        .zip([7, 8])
        .map(|(&g, seed)| {
            let s = single_scene(Phase::hg(g).unwrap(), memory_endpoints());
            render_single_scattering(&s, &o(seed), &NoProgress).unwrap()
        })
        .collect();
    let mut sum = parts[0].clone();
    for r in 0..sum.value.rows() {
        for c in 0..sum.value.cols() {
            let v = BETA[0] * parts[0].value.get(r, c) + BETA[1] * parts[1].value.get(r, c);
            let (s0, s1) = (parts[0].std_error.get(r, c), parts[1].std_error.get(r, c));
            let se = speckle::phase::Complex64::new(
                (BETA[0] * s0.re).hypot(BETA[1] * s1.re),
                (BETA[0] * s0.im).hypot(BETA[1] * s1.im),
            );
            let at = r * sum.value.cols() + c;
            sum.value.as_mut_slice()[at] = v;
            sum.std_error.as_mut_slice()[at] = se;
        }
    }
    assert!(max_z("single scattering", &a, &sum) < Z_MAX);
}

/// Alg. 4 against Alg. 3: the empirical covariance of 8000 two-type field realizations
/// (500 sub-paths each) equals the two-type covariance render (1 M paths), 36 entries, within
/// 4.5 combined SE.
#[test]
fn two_type_fields_have_the_two_type_covariance() {
    let typed = typed_scene(two_types(), memory_endpoints());
    let cov = render_covariance(
        &typed,
        &options(1_000_000, 9, Coherence::ForwardAndReversed),
        &NoProgress,
    )
    .unwrap();
    let fields = render_fields(
        &typed,
        &FieldOptions {
            realizations: 8000,
            paths_per_realization: 500,
            seed: 10,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    let m = empirical_moments(&fields.fields).unwrap();
    assert!(max_z("fields vs covariance", &m.covariance, &cov.total) < Z_MAX);
}
