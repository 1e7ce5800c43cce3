//! Dynamic wavefront shaping on sampled transmission-matrix sequences
//! (`speckle::studies::shaping`; Bar et al. 2023, Sec. 8.6, Fig. 10).
//!
//! - Phase conjugation at one frame of a static medium: the enhancement at the target equals
//!   the closed form of phase-only shaping for independent circular Gaussian transmission
//!   entries, `1 + (pi/4) ((sum sigma_m)^2 - sum sigma_m^2) / sum sigma_m^2` (about
//!   `1 + (pi/4)(N - 1)`), within 4.5 jackknife standard errors: the sampled transmission
//!   matrices have the statistics the closed form assumes (independent modes, Gaussian entries,
//!   the right intensities).
//! - A medium half static, half dynamic: a mask learned over several frames while the medium
//!   moves keeps its focus correlated longer than native speckle decorrelates (the paper's
//!   observation, and [47]'s): at the last frame the focus correlation exceeds the speckle's by
//!   more than 4.5 combined standard errors.

use speckle::estimators::{
    FieldOptions, NoProgress, Pair, Scene, Sensor, Source, render_field_sequence,
};
use speckle::medium::{Aabb, AnyMedium, DVec3, HomogeneousBox, Material, VoxelGrid};
use speckle::motion::{Motion, MotionModel};
use speckle::phase::Phase;
use speckle::studies::shaping::{phase_only_enhancement, shape};

const MODES: usize = 16;

/// `MODES` point sources 3 wavelengths apart below a slab, a far-field target above it.
fn endpoints(depth: f64) -> (Vec<Source>, Vec<Sensor>) {
    let sources = (0..MODES)
        .map(|m| {
            let (x, y) = ((m % 4) as f64 - 1.5, (m / 4) as f64 - 1.5);
            Source::point(DVec3::new(3.0 * x, 3.0 * y, -depth))
        })
        .collect();
    let sensors = vec![
        Sensor::far_field(DVec3::Z).unwrap(),
        Sensor::far_field(DVec3::new(0.3, 0.0, 1.0)).unwrap(),
    ];
    (sources, sensors)
}

fn options(realizations: usize, seed: u64) -> FieldOptions {
    FieldOptions {
        realizations,
        paths_per_realization: 100,
        seed,
        add_mean: false,
        ..Default::default()
    }
}

#[test]
fn phase_conjugation_gives_the_phase_only_enhancement() {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(30.0, 30.0, 6.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 1.5, 1.0).unwrap();
    let (src, sen) = endpoints(8.0);
    let scene = Scene::new(
        m,
        Phase::hg(0.5).unwrap(),
        1.0,
        src,
        sen,
        Pair::all(MODES, 2),
    )
    .unwrap();
    let still = MotionModel::uniform(Motion::STATIC);
    let r = 1024;
    let seq = render_field_sequence(&scene, &still, &[0.0], &options(r, 1), &NoProgress).unwrap();
    let s = shape(&seq, MODES, 2, 0, 1, 7).unwrap();
    // Mean intensity of every mode at the target, from the same realizations.
    let s2: Vec<f64> = (0..MODES)
        .map(|m| (0..r).map(|i| seq.get(i, 0, m * 2).norm_sqr()).sum::<f64>() / r as f64)
        .collect();
    let expected = phase_only_enhancement(&s2);
    let (eta, se) = s.enhancement[0];
    eprintln!(
        "phase conjugation, {MODES} modes: enhancement {eta:.3} +- {se:.3}, closed form {expected:.3} \
         (equal intensities: {:.3})",
        1.0 + std::f64::consts::FRAC_PI_4 * (MODES as f64 - 1.0)
    );
    assert!(se < 0.05 * eta, "not resolved: {se}");
    assert!(
        (eta - expected).abs() < 4.5 * se,
        "{eta} +- {se} vs {expected}"
    );
}

#[test]
fn a_mask_learned_while_the_medium_moves_keeps_its_focus_longer() {
    // A 30 x 30 x 6 slab whose half x < 0 is dynamic and half x > 0 static: paths that stay
    // in the static half keep their field.
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(30.0, 30.0, 6.0)).unwrap();
    let mats = vec![
        Material::single(1.0 / 1.5, 0.0),
        Material::single(1.0 / 1.5, 0.0),
    ];
    let grid = VoxelGrid::from_materials(b, [2, 1, 1], vec![1, 0], mats).unwrap();
    let (src, sen) = endpoints(8.0);
    let scene = Scene::new(
        AnyMedium::from(grid),
        Phase::hg(0.5).unwrap(),
        1.0,
        src,
        sen,
        Pair::all(MODES, 2),
    )
    .unwrap();
    let model =
        MotionModel::per_material(vec![Motion::STATIC, Motion::brownian(0.01).unwrap()]).unwrap();
    let times: Vec<f64> = (0..8).map(|l| l as f64).collect();
    let seq = render_field_sequence(&scene, &model, &times, &options(512, 2), &NoProgress).unwrap();
    let s = shape(&seq, MODES, 2, 0, 4, 9).unwrap();
    let last = s.times.len() - 1;
    let (f, sf) = s.focus_correlation[last];
    let (p, sp) = s.speckle_correlation[last];
    for k in 0..s.times.len() {
        eprintln!(
            "t = {:.0}: focus correlation {:.3} +- {:.3}, speckle {:.3} +- {:.3}, enhancement {:.2} +- {:.2}",
            s.times[k],
            s.focus_correlation[k].0,
            s.focus_correlation[k].1,
            s.speckle_correlation[k].0,
            s.speckle_correlation[k].1,
            s.enhancement[k].0,
            s.enhancement[k].1
        );
    }
    // The speckle decorrelates visibly, and the focus less.
    assert!(
        p + 4.5 * sp < 0.9,
        "speckle did not decorrelate: {p} +- {sp}"
    );
    assert!(
        f - p > 4.5 * sf.hypot(sp),
        "focus {f} +- {sf}, speckle {p} +- {sp}"
    );
}
