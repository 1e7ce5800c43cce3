//! The covariance decomposed by number of bounces (Bar et al. 2019, Fig. 14;
//! `scenes/fig14_bounces.toml` at full size): configurations `(i_k, v_k)` with
//! `i_k - v_k = d` for all `k`, so that every entry has `omega = i1 - v1 - (i2 - v2) = 0`, turned
//! about `d` in steps of `alpha`. Single scattering at `omega = 0` is blind to the turn (its
//! phase `k omega . x` vanishes everywhere), multiple scattering is not (the memory effect of a
//! thick cube is far narrower than the steps):
//!
//! - the covariance's single-scattering part equals an independent single-scattering render
//!   (`render_single_scattering`, other paths) entry by entry within 4.5 combined standard
//!   errors, off the diagonal too;
//! - off the diagonal the single part keeps more than half of its diagonal's magnitude at every
//!   separation, while the multiple part falls below a tenth of its diagonal at the largest (the
//!   contrast of the paper's figure; a decomposition with the parts swapped, or configurations
//!   with `omega != 0`, fails it).
//!
//! Run time: a few seconds in release.

use speckle::estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source, render_covariance,
    render_single_scattering,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::Phase;

/// A cube of 30 wavelengths at optical depth 5, isotropic scatterers, and `n` configurations
/// `i - v = d` (`|d| = 2 sin(beta / 2)`, `beta` = 20 degrees) turned about `d` in steps of
/// `step` degrees around the forward direction.
fn scene(n: usize, step: f64) -> Scene<HomogeneousBox, Phase> {
    let cube = Aabb::centered(DVec3::ZERO, DVec3::splat(30.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(cube, 6.0, 1.0).unwrap();
    let d = 2.0 * 10f64.to_radians().sin();
    let r = (1.0 - d * d / 4.0).sqrt();
    let turn = |k: usize| (90.0 + step * (k as f64 - (n - 1) as f64 / 2.0)).to_radians();
    let (mut src, mut sen) = (vec![], vec![]);
    for k in 0..n {
        let (c, s) = (turn(k).cos(), turn(k).sin());
        src.push(Source::plane_wave(DVec3::new(d / 2.0, r * c, r * s)).unwrap());
        sen.push(Sensor::far_field(DVec3::new(-d / 2.0, r * c, r * s)).unwrap());
    }
    let pairs = (0..n)
        .map(|k| Pair {
            source: k,
            sensor: k,
        })
        .collect();
    Scene::new(m, Phase::Isotropic, 1.0, src, sen, pairs).unwrap()
}

#[test]
fn single_scattering_is_blind_to_the_turn_at_omega_zero_and_multiple_is_not() {
    let n = 8;
    let s = scene(n, 4.0);
    let opts = |paths, seed| CovarianceOptions {
        paths,
        seed,
        coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
    let c = render_covariance(&s, &opts(100_000, 1), &NoProgress).unwrap();
    let single = render_single_scattering(&s, &opts(100_000, 2), &NoProgress).unwrap();
    // The single part against the independent render, entry by entry.
    let mut worst: f64 = 0.0;
    for a in 0..n {
        for b in 0..n {
            let (x, y) = (c.single.value.get(a, b), single.value.get(a, b));
            let (sx, sy) = (c.single.std_error.get(a, b), single.std_error.get(a, b));
            for (d, se) in [
                (x.re - y.re, sx.re.hypot(sy.re)),
                (x.im - y.im, sx.im.hypot(sy.im)),
            ] {
                if se > 0.0 {
                    worst = worst.max(d.abs() / se);
                }
            }
        }
    }
    println!("single part against render_single_scattering: largest {worst:.2} SE");
    assert!(worst < 4.5, "{worst}");
    // Mean magnitudes by separation, relative to each part's diagonal.
    let by = |m: &speckle::estimators::CMatrix, k: usize| {
        (0..n - k).map(|a| m.get(a, a + k).norm()).sum::<f64>() / (n - k) as f64
    };
    let (s0, m0) = (by(&c.single.value, 0), by(&c.multiple.value, 0));
    for k in 0..n {
        println!(
            "separation {k} ({} deg of turn): single {:.3}, multiple {:.3} of their diagonals",
            4 * k,
            by(&c.single.value, k) / s0,
            by(&c.multiple.value, k) / m0
        );
    }
    assert!(
        m0 > s0,
        "the intensity is mostly multiple scattering: {m0} vs {s0}"
    );
    for k in 1..n {
        assert!(by(&c.single.value, k) > 0.5 * s0, "single at {k}");
    }
    assert!(
        by(&c.multiple.value, n - 1) < 0.1 * m0,
        "multiple at {}",
        n - 1
    );
}
