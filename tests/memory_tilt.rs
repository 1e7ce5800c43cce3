//! `speckle memory-tilt` (Bar et al. 2023, Fig. 6; `speckle::studies::memory::TiltStudy`): at
//! `g = 0` in a slab thick enough for diffusion, the Monte Carlo memory-effect curve follows the
//! C1 term `(k theta L)^2 / sinh^2(k theta L)`.
//!
//! Tolerance, fixed before running (the derivation of `tests/memory_effect.rs`, which checks
//! the same physics on a hand-built scene): C1 is the diffusion limit `L >> l*` of an infinite
//! slab; at a finite optical depth the diffusion solution depends on where its absorbing
//! boundaries are put, at the faces (`L`) or at the Milne extrapolated boundaries `z_e = 0.7104
//! l*` outside them (`L + 2 z_e`), a relative uncertainty `2 z_e / L` of the thickness (14% at
//! optical depth 10). The model band is `C1(x (L + 2 z_e) / L) <= C <= C1(x)`, widened by 4
//! jackknife standard errors. Here: isotropic (`g = 0`), `L = 10 l` (3 cm at `l` = 3 mm,
//! `lambda` = 500 nm, as the shipped `scenes/fig6a_memory_tilt.toml`), 100 L wide,
//! `k theta L` = 0, 0.5, 1, 1.5, 2, 3. A wrong tilt or wavenumber scale (a factor 2 in
//! `k theta`) puts `C(1)` near 0.30, far outside the band (0.66 to 0.72); a correlation that
//! forgot the normalisation by `C_nn` or the square misses it too. The curve must also decay
//! monotonically and start at exactly 1, and the written C1 column must be the formula.
//!
//! Run time (ci profile, 2 cores): about 5 s.

use speckle::estimators::NoProgress;
use speckle::studies::memory::{eq39, load_tilt_str};

const STUDY: &str = r#"
wavelength_um = 0.5
mean_free_path_um = 3000.0
thickness_um = 30000.0
g = [0.0]
k_theta_l = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0]

[render]
paths = 320000
seed = 11
groups = 16
"#;

#[test]
fn isotropic_thick_slab_follows_c1() {
    let s = load_tilt_str(STUDY, "<test>", "t", &Default::default()).unwrap();
    let m = s.render(&NoProgress).unwrap();
    let row = &m.rows[0];
    let l_star = s.materials[0].transport_mfp();
    let leff = s.thickness + 2.0 * 0.7104 * l_star;
    for (n, &x) in m.k_theta_l.iter().enumerate() {
        let (c, se) = (row.curve.c[n], row.curve.se[n]);
        let (hi, lo) = (eq39(x), eq39(x * leff / s.thickness));
        println!("k theta L = {x:.3}: C = {c:.4} +- {se:.4}; C1(L) {hi:.4}, C1(L + 2 z_e) {lo:.4}");
        assert_eq!(m.c1[n], hi);
        assert_eq!(row.extrapolated[n], lo);
        assert!(
            c <= hi + 4.0 * se && c >= lo - 4.0 * se,
            "k theta L = {x}: C = {c} +- {se} outside [{lo}, {hi}]"
        );
        if n == 0 {
            assert_eq!(c, 1.0);
        } else {
            assert!(row.curve.c[n - 1] > c, "no decay at k theta L = {x}");
        }
    }
    // The tilts were given as k theta L: they come back.
    let back: Vec<f64> = s.angles.iter().map(|t| t * s.k() * s.thickness).collect();
    for (a, b) in back.iter().zip([0.0, 0.5, 1.0, 1.5, 2.0, 3.0]) {
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }
}

/// Bad study files are refused naming the key.
#[test]
fn bad_studies_name_the_key() {
    for (from, to, field) in [
        ("g = [0.0]", "g = [1.0]", "g[0]"),
        ("g = [0.0]", "g = []", "g"),
        (
            "thickness_um = 30000.0",
            "thickness_um = 3e6",
            "thickness_um",
        ),
        (
            "k_theta_l = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0]",
            "k_theta_l = [0.5, 1.0]",
            "k_theta_l[0]",
        ),
        (
            "k_theta_l = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0]",
            "",
            "angles_mdeg | k_theta_l",
        ),
        (
            "mean_free_path_um = 3000.0",
            "mean_free_path_um = -1.0",
            "mean_free_path_um",
        ),
    ] {
        let text = STUDY.replace(from, to);
        assert_ne!(text, STUDY);
        let e = load_tilt_str(&text, "<test>", "t", &Default::default()).unwrap_err();
        assert!(e.to_string().contains(field), "{field}: {e}");
    }
}
