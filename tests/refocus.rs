//! `speckle refocus` (Bar et al. 2020, Sec. 9.1, Fig. 13 bottom; `speckle::studies::memory::
//! RefocusStudy`): the expected power of a phase-conjugate focus through a slab against its
//! displacement `Delta`, the conjugate field shifted (Eq. 51) or shifted and tilted (Eq. 52).
//!
//! The slab is the one of `tests/tilt_shift.rs` (L = 20 um, l = 23 um, g = 0.98, lambda = 0.5 um,
//! NA 0.2; K = k^2 L^3 / (2 l_tr) = 550), displacements 0, 0.5, 1, 1.5 um. Tolerances, fixed
//! before running (jackknife SE over 10 groups of 3000 paths):
//!
//! 1. At `Delta = 0` the focus amplitude `E A(0) = sum_m E|u_i(tau_m)|^2` is the camera's total
//!    mean intensity: real (`Im / Re` within 4 SE of 0) and positive; the normalised power is 1
//!    by construction, and no displaced focus may exceed it by more than 4 SE (phase conjugation
//!    focuses best where the guide star was).
//! 2. The shift-only power decays: each step down within 4 SE of the difference (the SEs of the
//!    two points added in quadrature, independent renders), and at 1.5 um it is below 1 by more
//!    than 5 SE (Eq. 50: exp(-2 K (1.5/20)^2) = 0.002).
//! 3. The tilt helps: at 1 and 1.5 um Eq. 50 gives the shift-and-tilt power 0.50 and 0.21
//!    against 0.064 and 0.002; the difference must be positive by more than 4 of its jackknife
//!    SEs. The tilt of the wrong sign (`theta = +3 Delta / (2 L)`, pattern shift `5 Delta / 2`)
//!    has Eq. 50's exponent 13/4 of the shift-only one (power 0.11 and 1e-4 against 0.50 and
//!    0.064 at 0.5 and 1 um): rendered here too, it must be worse than shift only by more than 4
//!    SE at 0.5 and 1 um; so the test fails if the sign of the tilt of
//!    Eq. 52 (or of the delta `Delta_b = Delta_a + L theta`) is wrong.
//!
//! Run time (ci profile, 2 cores): about 3 s.

use speckle::estimators::NoProgress;
use speckle::studies::memory::{load_refocus_str, optimal_tilt};

const STUDY: &str = r#"
wavelength_um = 0.5
mean_free_path_um = 23.0
g = 0.98
thickness_um = 20.0
width_um = 30.0
numerical_aperture = 0.2
delta_max_um = 1.5
n_delta = 4
tau_max_um = 8.0
n_tau = 17

[render]
paths = 30000
seed = 7
groups = 10
"#;

#[test]
fn refocus_peaks_at_zero_decays_and_the_tilt_helps() {
    let s = load_refocus_str(STUDY, "<test>", "t", &Default::default()).unwrap();
    assert_eq!(s.delta, vec![0.0, 0.5, 1.0, 1.5]);
    assert!((optimal_tilt(1.0, 20.0) + 0.075).abs() < 1e-15);
    let r = s.render(&NoProgress).unwrap();
    eprintln!("{}", r.text(&s));
    let n = s.delta.len();

    // 1. Delta = 0.
    assert!(r.complex[0].re > 0.0, "E A(0) = {}", r.complex[0]);
    assert!(
        r.im_ratio.abs() <= 4.0 * r.im_ratio_se + 1e-12,
        "Im/Re at 0: {} +- {}",
        r.im_ratio,
        r.im_ratio_se
    );
    assert!((r.shift[0] - 1.0).abs() < 1e-12 && (r.tilt[0] - 1.0).abs() < 1e-12);
    for j in 1..n {
        assert!(
            r.shift[j] <= 1.0 + 4.0 * r.shift_se[j],
            "shift {j}: {}",
            r.shift[j]
        );
        assert!(
            r.tilt[j] <= 1.0 + 4.0 * r.tilt_se[j],
            "tilt {j}: {}",
            r.tilt[j]
        );
    }

    // 2. Decay.
    for j in 1..n {
        let se = r.shift_se[j].hypot(r.shift_se[j - 1]);
        assert!(
            r.shift[j] < r.shift[j - 1] + 4.0 * se,
            "shift-only power rises from {} to {} (SE {se})",
            r.shift[j - 1],
            r.shift[j]
        );
    }
    assert!(r.shift[n - 1] < 1.0 - 5.0 * r.shift_se[n - 1]);

    // 3. The tilt helps at 1 and 1.5 um; the wrong sign hurts.
    for j in [2, 3] {
        assert!(
            r.gain[j] > 4.0 * r.gain_se[j],
            "Delta = {}: shift+tilt {} +- {} against shift {} +- {} (gain {} +- {})",
            s.delta[j],
            r.tilt[j],
            r.tilt_se[j],
            r.shift[j],
            r.shift_se[j],
            r.gain[j],
            r.gain_se[j]
        );
    }
    let wrong: Vec<f64> = s.tilts().iter().map(|t| -t).collect();
    let w = s.render_with_tilts(&wrong, &NoProgress).unwrap();
    eprintln!("wrong sign:\n{}", w.text(&s));
    for j in [1, 2] {
        assert!(
            w.gain[j] < -4.0 * w.gain_se[j],
            "Delta = {}: wrong-sign tilt {} +- {} against shift {} +- {}",
            s.delta[j],
            w.tilt[j],
            w.tilt_se[j],
            w.shift[j],
            w.shift_se[j]
        );
    }
}

/// The shipped file of Fig. 13 loads (its results: `docs/experiments-2020.md`).
#[test]
fn shipped_refocus_study_loads() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = speckle::studies::memory::load_refocus_file(
        &root.join("scenes/fig13_refocus.toml"),
        &Default::default(),
    )
    .unwrap();
    assert_eq!((s.name.as_str(), s.delta.len()), ("fig13_refocus", 9));
    assert_eq!(s.delta[8], 2.0);
}

/// The rendered refocused fields (`[images]`, Fig. 13 top) against the covariances: on the slab
/// above (17 camera pixels), cases `Delta = 0` and `Delta = 1 um` shift only and shift and tilt,
/// a line of 5 pixels over +-4 um around the target, 48 realizations of 1500 sub-paths; the
/// check renders 24 000 paths per case in 8 groups. Tolerances fixed before running:
///
/// 1. At every case and check pixel (the target and both ends of the line), the realizations' mean
///    of `A` (real and imaginary parts), mean of `|A|^2` and variance of `A` agree with the
///    covariance prediction (`E A`; `|E A|^2 + Var A` and `Var A` with the Isserlis background)
///    within 4.5 standard errors (realizations' SE and jackknife SE in quadrature). A wrong
///    conjugation (the pattern `u_g` instead of `conj(u_g)`) makes the mean of `A` at the target
///    of `Delta = 0` zero where the covariances give 1 (checked by mutation: tens of SE off).
/// 2. Phase conjugation focuses: at `Delta = 0` the realizations' mean of `A` at the target
///    (the camera's total intensity) is positive by more than 5 SE.
/// 3. The focus term of the images, `|E A|^2` of the check renders, equals the bottom row's
///    (`Refocus::shift`, `Refocus::tilt`, Eq. 49 of independent renders) at `Delta = 1 um`
///    within 4.5 SE: the ramp `exp(-i q tau)` and the geometry are the study's (a ramp of the
///    wrong sign leaves a few percent of the tilted focus; checked by mutation).
#[test]
fn refocused_images_match_the_covariances() {
    let text = format!(
        "{}\n[images]\ndelta_um = [1.0]\nhalf_width_um = 4.0\nn_pixels = 5\nrealizations = \
         48\npaths = 1500\n",
        STUDY
            .replace("paths = 30000", "paths = 24000")
            .replace("groups = 10", "groups = 8")
    );
    let s = load_refocus_str(&text, "<test>", "t", &Default::default()).unwrap();
    let plan = s.images.clone().unwrap();
    assert_eq!(plan.cases.len(), 3);
    let im = s.render_images(&NoProgress).unwrap().unwrap();
    eprintln!("{}", im.text(&plan));

    // 1. Every moment at every check pixel.
    for (c, dev) in im.deviations().iter().enumerate() {
        for (k, d) in dev.iter().enumerate() {
            for (q, z) in d.iter().enumerate() {
                assert!(
                    z.abs() < 4.5,
                    "case {c} ({}), {}: moment {q} off by {z:.2} SE",
                    plan.cases[c].label(),
                    speckle::studies::memory::CHECK_PIXEL_NAMES[k]
                );
            }
        }
    }
    // 2. The focus: at Delta = 0 the target's mean amplitude is the camera's total intensity.
    let t = &im.measured[0][0];
    assert!(
        t.mean_re > 5.0 * t.mean_se,
        "Delta = 0: mean A at the target {} +- {}",
        t.mean_re,
        t.mean_se
    );
    // 3. The bottom row at Delta = 1 um (index 2 of the study's displacements).
    let r = s.render(&NoProgress).unwrap();
    for (c, (curve, se)) in [(1, (&r.shift, &r.shift_se)), (2, (&r.tilt, &r.tilt_se))] {
        let p = &im.predicted[c][0];
        let (focus, focus_se) = p.focus;
        let z = (focus - curve[2]) / focus_se.hypot(se[2]);
        assert!(
            z.abs() < 4.5,
            "{}: images' |E A|^2 {focus} +- {focus_se} against the study's {} +- {}",
            plan.cases[c].label(),
            curve[2],
            se[2]
        );
    }
}
