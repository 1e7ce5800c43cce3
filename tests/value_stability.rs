//! Value stability: numbers computed once and stored here, never a value compared with itself.
//!
//! Pinned: the first outputs of the random streams and of `derive_seed`, of each direction and
//! cosine sampler, of the tracer's first vertex and of a free flight, and one tiny covariance,
//! field render and wave estimate. A change of any of them is a value-breaking change: every
//! seeded result of the project changes with it. Such a change must be deliberate, recorded in
//! `CHANGELOG.md` (what changed, why, and by how much results move in standard errors), and these
//! numbers regenerated with
//! `SPECKLE_PRINT_PINS=1 cargo test --test value_stability -- --nocapture --test-threads 1`.
//!
//! Tolerances: integers and the samplers' outputs (a handful of floating-point operations of
//! one path) bitwise or to 1e-15 relative; the rendered estimates to 1e-14 of their largest
//! entry, because the rank-K accumulation runs faer's GEMM kernels, which sum in an order that
//! depends on the instruction set the CPU offers (AVX2 or AVX-512), a rounding-level difference.
//! Run time: under a second.

use num_complex::Complex64;
use speckle::endpoints::{Pair, Sensor, Source};
use speckle::estimators::{
    CovarianceOptions, FieldOptions, NoProgress, Scene, render_covariance, render_fields,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox, Medium};
use speckle::paths::{Tracer, TracerConfig};
use speckle::phase::{HgMixture, Phase, PhaseFunction, VmfMixture};
use speckle::stats::PathRng;
use speckle::stats::rng::derive_seed;
use speckle::wave::{WaveOptions, render_wave};
use std::sync::Arc;

fn printing() -> bool {
    std::env::var_os("SPECKLE_PRINT_PINS").is_some()
}

/// Compares `got` with `want` to `tol` relative to `scale` (or prints `got` in print mode).
fn check(name: &str, got: &[f64], want: &[f64], tol: f64) {
    if printing() {
        let list: Vec<String> = got.iter().map(|x| format!("{x:?}")).collect();
        eprintln!("{name}: [{}]", list.join(", "));
        return;
    }
    assert_eq!(got.len(), want.len(), "{name}: length");
    let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tol * scale,
            "{name}[{i}]: {g:?} differs from the pinned {w:?} (a value-breaking change: see \
             the module docs)"
        );
    }
}

fn flat(z: &[Complex64]) -> Vec<f64> {
    z.iter().flat_map(|c| [c.re, c.im]).collect()
}

#[test]
fn random_streams_are_pinned() {
    let mut r = PathRng::new(1, 2);
    let bits: Vec<u64> = (0..3).map(|_| r.next_u64()).collect();
    let mut r = PathRng::new(0xDEAD_BEEF, 1 << 40);
    let uniforms: Vec<f64> = (0..4).map(|_| r.next_f64()).collect();
    let seeds = [derive_seed(1, 0), derive_seed(1, 1), derive_seed(7, 123)];
    if printing() {
        eprintln!("bits: {bits:?}\nseeds: {seeds:?}");
    } else {
        assert_eq!(
            bits,
            [
                10154990248698053839,
                723669816833414966,
                15781932863528943987
            ]
        );
        assert_eq!(
            seeds,
            [
                10451216379200822465,
                13757245211066428519,
                11643247792660730917
            ]
        );
    }
    check(
        "uniforms",
        &uniforms,
        &[
            0.09255467039724496,
            0.31123164197336706,
            0.5740216095648341,
            0.1797440025421685,
        ],
        0.0,
    );
}

#[test]
fn samplers_are_pinned() {
    let u = [0.0, 0.137, 0.5, 0.861, 0.999];
    let incoming = DVec3::new(0.3, -0.2, 0.9).normalize();
    let table = {
        let mu: Vec<f64> = (0..=20).map(|i| -1.0 + 0.1 * i as f64).collect();
        let s = mu
            .iter()
            .map(|&m| Complex64::from_polar(1.0 + m * m, 0.3 * m))
            .collect();
        Phase::Tabulated(Arc::new(
            speckle::phase::TabulatedAmplitude::new(mu, s).unwrap(),
        ))
    };
    let phases = [
        ("isotropic", Phase::Isotropic),
        ("hg", Phase::hg(0.6).unwrap()),
        (
            "hg_mixture",
            Phase::HgMixture(Arc::new(
                HgMixture::new(&[(0.4, 0.8), (0.6, -0.3)]).unwrap(),
            )),
        ),
        ("table", table),
        (
            "vmf",
            Phase::Vmf(Arc::new(
                VmfMixture::new(vec![(0.0, 1.0), (25.0, 3.0), (-4.0, 0.5)]).unwrap(),
            )),
        ),
        ("flat_hg", Phase::flat_hg(0.5).unwrap()),
    ];
    let mut got = Vec::new();
    for (name, p) in &phases {
        let inc = if p.dimension() == speckle::phase::Dimension::Two {
            DVec3::new(0.6, 0.8, 0.0)
        } else {
            incoming
        };
        let mut values = Vec::new();
        for (i, &x) in u.iter().enumerate() {
            let d = p.sample_direction(inc, [x, u[(i + 2) % u.len()]]);
            values.extend([d.x, d.y, d.z]);
        }
        got.push((name, values));
    }
    let want: [&[f64]; 6] = [
        &[
            0.309426373877638,
            -0.20628424925175867,
            0.9282791216329139,
            0.6269384327723062,
            -0.6506229696840239,
            0.4285299905870602,
            0.950120340890764,
            0.026956802678023212,
            -0.31071637970180505,
            0.43413270576702745,
            0.17184023303529355,
            -0.8843074850377415,
            -0.26806162613712253,
            0.2541167598478837,
            -0.9292833996995397,
        ],
        &[
            -0.3094263939047052,
            0.2062842485541873,
            -0.9282791151122405,
            0.6029955693733976,
            -0.7396748768114441,
            -0.29879327289955354,
            0.8251341932242616,
            -0.14691942888295917,
            0.545498161856529,
            0.5408177043878573,
            -0.19109592964855968,
            0.8191450154230329,
            0.3222624605565219,
            -0.1909710507136525,
            0.9271876640170421,
        ],
        &[
            -0.3094264055432116,
            0.20628424814880147,
            -0.9282791113228237,
            0.5499728969891269,
            -0.5272002920198777,
            0.6477574119001208,
            0.22212835416569948,
            0.19087332240909752,
            -0.9561518546068664,
            0.9850026401428932,
            0.003048346673314096,
            -0.1725123372228467,
            0.3884647602730059,
            -0.10810034642689245,
            0.9151007841371472,
        ],
        &[
            -0.309426373877638,
            0.20628424925175867,
            -0.9282791216329139,
            0.042210637301385856,
            -0.20508190619994224,
            -0.9778341750256065,
            0.950120340890764,
            0.026956802678023212,
            -0.31071637970180505,
            0.7638467951686005,
            -0.15785993662374667,
            0.6257941466007847,
            0.3370399311909075,
            -0.1730516372494984,
            0.9254497369539288,
        ],
        &[
            -0.309426373877638,
            0.20628424925175867,
            -0.9282791216329139,
            0.4685586861995069,
            -0.412406662797043,
            0.7812640411970833,
            0.46612107603501335,
            -0.19872135825678555,
            0.862114240833858,
            0.3822736377438857,
            -0.2030917316327319,
            0.9014547212303425,
            0.117207848171276,
            0.6074257803058549,
            -0.7856820233064278,
        ],
        &[
            -0.5999999999999995,
            -0.8000000000000004,
            0.0,
            0.9464623452439618,
            -0.3228142330122697,
            0.0,
            0.6,
            0.8,
            0.0,
            -0.5620514770709443,
            0.8271022531237415,
            0.0,
            -0.6149717720206351,
            -0.7885491231482031,
            0.0,
        ],
    ];
    for ((name, values), w) in got.iter().zip(want) {
        check(name, values, w, 1e-15);
    }
}

/// A 6 x 4 x 3 box, sigma_s 0.4, sigma_a 0.1, HG 0.5, wavelength 1.
fn tiny() -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(6.0, 4.0, 3.0)).unwrap();
    let m = HomogeneousBox::new(b, 0.4, 0.1).unwrap();
    Scene::new(
        m,
        Phase::hg(0.5).unwrap(),
        1.0,
        vec![
            Source::plane_wave(DVec3::new(0.1, 0.0, 1.0)).unwrap(),
            Source::point(DVec3::new(0.5, -0.3, -5.0)),
        ],
        vec![
            Sensor::far_field(DVec3::new(0.0, 0.2, 1.0)).unwrap(),
            Sensor::point(DVec3::new(-0.4, 0.2, 4.0)),
        ],
        Pair::all(2, 2),
    )
    .unwrap()
}

#[test]
fn tracer_and_flights_are_pinned() {
    let s = tiny();
    let t = Tracer::with_types(s.medium(), s.phases(), TracerConfig::default()).unwrap();
    let mut rng = PathRng::new(11, 3);
    let (x1, ty, w) = t.sample_first_vertex(&mut rng).unwrap();
    let flight = s
        .medium()
        .sample_flight(x1, DVec3::Z, &mut || rng.next_f64())
        .unwrap_or(-1.0);
    check(
        "first vertex, weight, flight",
        &[x1.x, x1.y, x1.z, ty as f64, w, flight],
        &[
            -2.938282383754055,
            1.953477645426064,
            -1.4070019301781835,
            0.0,
            28.8,
            0.07422763837939034,
        ],
        1e-15,
    );
}

#[test]
fn tiny_renders_are_pinned() {
    let s = tiny();
    let opts = CovarianceOptions {
        paths: 300,
        seed: 5,
        ..Default::default()
    };
    let c = render_covariance(&s, &opts, &NoProgress).unwrap();
    check(
        "covariance",
        &flat(c.total.value.as_slice()),
        &[
            3.6438976660207953,
            -0.0,
            0.027701753310631717,
            -0.13054872823993427,
            0.10403928675609474,
            -0.14604365649724446,
            0.0034459609018990508,
            -0.022530510546496827,
            0.027701753310631717,
            0.13054872823993427,
            0.1445055912953883,
            -0.0,
            0.007770188015803775,
            -0.0024225672969970355,
            0.004981282411213208,
            -0.006284479301449167,
            0.10403928675609474,
            0.14604365649724446,
            0.007770188015803775,
            0.0024225672969970355,
            0.10291142438378012,
            -0.0,
            0.0018844964614533391,
            -0.0051319977586662775,
            0.0034459609018990508,
            0.022530510546496827,
            0.004981282411213208,
            0.006284479301449167,
            0.0018844964614533391,
            0.0051319977586662775,
            0.0034112871755447097,
            -0.0,
        ],
        1e-14,
    );
    check(
        "covariance standard errors",
        &flat(c.total.std_error.as_slice()),
        &[
            0.14702805980154166,
            0.0,
            0.03759325835465999,
            0.03364468807066002,
            0.03244066374211343,
            0.030403619478331784,
            0.004794901617579947,
            0.006802681974617152,
            0.03759325835465999,
            0.03364468807066002,
            0.009218432764807738,
            0.0,
            0.004776489363671931,
            0.006141382318803087,
            0.0013464378423370723,
            0.0014146133818829147,
            0.03244066374211343,
            0.030403619478331784,
            0.004776489363671931,
            0.006141382318803087,
            0.006933049899266402,
            0.0,
            0.0011125551402891027,
            0.001192608679101759,
            0.004794901617579947,
            0.006802681974617152,
            0.0013464378423370723,
            0.0014146133818829147,
            0.0011125551402891027,
            0.001192608679101759,
            0.0003587722186549819,
            0.0,
        ],
        1e-13,
    );
    let f = render_fields(
        &s,
        &FieldOptions {
            realizations: 2,
            paths_per_realization: 40,
            seed: 6,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    check(
        "fields",
        &flat(f.fields.as_slice()),
        &[
            1.3339796944774076,
            3.4962996159765147,
            0.4415299074099885,
            0.18438753763708193,
            0.5851056785012312,
            -0.08091836785368588,
            0.027006099993938826,
            0.017801343367656156,
            0.979854894994,
            -0.4339700854881978,
            0.24491003678691928,
            -0.6987416668435402,
            0.8046689395966937,
            -0.481186005256365,
            0.1524647293129372,
            -0.04690443238387976,
        ],
        1e-14,
    );

    // The wave solver: a lossless isotropic flatland box of about 10 scatterers.
    let b = Aabb::flat(glam::DVec2::new(-3.0, -1.5), glam::DVec2::new(3.0, 1.5)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 3.0, 1.0).unwrap();
    let w = Scene::new(
        m,
        Phase::FlatIsotropic,
        1.0,
        vec![Source::plane_wave(DVec3::Y).unwrap()],
        vec![
            Sensor::far_field(DVec3::new(0.3, 1.0, 0.0)).unwrap(),
            Sensor::point(DVec3::new(0.0, 3.0, 0.0)),
        ],
        Pair::all(1, 2),
    )
    .unwrap();
    let e = render_wave(
        &w,
        &WaveOptions {
            configurations: 3,
            seed: 4,
        },
        &NoProgress,
    )
    .unwrap();
    check(
        "wave fields",
        &flat(e.fields.as_slice()),
        &[
            -0.1580430321115655,
            -0.047865276926693845,
            0.9267605792748126,
            0.2135154153067702,
            0.6750431496120636,
            -0.5523847626475744,
            0.42735139605415284,
            0.04334326476022826,
            0.8467286341681902,
            -0.10340409560218466,
            1.0777268672361653,
            0.3860432824961402,
        ],
        1e-14,
    );
}
