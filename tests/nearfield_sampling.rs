//! Importance sampling around focused Gaussian beams (Bar et al. 2020, Sec. 6; issue 11, Build
//! 4; `speckle::paths::Tracer::with_endpoints`): first vertices from the beams' Gaussian
//! structure (Eqs. 33-36) and first directions from the vMF pair mixture of `|Upsilon|^2`
//! (Eq. 41), mixed with the volume strategy and the phase function, weighed by the exact
//! density of the whole mixture in both orders of every path.
//!
//! Each scene is rendered with the beam strategy (`BeamStrategy::PositionAndDirection`, the
//! default), with beam positions only (`Position`), and with uniform first vertices and
//! directions (`Off`, the estimator of Bar et al. 2019), on independent seeds: every entry of the
//! near-field covariance (real and imaginary parts) must agree within 4 combined standard
//! errors, and the least resolved diagonal entry of the beam render must be resolved to a few
//! percent (so that the comparison is not vacuous). A wrong density in the mixture, in either
//! order, is a bias this test sees. The variance-times-time gain over uniform sampling,
//! `(se_off^2 t_off) / (se^2 t)` of the median diagonal entry, is printed per scene (speed is
//! reported, never asserted).
//!
//! Scenes: a small 3D box with an HG-like vMF amplitude (two sources, two transmission sensors
//! and one in reflection, the memory-effect geometry); a flatland box with isotropic scattering
//! (beam positions only: the direction mixture is 3D); and a wide thin slab lit by narrow
//! beams with a forward vMF amplitude, where the beams cover a small fraction of the medium and
//! most uniform first directions carry almost nothing (notes Sec. 7.4, Fig. 9's bottom panel).

mod common_z;
use common_z::max_z;

use speckle::endpoints::GaussianBeam;
use speckle::estimators::{
    Coherence, CovarianceEstimate, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source,
    render_covariance,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{BeamStrategy, TracerConfig};
use speckle::phase::{Dimension, Phase};
use speckle::vmf::VmfMixture;
use std::sync::Arc;
use std::time::Instant;

struct Case {
    name: &'static str,
    dimension: Dimension,
    /// Box (lateral, depth), centred on the origin.
    size: (f64, f64),
    mean_free_path: f64,
    gamma: f64,
    phase: Phase,
    /// Whether a sensor looks back at the first source's focus (reflection).
    reflection: bool,
    /// Paths of the uniform render and of the beam renders.
    paths: (u64, u64),
}

fn scene(c: &Case) -> Scene<HomogeneousBox, Phase> {
    let (lat, depth) = c.size;
    let (bounds, axis) = match c.dimension {
        Dimension::Two => (
            Aabb::flat(
                glam::DVec2::new(-0.5 * lat, -0.5 * depth),
                glam::DVec2::new(0.5 * lat, 0.5 * depth),
            )
            .unwrap(),
            DVec3::Y,
        ),
        Dimension::Three => (
            Aabb::centered(DVec3::ZERO, DVec3::new(lat, lat, depth)).unwrap(),
            DVec3::Z,
        ),
    };
    let medium = HomogeneousBox::from_mean_free_path(bounds, c.mean_free_path, 1.0).unwrap();
    // Sources focused on the entry face, sensors on the exit face (transmission) and one on the
    // entry face looking back (reflection).
    let at = |x: f64, d: f64| DVec3::X * x + axis * d;
    let beam = |field: &str, f: DVec3, a: DVec3| GaussianBeam::new(field, f, a, c.gamma).unwrap();
    let h = 0.5 * depth;
    let sources = vec![
        Source::GaussianBeam(beam("source", at(0.0, -h), axis)),
        Source::GaussianBeam(beam("source", at(1.0, -h), axis)),
    ];
    let mut sensors = vec![
        Sensor::GaussianBeam(beam("sensor", at(0.0, h), axis)),
        Sensor::GaussianBeam(beam("sensor", at(1.0, h), axis)),
    ];
    if c.reflection {
        sensors.push(Sensor::GaussianBeam(beam("sensor", at(0.0, -h), -axis)));
    }
    let pairs = Pair::all(2, sensors.len());
    Scene::new(medium, c.phase.clone(), 1.0, sources, sensors, pairs).unwrap()
}

fn render(
    s: &Scene<HomogeneousBox, Phase>,
    beams: BeamStrategy,
    paths: u64,
    seed: u64,
) -> (CovarianceEstimate, f64) {
    let opts = CovarianceOptions {
        paths,
        seed,
        coherence: Coherence::ForwardAndReversed,
        sampling: TracerConfig {
            beams,
            ..TracerConfig::default()
        },
    };
    let t0 = Instant::now();
    let c = render_covariance(s, &opts, &NoProgress).unwrap();
    (c, t0.elapsed().as_secs_f64())
}

/// The relative standard errors of the diagonal entries, sorted.
fn relative_ses(c: &CovarianceEstimate) -> Vec<f64> {
    let mut r: Vec<f64> = (0..c.total.value.rows())
        .map(|i| {
            let (v, s) = c.total.get(i, i);
            s.re / v.re
        })
        .collect();
    r.sort_by(f64::total_cmp);
    r
}

/// Variance times time, uniform over `on`, of each diagonal entry: the smallest and the median.
fn gain(off: &(CovarianceEstimate, f64), on: &(CovarianceEstimate, f64)) -> (f64, f64) {
    let n = off.0.total.value.rows();
    let mut g: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (off.0.total.get(i, i).1.re, on.0.total.get(i, i).1.re);
            (a * a * off.1) / (b * b * on.1)
        })
        .collect();
    g.sort_by(f64::total_cmp);
    (g[0], g[n / 2])
}

/// Renders `c` three ways and checks agreement; returns the (smallest, median) gains of
/// positions only and of positions and directions.
fn compare(c: &Case, seed: u64) -> ((f64, f64), (f64, f64)) {
    let s = scene(c);
    let off = render(&s, BeamStrategy::Off, c.paths.0, seed);
    let pos = render(&s, BeamStrategy::Position, c.paths.1, seed + 1);
    let both = render(&s, BeamStrategy::PositionAndDirection, c.paths.1, seed + 2);
    let (z_pos, z_both) = (max_z(&off.0, &pos.0), max_z(&off.0, &both.0));
    let (g_pos, g_both) = (gain(&off, &pos), gain(&off, &both));
    let worst = |c: &CovarianceEstimate| *relative_ses(c).last().unwrap();
    println!(
        "{}: max z uniform vs beam positions {z_pos:.2}, vs positions and directions \
         {z_both:.2}; worst relative SE: uniform {:.4} ({} paths, {:.2} s), positions {:.4}, \
         both {:.4} ({} paths, {:.2} s, {:.2} s); variance x time gain over uniform: positions \
         {:.1} (median {:.1}), positions and directions {:.1} (median {:.1})",
        c.name,
        worst(&off.0),
        c.paths.0,
        off.1,
        worst(&pos.0),
        worst(&both.0),
        c.paths.1,
        pos.1,
        both.1,
        g_pos.0,
        g_pos.1,
        g_both.0,
        g_both.1
    );
    // The default strategy must resolve every entry (positions alone, with uniform first
    // directions at beam vertices, has heavier tails in reflection: printed, not asserted).
    assert!(
        worst(&both.0) < 0.05,
        "{}: the beam render is not resolved",
        c.name
    );
    assert!(z_pos < 4.0, "{}: positions disagree, z {z_pos}", c.name);
    assert!(
        z_both < 4.0,
        "{}: the beam strategy disagrees, z {z_both}",
        c.name
    );
    (g_pos, g_both)
}

fn forward_phase(gamma: f64) -> Phase {
    Phase::Vmf(Arc::new(
        VmfMixture::new(vec![(0.0, 0.2), (gamma, 1.0), (-1.5, 0.1)]).unwrap(),
    ))
}

#[test]
fn beam_sampling_agrees_with_uniform_sampling_in_3d() {
    compare(
        &Case {
            name: "3D box 6 x 6 x 3, amplitude lobes (0, 6, -1.5)",
            dimension: Dimension::Three,
            size: (6.0, 3.0),
            mean_free_path: 3.0,
            gamma: 16.0,
            phase: forward_phase(6.0),
            reflection: true,
            paths: (200_000, 150_000),
        },
        1,
    );
}

#[test]
fn beam_sampling_agrees_with_uniform_sampling_in_flatland() {
    compare(
        &Case {
            name: "flatland 16 x 4, isotropic",
            dimension: Dimension::Two,
            size: (16.0, 4.0),
            mean_free_path: 4.0,
            gamma: 16.0,
            phase: Phase::FlatIsotropic,
            reflection: true,
            paths: (100_000, 50_000),
        },
        11,
    );
}

#[test]
fn beam_sampling_gains_most_in_a_wide_slab_with_forward_scattering() {
    let (g_pos, g_both) = compare(
        &Case {
            name: "3D slab 40 x 40 x 4, forward lobe 30",
            dimension: Dimension::Three,
            size: (40.0, 4.0),
            mean_free_path: 4.0,
            gamma: 16.0,
            phase: forward_phase(30.0),
            reflection: false,
            paths: (200_000, 30_000),
        },
        21,
    );
    println!(
        "wide slab: smallest gains over the diagonal: positions {:.1}, positions and \
         directions {:.1}",
        g_pos.0, g_both.0
    );
}

/// Heavier (`validation/run`): the 3D box with its reflection sensor at 400 000 paths per render
/// and three seed sets, where the reflection entries (about 1% of the transmitted intensity,
/// heavy-tailed under every strategy) are resolved to a few percent: every entry of the beam
/// render within 4 combined standard errors of the uniform render.
#[test]
#[ignore]
fn beam_sampling_agrees_with_uniform_sampling_in_reflection_at_higher_resolution() {
    let c = Case {
        name: "3D box 6 x 6 x 3 (400 000 paths)",
        dimension: Dimension::Three,
        size: (6.0, 3.0),
        mean_free_path: 3.0,
        gamma: 16.0,
        phase: forward_phase(6.0),
        reflection: true,
        paths: (400_000, 400_000),
    };
    let s = scene(&c);
    for seed in [101, 111, 121] {
        let off = render(&s, BeamStrategy::Off, c.paths.0, seed);
        let both = render(&s, BeamStrategy::PositionAndDirection, c.paths.1, seed + 1);
        let z = max_z(&off.0, &both.0);
        let worst = *relative_ses(&both.0).last().unwrap();
        let (g_min, g_med) = gain(&off, &both);
        println!(
            "{} seeds {seed}/{}: max z {z:.2}; worst relative SE {worst:.4} (uniform {:.4}); \
             gain {g_min:.1} (median {g_med:.1})",
            c.name,
            seed + 1,
            relative_ses(&off.0).last().unwrap()
        );
        assert!(worst < 0.05, "not resolved: {worst}");
        assert!(z < 4.0, "seed {seed}: the beam strategy disagrees, z {z}");
    }
}
