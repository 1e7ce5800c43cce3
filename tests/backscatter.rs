//! Coherent backscattering: with reversed paths, the multiple-scattering intensity at the exact
//! backscattering direction is about twice its value several cone widths away, and it is flat
//! with forward paths only.
//!
//! Scene: a lossless slab of isotropic scatterers, 20 x 20 mean free paths wide and 4 thick, mean
//! free path `l = 2000` wavelengths, a unit plane wave at normal incidence (`i = +z`), far-field
//! sensors at the exact backscattering direction `v = -z` and tilted from it by `theta` in the
//! x-z plane. The cone's angular scale is `w = 1 / (k l)` (`l* = l` for isotropic scattering);
//! a large `k l` keeps the cone far narrower than the angular variation of the diffuse background.
//!
//! Checks, on the multiple-scattering part (`B >= 2`) of the intensity (`C[j, j]`):
//!
//! 1. Exact backscattering: every reversed path has the same phase as its forward path, so
//!    forward-and-reversed is exactly twice forward-only, path by path (same seed: equal to
//!    rounding).
//! 2. The ratio `R = M_FR(0) / M_FR(10 w)`, with its standard error `sigma_R` by the delta method
//!    (entries treated as independent): `R + 4 sigma_R > 1.8` and `R - 4 sigma_R < 2`, and
//!    `R - 4 sigma_R > 1.5`. Justification: the peak is exactly twice the background (1.), and
//!    the forward-only background is flat to within its SE (3.), so `R = 2 / (1 + T)` with `T`
//!    the interference term left at ten cone widths; `T >= 0` gives `R <= 2`, and the wings of
//!    the cone (dominated by double scattering, which decays as `1/(q l)`, `q = k theta`) must
//!    have fallen below 10% of the background by `q l = 10`, giving `R > 1.8`. A wrong
//!    wavenumber, reversed-path phase or path geometry broadens or removes the cone and fails.
//! 3. Forward paths only: the intensity at `v = -z` and at the tilted sensors agree within 4
//!    combined standard errors `sqrt(se1^2 + se2^2)`.
//! 4. Far outside the cone, at `theta = 0.05 rad` (about 630 cone widths, where the `1/(q l)` wing
//!    is below 0.1%), forward-and-reversed and forward-only agree within 4 combined SE.
//!
//! Combined SEs ignore the (positive) correlation between entries computed from the same paths,
//! which overstates the noise of differences; the checks are conservative in that sense.

use speckle::estimators::{
    Coherence, CovarianceEstimate, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source,
    render_covariance,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::Phase;
use std::f64::consts::TAU;

const LAMBDA: f64 = 1.0;
const MFP: f64 = 2000.0;
const PATHS: u64 = 1 << 19;

/// Multiple-scattering intensity at sensor `j` and its standard error.
fn intensity(c: &CovarianceEstimate, j: usize) -> (f64, f64) {
    let (v, se) = c.multiple.get(j, j);
    (v.re, se.re)
}

/// Combined z-score of the difference of two independent estimates.
fn z(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).abs() / (a.1 * a.1 + b.1 * b.1).sqrt()
}

#[test]
fn coherent_backscattering_cone() {
    let k = TAU / LAMBDA;
    let w = 1.0 / (k * MFP);
    // Sensors: exact backscattering, one cone width, ten cone widths, far outside.
    let thetas = [0.0, w, 10.0 * w, 0.05];
    let size = DVec3::new(20.0 * MFP, 20.0 * MFP, 4.0 * MFP);
    let medium =
        HomogeneousBox::from_mean_free_path(Aabb::centered(DVec3::ZERO, size).unwrap(), MFP, 1.0)
            .unwrap();
    let sensors = thetas
        .iter()
        .map(|t| Sensor::far_field(DVec3::new(t.sin(), 0.0, -t.cos())).unwrap())
        .collect();
    let scene = Scene::new(
        medium,
        Phase::Isotropic,
        LAMBDA,
        vec![Source::plane_wave(DVec3::Z).unwrap()],
        sensors,
        Pair::all(1, thetas.len()),
    )
    .unwrap();
    let render = |coherence| {
        render_covariance(
            &scene,
            &CovarianceOptions {
                paths: PATHS,
                seed: 31,
                coherence,
                ..Default::default()
            },
            &NoProgress,
        )
        .unwrap()
    };
    let fr = render(Coherence::ForwardAndReversed);
    let fo = render(Coherence::ForwardOnly);
    for (j, t) in thetas.iter().enumerate() {
        let (a, b) = (intensity(&fr, j), intensity(&fo, j));
        eprintln!(
            "theta = {:8.2} cone widths: forward+reversed {:.5e} +- {:.1e}, forward only {:.5e} +- {:.1e}, ratio {:.4}",
            t / w,
            a.0,
            a.1,
            b.0,
            b.1,
            a.0 / b.0
        );
    }

    // 1. Exact backscattering: twice the forward-only value, path by path.
    let (peak, peak_fo) = (intensity(&fr, 0), intensity(&fo, 0));
    assert!(
        (peak.0 - 2.0 * peak_fo.0).abs() <= 1e-12 * peak.0,
        "at exact backscattering forward+reversed {} is not twice forward-only {}",
        peak.0,
        peak_fo.0
    );

    // 2. Enhancement relative to ten cone widths away.
    let far = intensity(&fr, 2);
    let ratio = peak.0 / far.0;
    let sigma = ratio * ((peak.1 / peak.0).powi(2) + (far.1 / far.0).powi(2)).sqrt();
    eprintln!(
        "backscatter enhancement M(0) / M(10 cone widths) = {ratio:.4} +- {sigma:.4} (forward+reversed)"
    );
    assert!(
        ratio - 4.0 * sigma > 1.5,
        "no clear backscattering peak: ratio {ratio} +- {sigma}"
    );
    assert!(
        ratio + 4.0 * sigma > 1.8 && ratio - 4.0 * sigma < 2.0,
        "enhancement {ratio} +- {sigma} outside [1.8, 2]"
    );

    // 3. Forward paths only: flat.
    for (j, t) in thetas.iter().enumerate().skip(1) {
        let zj = z(peak_fo, intensity(&fo, j));
        eprintln!(
            "forward only: backscatter vs {:.1} cone widths: z = {zj:.2}",
            t / w
        );
        assert!(
            zj < 4.0,
            "forward-only intensity not flat: sensor {j} differs from backscatter by {zj} SE"
        );
    }

    // 4. Far outside the cone the reversed paths add nothing.
    let zo = z(intensity(&fr, 3), intensity(&fo, 3));
    eprintln!(
        "far outside the cone ({:.0} cone widths): forward+reversed vs forward only z = {zo:.2}",
        thetas[3] / w
    );
    assert!(
        zo < 4.0,
        "forward+reversed and forward-only differ far outside the cone by {zo} SE"
    );
}
