//! The authors' MCX temporal correlation (`validation/data/mcx_dcs_validation/g1_mcx.csv`; the
//! scene of `shared/notes/spatiotemporal-2023.md` Sec. 8.7) against the shipped scene
//! `scenes/fig5_mcx_rods.toml` (the one definition of the configuration; `speckle g1` renders
//! it with `--reference`): a 1 cm cube, mean free path 1 mm, isotropic, lossless,
//! lambda = 500 nm, dynamic rods (0.1 mm wide in x and z, every 0.3 mm, through y: 1/9 of the
//! volume, D = 1e-6 cm^2/s, the rest static; `scenes/fig5_mcx_rods.npy`), source and sensor
//! 5 mm apart on the face z = 0; `g1(t)` for t = 0 .. 50 us.
//!
//! Source and sensor are isotropic points on the face, as in the authors' example: first
//! vertices are sampled around them (Build 3 of issue 12), so the estimator has finite variance
//! there. The authors' curve corresponds to these isotropic point endpoints: MCX-CL run by
//! `validation/mcx/dcs.py` with an isotropic source and a fluence-weighted detector agrees with
//! it and with us, while a pencil beam with a flux detector gives a different measurement
//! (`g1(50 us)` lower by 0.036: deeper first scattering, longer detected paths).
//!
//! - `mcx_g1_is_reproduced` (CI): `|g1(t)| = |C(t)| / C(0)` from 16 independent renders of
//!   60 000 paths, its standard error by the jackknife over the renders (the ratio's errors are
//!   strongly correlated, so the first-order formula that ignores it overstates them); every
//!   one of the 51 lags must lie within 4.5 standard errors of MCX's, and the curve must be
//!   resolved (standard error below 0.01).
//! - `mcx_dynamic_rods` (ignored; `validation/run`, `SPECKLE_MCX_PATHS`): one render, a report.

use num_complex::Complex64;
mod common_g1;

use speckle::estimators::{CovarianceOptions, Entries, NoProgress, render_correlation};
use speckle::medium::{DVec3, Medium};
use speckle::scene::Problem;

fn mcx() -> Vec<(f64, f64)> {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/validation/data/mcx_dcs_validation/g1_mcx.csv"
    ))
    .expect("the peer data in validation/data");
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
            (v[0], v[2])
        })
        .collect()
}

/// The shipped scene, whose lags are MCX's.
fn scene() -> Problem {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fig5_mcx_rods.toml");
    let p = speckle::scene::load::load_file(&file, &Default::default()).unwrap();
    let lags = &p.motion.as_ref().expect("[motion]").lags;
    let mcx_lags: Vec<f64> = mcx().iter().map(|r| r.0).collect();
    assert_eq!(lags, &mcx_lags, "the scene's lags are the MCX curve's");
    p
}

/// `C(t)` and its standard error at the MCX lags, from `paths` paths of seed `seed`.
fn render(p: &Problem, paths: u64, seed: u64) -> Vec<(Complex64, Complex64)> {
    let motion = p.motion.as_ref().expect("[motion]");
    let c = render_correlation(
        &p.scene,
        &motion.model,
        &motion.lags,
        &Entries::Diagonal,
        &CovarianceOptions {
            paths,
            seed,
            ..speckle::runs::covariance_options(p)
        },
        &NoProgress,
    )
    .unwrap();
    (0..motion.lags.len()).map(|l| c.total(l, 0)).collect()
}

#[test]
fn mcx_g1_is_reproduced() {
    let reference = mcx();
    let scene = scene();
    let groups: Vec<Vec<Complex64>> = (0..16)
        .map(|g| {
            render(&scene, 60_000, 100 + g)
                .into_iter()
                .map(|c| c.0)
                .collect()
        })
        .collect();
    let g1 = common_g1::g1_jackknife(&groups);
    let mut worst: (f64, f64, f64) = (0.0, 0.0, 0.0);
    for (l, (t, g_mcx)) in reference.iter().enumerate() {
        let (g, se) = g1[l];
        let z = if se > 0.0 { (g - g_mcx) / se } else { 0.0 };
        if l % 10 == 0 {
            eprintln!(
                "t = {:4.0} us: |g1| {:.4} +- {se:.4}, MCX {g_mcx:.4}, z = {z:+.2}",
                t * 1e6,
                g
            );
        }
        if z.abs() > worst.2.abs() {
            worst = (*t, g - g_mcx, z);
        }
        assert!(se < 0.01, "g1 not resolved at t = {t}: se {se}");
        assert!(
            z.abs() < 4.5,
            "t = {t}: |g1| {g} +- {se} against MCX {g_mcx}"
        );
    }
    eprintln!(
        "largest deviation in SE: {:+.4} (z = {:+.2}) at t = {:.0} us",
        worst.1,
        worst.2,
        worst.0 * 1e6
    );
}

#[test]
#[ignore]
fn mcx_dynamic_rods() {
    let reference = mcx();
    let scene = scene();
    let dynamic = ids_fraction(scene.scene.medium());
    let paths = std::env::var("SPECKLE_MCX_PATHS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(200_000u64);
    let start = std::time::Instant::now();
    let c = render(&scene, paths, 1);
    let secs = start.elapsed().as_secs_f64();
    let (c0, s0) = c[0];
    println!(
        "MCX rods (dynamic fraction {dynamic:.3}): {paths} paths in {secs:.1} s, C(0) = {:.4e} +- {:.1e}",
        c0.re, s0.re
    );
    let mut worst: (f64, f64, f64) = (0.0, 0.0, 0.0);
    for (l, (t, g_mcx)) in reference.iter().enumerate() {
        let (ct, st) = c[l];
        let g = ct.norm() / c0.re;
        // First-order error of the ratio, ignoring the (positive) correlation of C(t) and C(0):
        // an overstatement (see `mcx_g1_is_reproduced` for the jackknife).
        let se = g * ((st.re / ct.re).powi(2) + (s0.re / c0.re).powi(2)).sqrt();
        if (g - g_mcx).abs() > worst.1.abs() {
            worst = (*t, g - g_mcx, se);
        }
        if l % 5 == 0 {
            println!(
                "  t = {:4.0} us: |g1| {g:.4} +- {se:.4}, MCX {g_mcx:.4}",
                t * 1e6
            );
        }
    }
    println!(
        "  largest deviation {:+.4} (+- {:.4}, z = {:+.1}) at t = {:.0} us",
        worst.1,
        worst.2,
        worst.1 / worst.2,
        worst.0 * 1e6
    );
}

/// The fraction of voxels of material 1.
fn ids_fraction(g: &impl Medium) -> f64 {
    let n = 100;
    let mut dynamic = 0;
    for iz in 0..n {
        for ix in 0..n {
            let x = DVec3::new(
                -0.5 + (ix as f64 + 0.5) / n as f64,
                0.0,
                (iz as f64 + 0.5) / n as f64,
            );
            dynamic += g.material(x);
        }
    }
    dynamic as f64 / (n * n) as f64
}
