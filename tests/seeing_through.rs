//! Seeing through scattering (`speckle::studies::seeing`; Katz et al. 2014, Bar et al. 2019
//! Fig. 13).
//!
//! 1. The illuminators' patterns in the study's sampled images (Alg. 2, `render_fields`) are as
//!    correlated as the covariance (Alg. 1, `render_covariance`, an independent estimator)
//!    says: for cells 2.5 to 10 mdeg apart along x behind the 1 mm slab of Fig. 10c at
//!    `g = 0.9`, the Pearson correlation of `|u_0(v)|^2` and `|u_p(v + theta_p)|^2` over the
//!    image against `|C[(i_0, v), (i_p, v + theta_p)]|^2 / (C_00 C_pp)` (Gaussian speckle),
//!    averaged over 16 directions, within 4.5 combined standard errors. Measured: 0.43-1.00 SE
//!    (0.954, 0.864, 0.778, 0.702 against 0.953, 0.859, 0.770, 0.690).
//! 2. Phase retrieval of the shipped object (an F of 13 cells spanning 12.5 mdeg) recovers it
//!    where the object lies within the memory-effect range (`g = 0.97`, pattern correlation
//!    0.978 across the object: similarity 0.989) and not outside (`g = 0.7`, correlation 0.123:
//!    similarity 0.613), while the retrieval itself, given the autocorrelation a perfect memory
//!    effect would give with the same speckle, recovers it in both (0.995, 0.998).
//!
//! Run time: about 25 s on two cores (release).

use speckle::estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, render_covariance,
};
use speckle::medium::DVec3;
use speckle::paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle::stats::rng::derive_seed;
use speckle::studies::memory::StudyOverrides;
use speckle::studies::seeing::load_seeing_str;

const SLAB: &str = r#"
wavelength_um = 0.5
thickness_um = 1000.0
mean_free_path_um = 100.0
width_um = 23000.0
object_step_mdeg = 2.5
pixel_mdeg = 1.25
"#;

fn study(rest: &str) -> speckle::studies::seeing::SeeingStudy {
    load_seeing_str(
        &format!("{SLAB}{rest}"),
        "test",
        "seeing",
        &StudyOverrides::default(),
    )
    .unwrap()
}

#[test]
fn sampled_patterns_are_as_correlated_as_the_covariance_says() {
    let s = study(
        r######"
g = [0.9]
object = ["#####"]
pixels = 32
realizations = 16
window = 20
[render]
paths = 4000
seed = 3
"######,
    );
    let r = s.render(&NoProgress).unwrap();
    let case = &r.cases[0];
    // Alg. 1 on the same medium, sources and sensors: pairs (i_0, v_q) and (i_p, v_q + 2p
    // pixels) for 16 directions q in the middle rows.
    let scene = s.scene(0.9).unwrap();
    let n = s.file.pixels;
    let qs: Vec<usize> = (0..16)
        .map(|i| (12 + i / 8 * 4) * n + 6 + 2 * (i % 8))
        .collect();
    let np = s.points.len();
    let mut pairs = vec![];
    for &q in &qs {
        for p in 0..np {
            pairs.push(Pair {
                source: p,
                sensor: q + p * s.step,
            });
        }
    }
    let sub = Scene::new(
        scene.medium().clone(),
        scene.phase().clone(),
        scene.wavelength(),
        scene.sources().to_vec(),
        scene.sensors().to_vec(),
        pairs,
    )
    .unwrap();
    let groups = 8;
    let per_group: Vec<Vec<f64>> = (0..groups)
        .map(|g| {
            let o = CovarianceOptions {
                paths: 40_000,
                seed: derive_seed(11, g),
                coherence: Coherence::ForwardOnly,
                sampling: TracerConfig {
                    first_vertex: FirstVertex::ExponentialDepth {
                        direction: DVec3::Z,
                    },
                    first_direction: FirstDirection::Phase { axis: DVec3::Z },
                    ..TracerConfig::default()
                },
            };
            let c = render_covariance(&sub, &o, &NoProgress)
                .unwrap()
                .total
                .value;
            (0..np)
                .map(|p| {
                    qs.iter()
                        .enumerate()
                        .map(|(i, _)| {
                            let (a, b) = (i * np, i * np + p);
                            c.get(a, b).norm_sqr() / (c.get(a, a).re * c.get(b, b).re)
                        })
                        .sum::<f64>()
                        / qs.len() as f64
                })
                .collect()
        })
        .collect();
    for p in 1..np {
        let vals: Vec<f64> = per_group.iter().map(|v| v[p]).collect();
        let k = groups as f64;
        let mean = vals.iter().sum::<f64>() / k;
        let se = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt();
        let (m, m_se) = (case.memory[p], case.memory_stderr[p]);
        let z = (m - mean) / m_se.hypot(se);
        println!(
            "{:.1} mdeg: sampled patterns {m:.4} +- {m_se:.4}, covariance {mean:.4} +- {se:.4}, \
             z = {z:.2}",
            r.separation_mdeg[p]
        );
        assert!(m_se < 0.03 && se < 0.03, "resolved");
        assert!(z.abs() < 4.5, "{z}");
    }
    assert!(
        case.memory[np - 1] < 0.85,
        "the correlation decays: {:?}",
        case.memory
    );
}

#[test]
fn retrieval_sees_through_within_the_memory_effect_range_only() {
    let s = study(
        r######"
g = [0.97, 0.7]
object = ["#####.", "#.....", "####..", "#.....", "#.....", "#....."]
pixels = 64
realizations = 4
window = 24
[render]
paths = 4000
seed = 1
"######,
    );
    let r = s.render(&NoProgress).unwrap();
    for c in &r.cases {
        println!(
            "g = {}: similarity {:.3} (ideal {:.3}), pattern correlation across the object {:.3}",
            c.g,
            c.similarity,
            c.ideal_similarity,
            c.memory.last().unwrap()
        );
        assert!(c.ideal_similarity > 0.95, "the retrieval itself works");
    }
    let (inside, outside) = (&r.cases[0], &r.cases[1]);
    assert!(*inside.memory.last().unwrap() > 0.9 && *outside.memory.last().unwrap() < 0.4);
    assert!(inside.similarity > 0.9, "{}", inside.similarity);
    assert!(outside.similarity < 0.8, "{}", outside.similarity);
}
