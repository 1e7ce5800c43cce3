//! End-to-end tests of `speckle memory-spectrum` (Bar et al. 2019, Fig. 11): the outputs and
//! their shapes, bad study files (exit code 2, the field named), cancellation, thread-count
//! independence, and one physics check against diffusion theory (Eq. 39).
//!
//! Run time (release, 2 cores): about 3 s once built, most of it the optical-depth-10 render of
//! `small_particles_at_high_od_follow_the_diffusion_curve`.

mod common;
use common::*;

/// Eq. 39.
fn eq39(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        (x / x.sinh()).powi(2)
    }
}

/// Rayleigh spheres (radius 10 nm, polystyrene in water) in a thin slab; `density` and `rest`
/// complete the study.
fn study(name: &str, density: &str, rest: &str) -> String {
    format!(
        "name = \"{name}\"\nradius_um = 0.01\nparticle_index = 1.59\nhost_index = 1.33\n\
         thickness_um = 1000.0\n{density}\n{rest}\n"
    )
}

/// A fast study: two wavelengths (optical depth 6 at 400 nm, 1.9 at 530 nm), four tilts.
fn fast() -> String {
    study(
        "fast",
        "optical_depth = 6.0\noptical_depth_at_um = 0.4",
        "wavelengths_um = [0.4, 0.53]\nk_theta_l = [0.0, 0.75, 1.5, 3.0]\n\
         [render]\npaths = 24000\nseed = 3\ngroups = 8\n[output]\ndir = \"res\"",
    )
}

#[test]
fn outputs_have_their_shapes_and_the_correlation_decays() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "fast.toml", &fast());
    let o = speckle(dir.path(), &["memory-spectrum", p.to_str().unwrap(), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    let (shape, c) = load_f8(&res.join("fast.memory.npy"));
    assert_eq!(shape, vec![2, 4]);
    let (_, se) = load_f8(&res.join("fast.memory_stderr.npy"));
    let (_, diffusion) = load_f8(&res.join("fast.memory_diffusion.npy"));
    let (_, extrapolated) = load_f8(&res.join("fast.memory_diffusion_extrapolated.npy"));
    let (shape_x, x) = load_f8(&res.join("fast.memory_ktheta_l.npy"));
    let (shape_a, angles) = load_f8(&res.join("fast.memory_angles.npy"));
    assert_eq!((shape_x, shape_a), (vec![2, 4], vec![4]));
    // theta = k theta L / (k_1 L) with k_1 = 2 pi 1.33 / 0.4 per um, in degrees.
    let k1 = std::f64::consts::TAU * 1.33 / 0.4;
    assert!((angles[1].to_radians() * k1 * 1000.0 - 0.75).abs() < 1e-12);
    assert!((x[4 + 3] - 3.0 * 0.4 / 0.53).abs() < 1e-12, "{x:?}");
    for w in 0..2 {
        let row = |v: &[f64], n: usize| v[w * 4 + n];
        // C(0) = |C_00|^2 / C_00^2 = 1 up to rounding, with no error.
        assert!((row(&c, 0) - 1.0).abs() < 1e-12, "{c:?}");
        assert!(row(&se, 0) < 1e-12, "{se:?}");
        for n in 1..4 {
            assert!(row(&se, n) > 0.0 && row(&se, n) < 0.05, "{se:?}");
            assert!(
                row(&c, n) < row(&c, n - 1),
                "wavelength {w}: no decay at {n}: {c:?}"
            );
            assert_eq!(row(&diffusion, n), eq39(row(&x, n)));
            assert!(row(&extrapolated, n) < row(&diffusion, n));
        }
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(res.join("fast.memory.json")).unwrap())
            .unwrap();
    let w = &json["wavelengths"];
    assert_eq!(w.as_array().unwrap().len(), 2);
    // The density was set for optical depth 6 at 400 nm; Rayleigh scattering falls as lambda^-4.
    let od0 = w[0]["optical_depth"].as_f64().unwrap();
    let od1 = w[1]["optical_depth"].as_f64().unwrap();
    assert!((od0 - 6.0).abs() < 1e-9 && (od1 / od0 - (0.4f64 / 0.53).powi(4)).abs() < 0.01);
    assert!(w[0]["size_parameter"].as_f64().unwrap() < 0.25);
    assert!(w[0]["asymmetry_g"].as_f64().unwrap().abs() < 0.01);
    assert_eq!(json["render"]["groups"], 8);
    // The plot: an SVG document with one legend entry per wavelength, and one per line kind
    // (the drawing itself is tested with the library, speckle_studies::plot).
    let svg = std::fs::read_to_string(res.join("fast.memory.svg")).unwrap();
    assert!(svg.starts_with("<?xml") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("\u{3bb} = ").count(), 2);
    assert_eq!(svg.matches("Eq. 39, thickness L").count(), 1);
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "fast.toml", &fast());
    let p = p.to_str().unwrap();
    let mut outputs = Vec::new();
    for t in ["1", "2"] {
        let out = format!("t{t}");
        let o = speckle(
            dir.path(),
            &[
                "memory-spectrum",
                p,
                "-q",
                "--threads",
                t,
                "--paths",
                "4000",
                "--out",
                &out,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        outputs.push(std::fs::read(dir.path().join(out).join("fast.memory.npy")).unwrap());
    }
    assert_eq!(outputs[0], outputs[1]);
}

#[test]
fn bad_studies_name_the_field_and_exit_with_2() {
    let dir = tempfile::tempdir().unwrap();
    let base = fast();
    let replace = |from: &str, to: &str| {
        assert!(base.contains(from), "{from}");
        base.replacen(from, to, 1)
    };
    let cases = [
        (
            replace("[0.4, 0.53]", "[0.4, 0.53, -0.6]"),
            "wavelengths_um[2]",
        ),
        (replace("radius_um = 0.01", "radius_um = 0.0"), "radius_um"),
        (replace("radius_um = 0.01\n", ""), "radius_um"),
        (replace("name =", "colour = 1\nname ="), "colour"),
        (
            replace("seed = 3", "seed = 3\nflavour = 2"),
            "render.flavour",
        ),
        (
            replace("[0.0, 0.75, 1.5, 3.0]", "[0.0, 1.5, 0.75]"),
            "k_theta_l[2]",
        ),
        (
            replace(
                "optical_depth = 6.0",
                "optical_depth = 6.0\nvolume_fraction = 0.1",
            ),
            "volume_fraction | optical_depth",
        ),
        (replace("groups = 8", "groups = 1"), "render.groups"),
    ];
    for (text, field) in cases {
        let p = write(dir.path(), "bad.toml", &text);
        let o = speckle(dir.path(), &["memory-spectrum", p.to_str().unwrap(), "-q"]);
        assert_eq!(o.status.code(), Some(2), "{field}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("bad.toml: {field}")),
            "{field}: {}",
            stderr(&o)
        );
        assert!(!dir.path().join("res").exists());
    }
    let o = speckle(dir.path(), &["memory-spectrum", "missing.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot read the study file"));
}

#[test]
fn a_cancelled_run_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "fast.toml", &fast());
    let o = speckle(
        dir.path(),
        &[
            "memory-spectrum",
            p.to_str().unwrap(),
            "-q",
            "--cancel-after-paths",
            "30000",
        ],
    );
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(stderr(&o).contains("no output was written"));
    assert!(!dir.path().join("res").exists());
}

/// Milne extrapolation length in transport mean free paths.
const MILNE_ZE: f64 = 0.7104;

/// Physics, after tests/memory_effect.rs: Rayleigh spheres (g = 0.0075, phase 1 + cos^2) in a
/// slab of optical depth 10 at 400 nm, 100 times as wide as thick. Diffusion theory (Eq. 39) is
/// the limit `L >> l*`; at finite depth it depends on where the absorbing boundaries are put:
/// at the faces (`L`) or at the Milne extrapolated boundaries (`L + 2 z_e`,
/// `z_e = 0.7104 l*`). Model band: `Eq39(x (L + 2 z_e) / L) <= C(x) <= Eq39(x)`, widened by
/// 4 jackknife SEs and a model tolerance of 0.01 (the Rayleigh phase function and the slab's
/// finite width against the isotropic infinite slab of the test it follows, whose band held
/// without one). The band is narrow (at `k theta L = 1.5` from 0.408 to 0.496), so a wrong
/// wavenumber or tilt scale fails it (a factor 2 in `k theta` moves C(1.5) below 0.1).
///
/// And the cheaper, sharper check: the same spheres at optical depth 1 decorrelate more slowly
/// (the paper's "wider memory effect at low OD"): `C` larger at every `k theta L >= 1` by more
/// than 4 combined SEs (measured: z = 21, 43, 68, 99 at 1, 1.5, 2, 3; at 0.5, where both curves
/// are near 1, only 0.918 against 0.911, z = 4.4, so not checked).
///
/// The slab is 1 mm thick (`k L = 2.1e4`): the cost does not depend on `k L`, but a tilted plane
/// wave also enters a finite slab through its side faces, into a strip of relative width
/// `theta L / W = k theta L / (k W)`, where deep first vertices carry weights up to `e^OD`; at
/// `k L = 420` (a 20 um slab) that strip raised the standard errors six-fold.
#[test]
fn small_particles_at_high_od_follow_the_diffusion_curve() {
    let dir = tempfile::tempdir().unwrap();
    let xs = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0];
    let angles = format!("k_theta_l = [{}]", xs.map(|x| format!("{x:.1}")).join(", "));
    let run = |name: &str, od: f64, paths: u64| {
        let text = study(
            name,
            &format!("optical_depth = {od}\noptical_depth_at_um = 0.4"),
            &format!(
                "wavelengths_um = [0.4]\n{angles}\n[render]\npaths = {paths}\nseed = 11\n\
                 [output]\ndir = \"res\""
            ),
        );
        let p = write(dir.path(), &format!("{name}.toml"), &text);
        let o = speckle(dir.path(), &["memory-spectrum", p.to_str().unwrap(), "-q"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let res = dir.path().join("res");
        let (_, c) = load_f8(&res.join(format!("{name}.memory.npy")));
        let (_, se) = load_f8(&res.join(format!("{name}.memory_stderr.npy")));
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(res.join(format!("{name}.memory.json"))).unwrap(),
        )
        .unwrap();
        let w = &json["wavelengths"][0];
        let transport_od = w["transport_optical_depth"].as_f64().unwrap();
        (c, se, transport_od)
    };
    let (c, se, tod) = run("od10", 10.0, 240_000);
    let leff_over_l = 1.0 + 2.0 * MILNE_ZE / tod;
    const MODEL_TOLERANCE: f64 = 0.01;
    for n in 1..xs.len() {
        let (hi, lo) = (eq39(xs[n]), eq39(xs[n] * leff_over_l));
        eprintln!(
            "OD 10: k theta L = {}: C = {:.4} +- {:.4}; Eq. 39 with L {hi:.4}, with L + 2 z_e \
             {lo:.4}",
            xs[n], c[n], se[n]
        );
        let slack = 4.0 * se[n] + MODEL_TOLERANCE;
        assert!(
            c[n] <= hi + slack && c[n] >= lo - slack,
            "k theta L = {}: C = {} +- {} outside the diffusion band [{lo}, {hi}]",
            xs[n],
            c[n],
            se[n]
        );
        assert!(se[n] < 0.02, "{se:?}");
    }
    let (c1, se1, _) = run("od1", 1.0, 60_000);
    for n in 1..xs.len() {
        let z = (c1[n] - c[n]) / se1[n].hypot(se[n]);
        eprintln!(
            "k theta L = {}: C(OD 1) = {:.4} +- {:.4} > C(OD 10) = {:.4}: z = {z:.1}",
            xs[n], c1[n], se1[n], c[n]
        );
        if xs[n] >= 1.0 {
            assert!(z > 4.0, "k theta L = {}: z = {z}", xs[n]);
        }
    }
}

/// `speckle memory-tilt` (Bar et al. 2023, Fig. 6): its files and their shapes, `C(0) = 1`, the
/// C1 column, and a bad key named with exit code 2 (the physics: `tests/memory_tilt.rs`).
#[test]
fn memory_tilt_writes_its_curves() {
    let dir = tempfile::tempdir().unwrap();
    let study = "wavelength_um = 0.5\nmean_free_path_um = 3000.0\nthickness_um = 6000.0\n\
                 g = [0.0, 0.9]\nk_theta_l = [0.0, 1.0, 2.0]\n\n[render]\npaths = 400\n\
                 groups = 4\n";
    let p = dir.path().join("t.toml");
    std::fs::write(&p, study).unwrap();
    let o = speckle(
        dir.path(),
        &["memory-tilt", p.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    let (shape, c) = load_f8(&out.join("t.memory_tilt.npy"));
    assert_eq!(shape, vec![2, 3]);
    assert_eq!((c[0], c[3]), (1.0, 1.0));
    assert_eq!(load_f8(&out.join("t.memory_tilt_stderr.npy")).0, vec![2, 3]);
    let (_, c1) = load_f8(&out.join("t.memory_tilt_c1.npy"));
    for (x, v) in [0.0, 1.0, 2.0].iter().zip(&c1) {
        assert!((v - eq39(*x)).abs() < 1e-12, "{x}: {v}");
    }
    assert_eq!(load_f8(&out.join("t.memory_tilt_g.npy")).1, vec![0.0, 0.9]);
    assert_eq!(
        load_f8(&out.join("t.memory_tilt_angles_mdeg.npy")).0,
        vec![3]
    );
    assert_eq!(
        load_f8(&out.join("t.memory_tilt_c1_extrapolated.npy")).0,
        vec![2, 3]
    );
    let svg = std::fs::read_to_string(out.join("t.memory_tilt.svg")).unwrap();
    assert!(svg.contains("g = 0.9") && svg.contains("C1 (diffusion)"));
    assert!(out.join("t.memory_tilt.json").exists());
    std::fs::write(&p, study.replace("g = [0.0, 0.9]", "g = [0.0, 1.5]")).unwrap();
    let o = speckle(dir.path(), &["memory-tilt", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("g[1]"), "{}", stderr(&o));
}

/// `speckle tilt-shift` (Bar et al. 2020, Fig. 12): its files and their shapes, `C(0, 0) = 1`,
/// the model column, and a bad key named with exit code 2 (the physics: `tests/tilt_shift.rs`).
#[test]
fn tilt_shift_writes_its_grid() {
    let dir = tempfile::tempdir().unwrap();
    let study = "wavelength_um = 0.5\nmean_free_path_um = 23.0\ng = 0.98\nthickness_um = 20.0\n\
                 width_um = 30.0\nnumerical_aperture = 0.2\ntheta_max_mrad = 100.0\n\
                 n_theta = 3\ndelta_b_max_um = 2.0\nn_delta_b = 5\ntau_max_um = 4.0\n\
                 n_tau = 5\n\n[render]\npaths = 200\ngroups = 2\n";
    let p = dir.path().join("t.toml");
    std::fs::write(&p, study).unwrap();
    let o = speckle(
        dir.path(),
        &["tilt-shift", p.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    let (shape, c) = load_f8(&out.join("t.tilt_shift.npy"));
    assert_eq!(shape, vec![3, 5]);
    assert_eq!(c[7], 1.0);
    assert_eq!(load_f8(&out.join("t.tilt_shift_stderr.npy")).0, vec![3, 5]);
    assert_eq!(
        load_f8(&out.join("t.tilt_shift_complex.npy")).0,
        vec![3, 5, 2]
    );
    let (_, model) = load_f8(&out.join("t.tilt_shift_model.npy"));
    assert_eq!(model[7], 1.0);
    let (_, printed) = load_f8(&out.join("t.tilt_shift_model_printed.npy"));
    // The printed form is the derivation's mirrored in theta.
    for d in 0..5 {
        assert_eq!(printed[d], model[10 + d]);
    }
    assert_eq!(
        load_f8(&out.join("t.tilt_shift_theta_mrad.npy")).1,
        vec![-100.0, 0.0, 100.0]
    );
    assert_eq!(
        load_f8(&out.join("t.tilt_shift_delta_b_um.npy")).1,
        vec![-2.0, -1.0, 0.0, 1.0, 2.0]
    );
    let svg = std::fs::read_to_string(out.join("t.tilt_shift.svg")).unwrap();
    assert!(svg.contains("MC, theta = 100 mrad") && svg.contains("Eq. 50, theta = 0 mrad"));
    assert!(out.join("t.tilt_shift.json").exists());
    std::fs::write(&p, study.replace("n_theta = 3", "n_theta = 4")).unwrap();
    let o = speckle(dir.path(), &["tilt-shift", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("n_theta"), "{}", stderr(&o));
}

/// `speckle refocus` (Bar et al. 2020, Fig. 13 bottom): its files and their shapes, the power 1
/// at `Delta = 0`, the tilts `-3 Delta / (2 L)`, Eq. 50's curves, and a bad key named with exit
/// code 2 (the physics: `tests/refocus.rs`).
#[test]
fn refocus_writes_its_curves() {
    let dir = tempfile::tempdir().unwrap();
    let study = "wavelength_um = 0.5\nmean_free_path_um = 23.0\ng = 0.98\nthickness_um = 20.0\n\
                 width_um = 30.0\nnumerical_aperture = 0.2\ndelta_max_um = 2.0\nn_delta = 3\n\
                 tau_max_um = 4.0\nn_tau = 5\n\n[render]\npaths = 200\ngroups = 2\n";
    let p = dir.path().join("t.toml");
    std::fs::write(&p, study).unwrap();
    let o = speckle(
        dir.path(),
        &["refocus", p.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    assert_eq!(
        load_f8(&out.join("t.refocus_delta_um.npy")).1,
        vec![0.0, 1.0, 2.0]
    );
    for key in ["shift", "tilt"] {
        let (shape, c) = load_f8(&out.join(format!("t.refocus_{key}.npy")));
        assert_eq!(shape, vec![3]);
        assert_eq!(c[0], 1.0);
        assert_eq!(
            load_f8(&out.join(format!("t.refocus_{key}_stderr.npy"))).0,
            vec![3]
        );
        assert_eq!(
            load_f8(&out.join(format!("t.refocus_model_{key}.npy"))).1[0],
            1.0
        );
    }
    assert_eq!(
        load_f8(&out.join("t.refocus_theta_mrad.npy")).1,
        vec![0.0, -75.0, -150.0]
    );
    // Eq. 50: the tilt divides the exponent by 4.
    let shift = load_f8(&out.join("t.refocus_model_shift.npy")).1;
    let tilt = load_f8(&out.join("t.refocus_model_tilt.npy")).1;
    assert!((tilt[2].ln() * 4.0 / shift[2].ln() - 1.0).abs() < 1e-9);
    let svg = std::fs::read_to_string(out.join("t.refocus.svg")).unwrap();
    assert!(svg.contains("shift + tilt (Eq. 52)") && svg.contains("Eq. 50, shift only"));
    assert!(out.join("t.refocus.json").exists());
    std::fs::write(&p, study.replace("n_delta = 3", "n_delta = 1")).unwrap();
    let o = speckle(dir.path(), &["refocus", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("n_delta"), "{}", stderr(&o));
    std::fs::write(&p, study.replace("width_um = 30.0", "width_um = 9.0")).unwrap();
    let o = speckle(dir.path(), &["refocus", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("width_um"), "{}", stderr(&o));
}

/// `speckle refocus --images-only` with an `[images]` section (Fig. 13 top): its files, their
/// shapes, the PNG mosaic and the sidecar; a bad `[images]` key is named with exit code 2, and
/// `--images-only` without the section is refused (the physics: `tests/refocus.rs`).
#[test]
fn refocus_writes_its_images() {
    let dir = tempfile::tempdir().unwrap();
    let study = "wavelength_um = 0.5\nmean_free_path_um = 23.0\ng = 0.98\nthickness_um = 20.0\n\
                 width_um = 30.0\nnumerical_aperture = 0.2\ndelta_max_um = 2.0\nn_delta = 3\n\
                 tau_max_um = 4.0\nn_tau = 5\n\n[render]\npaths = 200\ngroups = 2\n\n[images]\n\
                 delta_um = [1.0]\nhalf_width_um = 2.0\nn_pixels = 5\nn_rows = 3\n\
                 realizations = 3\npaths = 50\n";
    let p = dir.path().join("t.toml");
    std::fs::write(&p, study).unwrap();
    let o = speckle(
        dir.path(),
        &[
            "refocus",
            p.to_str().unwrap(),
            "--out",
            "out",
            "-q",
            "--images-only",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    assert!(!out.join("t.refocus_shift.npy").exists());
    assert_eq!(
        load_f8(&out.join("t.refocus_images.npy")).0,
        vec![3, 3, 3, 5, 2]
    );
    let (shape, power) = load_f8(&out.join("t.refocus_images_power.npy"));
    assert_eq!(shape, vec![3, 3, 3, 5]);
    assert!(power.iter().all(|v| v.is_finite() && *v >= 0.0));
    assert_eq!(
        load_f8(&out.join("t.refocus_images_mean_power.npy")).0,
        vec![3, 3, 5]
    );
    assert_eq!(
        load_f8(&out.join("t.refocus_images_offset_um.npy")).1,
        vec![-2.0, -1.0, 0.0, 1.0, 2.0]
    );
    assert_eq!(
        load_f8(&out.join("t.refocus_images_row_um.npy")).1,
        vec![-1.0, 0.0, 1.0]
    );
    assert_eq!(
        load_f8(&out.join("t.refocus_images_theta_mrad.npy")).1,
        vec![0.0, 0.0, -75.0]
    );
    for key in [
        "check_power",
        "check_var",
        "predicted_power",
        "predicted_var",
    ] {
        let (shape, _) = load_f8(&out.join(format!("t.refocus_images_{key}.npy")));
        assert_eq!(shape, vec![3, 5, 2], "{key}");
    }
    let png = std::fs::read(out.join("t.refocus_images.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("t.refocus.json")).unwrap())
            .unwrap();
    assert_eq!(json["images"]["cases"].as_array().unwrap().len(), 3);
    assert!(json["files"]["images"]["png"]["file"].is_string());
    std::fs::write(&p, study.replace("n_pixels = 5", "n_pixels = 4")).unwrap();
    let o = speckle(dir.path(), &["refocus", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("images.n_pixels"), "{}", stderr(&o));
    std::fs::write(&p, study.replace("delta_um = [1.0]", "delta_um = [3.0]")).unwrap();
    let o = speckle(dir.path(), &["refocus", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("images.delta_um"), "{}", stderr(&o));
    let no_images = &study[..study.find("[images]").unwrap()];
    std::fs::write(&p, no_images).unwrap();
    let o = speckle(
        dir.path(),
        &["refocus", p.to_str().unwrap(), "-q", "--images-only"],
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--images-only"), "{}", stderr(&o));
}
