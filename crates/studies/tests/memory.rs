//! The memory-spectrum study as a library: the embedded studies and their optical depths, the
//! conversions of densities and angles, field-named errors, Eq. 39, and the seeds of the groups.
//! (The end-to-end runs, with their outputs and the physics check against diffusion, are the
//! `speckle` binary's tests: `crates/cli/tests/memory_spectrum.rs`.) Under a second.

use speckle_scene::LoadError;
use speckle_studies::examples;
use speckle_studies::memory::{Study, StudyOverrides, eq39, load_str};
use std::f64::consts::{PI, TAU};

const BASE: &str = r#"
radius_um = 0.01
particle_index = 1.59
host_index = 1.33
wavelengths_um = [0.4, 0.65]
thickness_um = 50.0
optical_depth = 5.0
optical_depth_at_um = 0.4
k_theta_l = [0.0, 1.0, 2.0]
"#;

fn load(text: &str) -> Result<Study, LoadError> {
    load_str(text, "t.toml", "t", &StudyOverrides::default())
}

/// `BASE` with the lines of the keys `remove` removed and `extra` appended.
fn edited(remove: &[&str], extra: &str) -> String {
    let mut s: String = BASE
        .lines()
        .filter(|l| !remove.iter().any(|k| l.starts_with(&format!("{k} ="))))
        .map(|l| format!("{l}\n"))
        .collect();
    s.push_str(extra);
    s
}

fn study(name: &str) -> Study {
    let text = examples::study(name).unwrap();
    load_str(text, name, name, &StudyOverrides::default()).unwrap()
}

#[test]
fn the_small_study_has_the_optical_depths_of_fig_11a() {
    // Rayleigh scattering: OD 20 at 400 nm falls as lambda^-4 (2.9 and 0.78).
    let s = study("fig11a_memory_small");
    let b = s.prepare().unwrap();
    assert_eq!(b.len(), 3);
    let od: Vec<f64> = b.iter().map(|b| b.sigma_t() * s.thickness).collect();
    assert!((od[0] - 20.0).abs() < 1e-9, "{od:?}");
    assert!(
        (od[1] - 20.0 * (0.4f64 / 0.65).powi(4)).abs() < 0.05,
        "{od:?}"
    );
    assert!(
        (od[2] - 20.0 * (0.4f64 / 0.9).powi(4)).abs() < 0.02,
        "{od:?}"
    );
    for b in &b {
        assert!(b.mie.asymmetry().abs() < 0.01);
    }
}

#[test]
fn the_large_study_has_a_mean_optical_depth_of_20() {
    let s = study("fig11b_memory_large");
    let b = s.prepare().unwrap();
    assert_eq!(b.len(), 3);
    let mean = b.iter().map(|b| b.sigma_t() * s.thickness).sum::<f64>() / b.len() as f64;
    assert!((mean - 20.0).abs() < 1e-9, "{mean}");
    for b in &b {
        assert!(b.mie.size_parameter() > 90.0 && b.mie.asymmetry() > 0.8);
    }
}

#[test]
fn density_and_angle_options_convert_as_documented() {
    let s = load(BASE).unwrap();
    // k theta L at the first wavelength: theta = x lambda_1 / (2 pi n_host L).
    let k1 = TAU * 1.33 / 0.4;
    assert!((s.angles[1] * k1 * 50.0 - 1.0).abs() < 1e-12);
    let s = load(&edited(&["k_theta_l"], "angles_deg = [0.0, 0.5]\n")).unwrap();
    assert!((s.angles[1] - 0.5f64.to_radians()).abs() < 1e-15);
    // Volume fraction: N = f / (4/3 pi r^3).
    let s = load(&edited(
        &["optical_depth", "optical_depth_at_um"],
        "volume_fraction = 0.01\n",
    ))
    .unwrap();
    let b = s.prepare().unwrap();
    let n = 0.01 / (4.0 / 3.0 * PI * 1e-6);
    assert!((b[0].density / n - 1.0).abs() < 1e-12);
    assert!((b[0].sigma_s / (n * b[0].mie.c_sca()) - 1.0).abs() < 1e-12);
    assert!((s.volume_fraction(&b) - 0.01).abs() < 1e-15);
}

#[test]
fn bad_fields_are_named() {
    let cases: Vec<(String, &str)> = vec![
        (edited(&[], "colour = 1\n"), "colour"),
        (edited(&["radius_um"], "radius_um = -1.0\n"), "radius_um"),
        (edited(&["radius_um"], ""), "radius_um"),
        (
            edited(&["wavelengths_um"], "wavelengths_um = [0.4, 0.5, -0.6]\n"),
            "wavelengths_um[2]",
        ),
        (
            edited(&["wavelengths_um"], "wavelengths_um = [0.4, \"a\"]\n"),
            "wavelengths_um[1]",
        ),
        (
            edited(&["wavelengths_um"], "wavelengths_um = []\n"),
            "wavelengths_um",
        ),
        (edited(&["host_index"], "host_index = 0.0\n"), "host_index"),
        (
            edited(&["particle_index"], "particle_index = 1.33\n"),
            "particle_index",
        ),
        (
            edited(&[], "particle_index_imag = -0.1\n"),
            "particle_index_imag",
        ),
        (
            edited(&["thickness_um"], "thickness_um = 0.0\n"),
            "thickness_um",
        ),
        (edited(&[], "lateral_factor = 0.5\n"), "lateral_factor"),
        (
            edited(&[], "volume_fraction = 0.1\n"),
            "volume_fraction | optical_depth",
        ),
        (
            edited(&["optical_depth", "optical_depth_at_um"], ""),
            "number_density_per_um3 | volume_fraction | optical_depth | optical_depth_mean",
        ),
        (edited(&["optical_depth_at_um"], ""), "optical_depth_at_um"),
        (
            edited(
                &["optical_depth", "optical_depth_at_um"],
                "optical_depth_mean = 1e9\n",
            ),
            "optical_depth_mean",
        ),
        (
            edited(&["k_theta_l"], "k_theta_l = [0.5, 1.0]\n"),
            "k_theta_l[0]",
        ),
        (
            edited(&["k_theta_l"], "k_theta_l = [0.0, 1.0, 1.0]\n"),
            "k_theta_l[2]",
        ),
        (edited(&["k_theta_l"], "k_theta_l = [0.0]\n"), "k_theta_l"),
        (
            edited(&[], "angles_deg = [0.0, 1.0]\n"),
            "angles_deg | k_theta_l",
        ),
        (
            edited(&["k_theta_l"], "angles_deg = [0.0, 95.0]\n"),
            "angles_deg[1]",
        ),
        (edited(&[], "[render]\ngroups = 1\n"), "render.groups"),
        (edited(&[], "[render]\npaths = 10\n"), "render.paths"),
        (edited(&[], "[render]\nflavour = 1\n"), "render.flavour"),
        (edited(&[], "name = \"a/b\"\n"), "name"),
        (
            edited(&["radius_um"], "radius_um = 1e6\n"),
            "wavelengths_um[0]",
        ),
    ];
    for (text, field) in cases {
        let e = load(&text)
            .and_then(|s| s.prepare())
            .err()
            .unwrap_or_else(|| panic!("{field}: accepted"));
        assert!(
            e.to_string().starts_with(&format!("t.toml: {field}:")),
            "{field}: {e}"
        );
    }
}

#[test]
fn eq39_is_smooth_at_zero_and_vanishes_far_out() {
    assert_eq!(eq39(0.0), 1.0);
    for x in [1e-5, 9.9e-5, 1.01e-4, 1e-3] {
        let exact = (x / f64::sinh(x)).powi(2);
        assert!((eq39(x) - exact).abs() < 1e-15, "{x}");
    }
    assert!((eq39(1.0) - 0.724_061_5).abs() < 1e-6);
    assert_eq!(eq39(1000.0), 0.0);
}

/// The groups are seeded with `derive_seed(seed, w groups + g)`; these values were computed
/// once from the SplitMix64 formula the study used before `derive_seed` existed (its
/// `group_seed`), so a study renders the same numbers as before.
#[test]
fn group_seeds_are_those_of_earlier_versions() {
    use speckle_stats::rng::derive_seed;
    for (seed, index, want) in [
        (1, 0, 0x910a_2dec_8902_5cc1u64),
        (1, 1, 0xbeeb_8da1_658e_ec67),
        (2019, 0, 0x5f33_5bda_79ec_fb6e),
        (2019, 47, 0x556f_ef11_d447_905e),
        (3, 15, 0xcc84_126a_6182_93ea),
        (u64::MAX, 5, 0xd31d_adbd_a438_bb33),
    ] {
        assert_eq!(derive_seed(seed, index), want, "{seed}, {index}");
    }
}
