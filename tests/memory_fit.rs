//! Fits of the anisotropy `g` (hence the transport mean free path) to a measured memory-effect
//! curve (issue 26, item 3: `[fit]` of `speckle memory-tilt`, `speckle_inverse::fit_family`).
//!
//! The measurement: the memory-effect curve of a slab (optical depth 5, `k theta L` = 0.5 to
//! 3) rendered at `g = 0.42` with another seed and four times the paths, plus Gaussian noise
//! of 0.01; its standard errors are the noise and the render's own jackknife error added in
//! quadrature (both are errors of this measurement). The fit: the study's renders at `g` =
//! 0, 0.25, 0.5, 0.75 (not at the truth), interpolated in `g`. For 20 noise draws the truth
//! must lie within 4.5 reported standard errors (measurement, Monte Carlo and interpolation
//! parts), and the reported error must be within [0.5, 2] of the estimates' spread over the
//! draws plus the fit render's Monte Carlo part (shared by the draws); the transport mean free
//! path is `l / (1 - g)`. A truth outside the grid is refused at its bound, and bad `[fit]`
//! tables name their key.
//!
//! Run time (ci profile, 2 cores): about 10 s.

use speckle::estimators::NoProgress;
use speckle::stats::PathRng;
use speckle::studies::memory::{load_tilt_file, load_tilt_str};

const TILTS: &str = "k_theta_l = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0]";

fn study(g: &str, paths: u64, seed: u64, fit: &str) -> String {
    format!(
        "wavelength_um = 0.5\nmean_free_path_um = 3000.0\nthickness_um = 15000.0\n\
         lateral_factor = 40.0\ng = {g}\n{TILTS}\n[render]\npaths = {paths}\nseed = {seed}\n\
         groups = 16\n{fit}"
    )
}

#[test]
fn g_and_the_transport_mean_free_path_are_recovered_from_a_memory_effect_curve() {
    let truth_g = 0.42;
    let truth = load_tilt_str(
        &study(&format!("[{truth_g}]"), 640_000, 7, ""),
        "<truth>",
        "t",
        &Default::default(),
    )
    .unwrap()
    .render(&NoProgress)
    .unwrap();
    let c = &truth.rows[0].curve;
    let dir = tempfile::tempdir().unwrap();
    let text = study(
        "[0.0, 0.25, 0.5, 0.75]",
        160_000,
        1,
        "[fit]\ndata = \"curve.csv\"\n",
    );
    std::fs::write(dir.path().join("fit.toml"), &text).unwrap();
    let ktl = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0];
    let mut rng = PathRng::new(99, 0);
    let mut write_draw = || {
        let rows: String = ktl
            .iter()
            .enumerate()
            .map(|(i, x)| {
                let e = (0.01f64.powi(2) + c.se[i + 1].powi(2)).sqrt();
                format!("{x},{},{e}\n", c.c[i + 1] + 0.01 * rng.standard_normal())
            })
            .collect();
        std::fs::write(
            dir.path().join("curve.csv"),
            format!("tilt,C,stderr\n{rows}"),
        )
        .unwrap();
    };
    write_draw();
    let s = load_tilt_file(&dir.path().join("fit.toml"), &Default::default()).unwrap();
    let renders = s.render(&NoProgress).unwrap();
    let (mut estimates, mut reported, mut mc) = (vec![], vec![], 0.0);
    for draw in 0..20 {
        if draw > 0 {
            write_draw();
        }
        // The study again for the new measurement; the renders are the same.
        let s = load_tilt_file(&dir.path().join("fit.toml"), &Default::default()).unwrap();
        let f = renders.fit(&s).unwrap().unwrap();
        let g = &f.g;
        assert!(
            (g.estimate - truth_g).abs() < 4.5 * g.stderr,
            "draw {draw}: g = {} +- {} misses {truth_g} ({g:?})",
            g.estimate,
            g.stderr
        );
        let (l_star, se, interval) = f.transport;
        assert!((l_star - 3000.0 / (1.0 - g.estimate)).abs() < 1e-9 * l_star);
        assert!(se > 0.0 && interval[0] < l_star && l_star < interval[1]);
        estimates.push(g.estimate);
        reported.push(g.stderr);
        mc = g.stderr_monte_carlo;
    }
    let n = estimates.len() as f64;
    let mean = estimates.iter().sum::<f64>() / n;
    let spread = (estimates.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let expected = (spread * spread + mc * mc).sqrt();
    let mean_reported = reported.iter().sum::<f64>() / n;
    println!(
        "g = {mean:.4} (truth {truth_g}); reported s.e. {mean_reported:.4} (Monte Carlo part \
         {mc:.4}) against the draws' spread {spread:.4}"
    );
    assert!(
        (0.5..=2.0).contains(&(mean_reported / expected)),
        "reported {mean_reported} against {expected}"
    );
    assert!(mean_reported < 0.05, "g unresolved: {mean_reported}");
}

#[test]
fn a_truth_outside_the_grid_and_bad_fit_tables_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // A curve that decays far more slowly than any of g = 0, 0.1, 0.2 gives.
    let rows = "0.5,0.99,0.01\n1.0,0.97,0.01\n2.0,0.9,0.01\n";
    std::fs::write(dir.path().join("c.csv"), rows).unwrap();
    let write = |g: &str, fit: &str| {
        let p = dir.path().join("s.toml");
        std::fs::write(&p, study(g, 20_000, 1, fit)).unwrap();
        load_tilt_file(&p, &Default::default())
    };
    let s = write("[0.0, 0.1, 0.2]", "[fit]\ndata = \"c.csv\"\n").unwrap();
    let r = s.render(&NoProgress).unwrap();
    let e = r.fit(&s).unwrap().unwrap_err().to_string();
    assert!(e.contains("lies at a bound"), "{e}");
    for (g, fit, said) in [
        (
            "[0.0, 0.5]",
            "[fit]\ndata = \"c.csv\"\n",
            "g: a fit interpolates",
        ),
        (
            "[0.5, 0.0, 0.2]",
            "[fit]\ndata = \"c.csv\"\n",
            "g: a fit interpolates",
        ),
        (
            "[0.0, 0.1, 0.2]",
            "[fit]\ndata = \"none.csv\"\n",
            "fit.data",
        ),
        (
            "[0.0, 0.1, 0.2]",
            "[fit]\ndata = \"c.csv\"\nlevel = 1.5\n",
            "fit.level",
        ),
        (
            "[0.0, 0.1, 0.2]",
            "[fit]\ndata = \"c.csv\"\nwhat = 1\n",
            "unknown field",
        ),
        ("[0.0, 0.1, 0.2]", "[fit]\ndata = \"../c.csv\"\n", "outside"),
    ] {
        let e = write(g, fit).unwrap_err().to_string();
        assert!(e.contains(said), "{g} {fit}: {e}");
    }
    std::fs::write(dir.path().join("c.csv"), "0.5,0.9\n0.7,0.8\n").unwrap();
    let e = write("[0.0, 0.1, 0.2]", "[fit]\ndata = \"c.csv\"\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("fit.data") && e.contains("the tilt 0.7 is not one of the study's"),
        "{e}"
    );
}
