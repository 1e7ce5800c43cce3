//! Tracking (Bar et al. 2023, Eqs. 38-39, Fig. 9) as `speckle tracking` renders it
//! (`speckle::runs::temporal::tracking`): a point source and a point sensor on the face of a
//! lossless, isotropically scattering slab (diffuse reflection, as in the paper's figure) whose
//! scatterers drift with `U` along the face and diffuse with `D`.
//!
//! - the curve with source and sensor shifted by `tU` over each lag equals the curve of the
//!   same medium with `U = 0` (same `D`) within 4 combined standard errors at every lag (the
//!   renders are independent: the tracked lags and the `U = 0` curve use seeds of their own);
//! - the curve without tracking is clearly different: at every non-zero lag its magnitude is
//!   below half that at `U = 0`, and it deviates by more than 10 combined standard errors;
//! - the curve without tracking is bitwise the `speckle g1` render of the scene.
//!
//! What a wrong implementation gives: endpoints not shifted reproduce the untracked curve
//! (more than 10 standard errors away); endpoints shifted by `-tU`, or by the shift of another
//! lag, decorrelate at least as much as no tracking (the shift relative to the flow is then
//! `2 tU` or `|t' - t| U`, 1 to 3 wavelengths here); a `U = 0` curve that kept the drift is the
//! untracked curve. Each of these misses the 4-SE band at every non-zero lag.
//!
//! Run time (ci profile, 2 cores): a few seconds.

use speckle::estimators::NoProgress;
use speckle::runs::temporal::{deviation, temporal, tracking};
use speckle::scene::{Overrides, Problem, load_str};
use std::path::Path;

/// Units: wavelengths (and the scene's time unit). Mean free path 1, a slab 6 thick and 100
/// wide, source and sensor 2 apart on the face z = 0; `k |U| t` reaches 3 pi over the lags,
/// `k^2 D t` 0.06 per unit squared momentum transfer.
const SCENE: &str = r#"
name = "tracking_ci"
wavelength = 1.0

[medium]
size = [100.0, 100.0, 6.0]
center = [0.0, 0.0, 3.0]
mean_free_path = 1.0
albedo = 1.0

[phase]
type = "isotropic"

[[sources]]
type = "point"
position = [-1.0, 0.0, 0.0]

[[sensors]]
type = "point"
position = [1.0, 0.0, 0.0]

[motion]
diffusion = 0.0005
drift = [0.5, 0.0, 0.0]
lags = [0.0, 0.5, 1.0, 2.0, 3.0]

[render]
paths = 40000
seed = 5
"#;

fn problem(text: &str) -> Problem {
    load_str(
        text,
        "<tracking test>",
        Path::new("."),
        "t",
        &Overrides::default(),
    )
    .unwrap()
}

#[test]
fn tracking_undoes_the_drift() {
    let p = problem(SCENE);
    let t = tracking(&p, &NoProgress).unwrap();
    let nl = t.lags.len();
    let c0 = t.at(2, 0).0.re;
    for l in 0..nl {
        let (n, sn) = t.at(0, l);
        let (a, sa) = t.at(1, l);
        let (b, sb) = t.at(2, l);
        let tracked = deviation((a, sa), (b, sb));
        let untracked = deviation((n, sn), (b, sb));
        println!(
            "t = {}: no tracking {:.4} (+- {:.4}), tracking {:.4} (+- {:.4}), U = 0 {:.4} (+- \
             {:.4}) [|C| / C(0)]; deviations from U = 0: {tracked:.2} and {untracked:.2} SE",
            t.lags[l],
            n.norm() / c0,
            sn.norm() / c0,
            a.norm() / c0,
            sa.norm() / c0,
            b.norm() / c0,
            sb.norm() / c0,
        );
        assert!(tracked < 4.0, "t = {}: tracked {a} vs U = 0 {b}", t.lags[l]);
        if t.lags[l] != 0.0 {
            assert!(
                n.norm() < 0.5 * b.norm() && untracked > 10.0,
                "t = {}: untracked {n} vs U = 0 {b}",
                t.lags[l]
            );
        }
    }
    assert!(t.max_deviation[1] < 4.0 && t.max_deviation[0] > 10.0);
    assert_eq!(t.max_deviation[2], 0.0);
    // Every render samples render.paths paths: the drifting, the U = 0 and one per lag.
    assert_eq!(t.paths, 40_000 * (nl as u64 + 2));
    // The untracked curve is the render of `speckle g1`.
    let g = temporal(&p, &NoProgress).unwrap();
    let bits = |v: &[speckle::phase::Complex64]| -> Vec<(u64, u64)> {
        v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
    };
    assert_eq!(bits(&g.correlation), bits(&t.correlation[..nl]));
    assert_eq!(
        bits(&g.correlation_stderr),
        bits(&t.correlation_stderr[..nl])
    );
}

/// Bad input is refused naming the field, before any render.
#[test]
fn tracking_refuses_what_it_cannot_track() {
    let cases = [
        (SCENE.replace("drift = [0.5, 0.0, 0.0]\n", ""), "motion.drift"),
        (
            SCENE.replace(
                "type = \"point\"\nposition = [-1.0, 0.0, 0.0]",
                "type = \"plane\"\ndirection = [0.0, 0.0, 1.0]",
            ),
            "sources[0].type",
        ),
        (
            SCENE.replace(
                "[motion]",
                "[[sensors]]\ntype = \"point\"\nposition = [2.0, 0.0, 0.0]\n\n[motion]",
            ),
            "sensors",
        ),
        (
            SCENE.replace(
                "[motion]\ndiffusion = 0.0005\ndrift = [0.5, 0.0, 0.0]\nlags = [0.0, 0.5, 1.0, 2.0, 3.0]\n",
                "",
            ),
            "motion",
        ),
    ];
    for (text, field) in cases {
        assert_ne!(text, SCENE, "{field}: the case did not change the scene");
        let e = tracking(&problem(&text), &NoProgress).unwrap_err();
        assert!(e.to_string().contains(field), "{field}: {e}");
    }
}
