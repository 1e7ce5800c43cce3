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
//!
//! The scenes, renders, relative errors, gains and z-scores are the library's
//! (`speckle::studies::nearfield::sampling`, shared with `speckle sampling-gain` and
//! `scenes/fig9_sampling_gain.toml`); this test keeps the comparisons and their tolerances.

use speckle::endpoints::GaussianBeam;
use speckle::estimators::{CovarianceEstimate, NoProgress, Pair, Scene, Sensor, Source};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{BeamStrategy, MAX_BEAM_COMPONENTS};
use speckle::phase::{Dimension, Phase};
use speckle::studies::nearfield::{
    SamplingCase, StrategyRender, gain, max_z, relative_ses, render_strategy,
};
use speckle::vmf::VmfMixture;
use std::sync::Arc;

/// One case: the library's scene description with the paths of the uniform render and of the
/// beam renders.
struct Case {
    case: SamplingCase,
    paths: (u64, u64),
}

fn render(
    s: &Scene<HomogeneousBox, Phase>,
    beams: BeamStrategy,
    paths: u64,
    seed: u64,
) -> StrategyRender {
    render_strategy(s, beams, paths, seed, &NoProgress).unwrap()
}

/// Renders `c` three ways and checks agreement; returns the (smallest, median) gains of
/// positions only and of positions and directions.
fn compare(c: &Case, seed: u64) -> ((f64, f64), (f64, f64)) {
    let s = c.case.scene().unwrap();
    let name = &c.case.name;
    let off = render(&s, BeamStrategy::Off, c.paths.0, seed);
    let pos = render(&s, BeamStrategy::Position, c.paths.1, seed + 1);
    let both = render(&s, BeamStrategy::PositionAndDirection, c.paths.1, seed + 2);
    let (z_pos, z_both) = (
        max_z(&off.estimate, &pos.estimate),
        max_z(&off.estimate, &both.estimate),
    );
    let (g_pos, g_both) = (gain(&off, &pos), gain(&off, &both));
    let worst = |c: &CovarianceEstimate| *relative_ses(c).last().unwrap();
    println!(
        "{name}: max z uniform vs beam positions {z_pos:.2}, vs positions and directions \
         {z_both:.2}; worst relative SE: uniform {:.4} ({} paths, {:.2} s), positions {:.4}, \
         both {:.4} ({} paths, {:.2} s, {:.2} s); variance x time gain over uniform: positions \
         {:.1} (median {:.1}), positions and directions {:.1} (median {:.1})",
        worst(&off.estimate),
        c.paths.0,
        off.seconds,
        worst(&pos.estimate),
        worst(&both.estimate),
        c.paths.1,
        pos.seconds,
        both.seconds,
        g_pos.0,
        g_pos.1,
        g_both.0,
        g_both.1
    );
    // The default strategy must resolve every entry (positions alone, with uniform first
    // directions at beam vertices, has heavier tails in reflection: printed, not asserted).
    assert!(
        worst(&both.estimate) < 0.05,
        "{name}: the beam render is not resolved"
    );
    assert!(z_pos < 4.0, "{name}: positions disagree, z {z_pos}");
    assert!(
        z_both < 4.0,
        "{name}: the beam strategy disagrees, z {z_both}"
    );
    (g_pos, g_both)
}

fn forward_phase(gamma: f64) -> Phase {
    Phase::Vmf(Arc::new(
        VmfMixture::new(vec![(0.0, 0.2), (gamma, 1.0), (-1.5, 0.1)]).unwrap(),
    ))
}

/// The small 3D box with its reflection sensor.
fn box_3d() -> SamplingCase {
    SamplingCase {
        name: "3D box 6 x 6 x 3, amplitude lobes (0, 6, -1.5)".into(),
        dimension: Dimension::Three,
        size: (6.0, 3.0),
        mean_free_path: 3.0,
        gamma: 16.0,
        phase: forward_phase(6.0),
        reflection: true,
    }
}

#[test]
fn beam_sampling_agrees_with_uniform_sampling_in_3d() {
    compare(
        &Case {
            case: box_3d(),
            paths: (200_000, 150_000),
        },
        1,
    );
}

#[test]
fn beam_sampling_agrees_with_uniform_sampling_in_flatland() {
    compare(
        &Case {
            case: SamplingCase {
                name: "flatland 16 x 4, isotropic".into(),
                dimension: Dimension::Two,
                size: (16.0, 4.0),
                mean_free_path: 4.0,
                gamma: 16.0,
                phase: Phase::FlatIsotropic,
                reflection: true,
            },
            paths: (100_000, 50_000),
        },
        11,
    );
}

#[test]
fn beam_sampling_gains_most_in_a_wide_slab_with_forward_scattering() {
    let (g_pos, g_both) = compare(
        &Case {
            case: SamplingCase {
                name: "3D slab 40 x 40 x 4, forward lobe 30".into(),
                dimension: Dimension::Three,
                size: (40.0, 4.0),
                mean_free_path: 4.0,
                gamma: 16.0,
                phase: forward_phase(30.0),
                reflection: false,
            },
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

/// A camera: more beams than [`MAX_BEAM_COMPONENTS`] (two sources and a line of 16 pixels on
/// the exit face, 0.2 apart over the sources' light), where every pixel's beam is a position
/// component, the sources' also sample directions, and the volume, the sources and the pixels
/// each have a third of the samples. The mixture of this size is checked against uniform
/// sampling as the small scenes are (every entry of the 32 x 32 covariance within 4 combined
/// SE), and its gain printed.
#[test]
fn beam_sampling_of_a_camera_agrees_with_uniform_sampling() {
    let (lat, depth, gamma) = (10.0, 3.0, 16.0);
    let bounds = Aabb::centered(DVec3::ZERO, DVec3::new(lat, lat, depth)).unwrap();
    let medium = HomogeneousBox::from_mean_free_path(bounds, 3.0, 1.0).unwrap();
    let at = |x: f64, z: f64| DVec3::new(x, 0.0, z);
    let beam = |field: &str, f: DVec3| GaussianBeam::new(field, f, DVec3::Z, gamma).unwrap();
    let sources: Vec<Source> = [0.0, 1.0]
        .iter()
        .map(|&x| Source::GaussianBeam(beam("source", at(x, -0.5 * depth))))
        .collect();
    let sensors: Vec<Sensor> = (0..16)
        .map(|m| Sensor::GaussianBeam(beam("sensor", at(0.2 * m as f64 - 1.0, 0.5 * depth))))
        .collect();
    assert!(sources.len() + sensors.len() > MAX_BEAM_COMPONENTS);
    let pairs = Pair::all(2, sensors.len());
    let s = Scene::new(medium, forward_phase(6.0), 1.0, sources, sensors, pairs).unwrap();
    let off = render(&s, BeamStrategy::Off, 200_000, 41);
    let both = render(&s, BeamStrategy::PositionAndDirection, 100_000, 42);
    let z = max_z(&off.estimate, &both.estimate);
    let g = gain(&off, &both);
    let worst = |c: &CovarianceEstimate| *relative_ses(c).last().unwrap();
    println!(
        "camera of 16 pixels: max z uniform vs beams {z:.2}; worst relative SE: uniform {:.4} \
         ({:.2} s), beams {:.4} ({:.2} s); variance x time gain {:.1} (median {:.1})",
        worst(&off.estimate),
        off.seconds,
        worst(&both.estimate),
        both.seconds,
        g.0,
        g.1
    );
    assert!(
        worst(&both.estimate) < 0.05,
        "the camera render is not resolved"
    );
    assert!(z < 4.0, "the camera's beam mixture disagrees, z {z}");
}

/// Heavier (`validation/run`): the 3D box with its reflection sensor at 400 000 paths per render
/// and three seed sets, where the reflection entries (about 1% of the transmitted intensity,
/// heavy-tailed under every strategy) are resolved to a few percent: every entry of the beam
/// render within 4 combined standard errors of the uniform render.
#[test]
#[ignore]
fn beam_sampling_agrees_with_uniform_sampling_in_reflection_at_higher_resolution() {
    let c = Case {
        case: SamplingCase {
            name: "3D box 6 x 6 x 3 (400 000 paths)".into(),
            ..box_3d()
        },
        paths: (400_000, 400_000),
    };
    let s = c.case.scene().unwrap();
    for seed in [101, 111, 121] {
        let off = render(&s, BeamStrategy::Off, c.paths.0, seed);
        let both = render(&s, BeamStrategy::PositionAndDirection, c.paths.1, seed + 1);
        let z = max_z(&off.estimate, &both.estimate);
        let worst = *relative_ses(&both.estimate).last().unwrap();
        let (g_min, g_med) = gain(&off, &both);
        println!(
            "{} seeds {seed}/{}: max z {z:.2}; worst relative SE {worst:.4} (uniform {:.4}); \
             gain {g_min:.1} (median {g_med:.1})",
            c.case.name,
            seed + 1,
            relative_ses(&off.estimate).last().unwrap()
        );
        assert!(worst < 0.05, "not resolved: {worst}");
        assert!(z < 4.0, "seed {seed}: the beam strategy disagrees, z {z}");
    }
}
