//! End to end: the path-traced commands (covariance, intensity, fields) render scenes with
//! Gaussian-beam sources and sensors (near-field connections, Bar et al. 2020), and `mean` and
//! the means written beside them are the closed-form near-field means; so does `g1` with
//! moving scatterers.

mod common;
use common::*;

const SCENE: &str = include_str!("../../fuzz/corpus/gaussian_beams_isotropic.toml");

#[test]
fn covariance_and_intensity_render_gaussian_beams() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "g.toml", SCENE);
    let s = scene.to_str().unwrap();
    for command in ["covariance", "intensity"] {
        let o = speckle(dir.path(), &[command, s, "--out", "out", "-q", "--no-png"]);
        assert!(o.status.success(), "{command}: {}", stderr(&o));
        assert!(!stderr(&o).contains("NaN"), "{}", stderr(&o));
    }
    let out = dir.path().join("out");
    let cov = npy_f64(&out.join("gaussian_beams_isotropic.cov.npy"));
    let intensity = npy_f64(&out.join("gaussian_beams_isotropic.intensity.npy"));
    // J = 2 pairs: a 2 x 2 complex covariance whose diagonal is the intensity, bitwise.
    assert_eq!((cov.len(), intensity.len()), (8, 2));
    for j in 0..2 {
        assert_eq!(
            cov[2 * (3 * j)].to_bits(),
            intensity[j].to_bits(),
            "pair {j}"
        );
        assert!(intensity[j] > 0.0 && intensity[j].is_finite());
    }
    // The near-field means (beam to beam, point to beam): finite, and those of `speckle mean`.
    let mean = npy_f64(&out.join("gaussian_beams_isotropic.mean.npy"));
    assert!(
        mean.iter().all(|m| m.is_finite()) && mean.iter().any(|m| *m != 0.0),
        "{mean:?}"
    );
    let o = speckle(dir.path(), &["mean", s, "--out", "m"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let alone = npy_f64(
        &dir.path()
            .join("m")
            .join("gaussian_beams_isotropic.mean.npy"),
    );
    assert_eq!(alone, mean);
    // Moving scatterers: g1 renders the beams, its zero lag bitwise the intensity, and the
    // correlation decays.
    let motion = "\n[motion]\ndiffusion = 0.01\nlags = [0.0, 1.0, 4.0]\n";
    let moving = write(dir.path(), "gm.toml", &format!("{SCENE}{motion}"));
    let o = speckle(
        dir.path(),
        &["g1", moving.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let c = npy_f64(&out.join("gaussian_beams_isotropic.correlation.npy"));
    for j in 0..2 {
        let at = |l: usize| (c[2 * (3 * j + l)], c[2 * (3 * j + l) + 1]);
        assert_eq!(at(0).0.to_bits(), intensity[j].to_bits(), "pair {j}");
        let norm = |(re, im): (f64, f64)| (re * re + im * im).sqrt();
        assert!(
            norm(at(2)) < norm(at(1)) && norm(at(1)) < at(0).0,
            "pair {j}: {c:?}"
        );
    }
}

#[test]
fn fields_render_gaussian_beams() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "g.toml", SCENE);
    let s = scene.to_str().unwrap();
    let o = speckle(dir.path(), &["fields", s, "--out", "out", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    // R = 8 realizations (the default) of 2 sources x 1 sensor, complex: 32 values.
    let f = npy_f64(&out.join("gaussian_beams_isotropic.fields.npy"));
    assert_eq!(f.len(), 2 * 8 * 2);
    assert!(f.iter().all(|x| x.is_finite()) && f.iter().any(|x| *x != 0.0));
    // Images are drawn of sensor grids only; there is no grid of Gaussian sensors yet.
    assert!(!out.join("gaussian_beams_isotropic.r0.s0.png").exists());
    // On 1 and 3 threads: bitwise the same fields.
    let one = speckle(
        dir.path(),
        &[
            "fields",
            s,
            "--out",
            "o1",
            "-q",
            "--no-png",
            "--threads",
            "1",
        ],
    );
    let three = speckle(
        dir.path(),
        &[
            "fields",
            s,
            "--out",
            "o3",
            "-q",
            "--no-png",
            "--threads",
            "3",
        ],
    );
    assert!(one.status.success() && three.status.success());
    let read = |d: &str| {
        std::fs::read(
            dir.path()
                .join(d)
                .join("gaussian_beams_isotropic.fields.npy"),
        )
        .unwrap()
    };
    assert_eq!(read("o1"), read("o3"));
    assert_eq!(
        read("o1"),
        std::fs::read(out.join("gaussian_beams_isotropic.fields.npy")).unwrap()
    );
}

#[test]
fn fields_add_the_near_field_mean() {
    let dir = tempfile::tempdir().unwrap();
    let text = SCENE.replace("add_mean = false", "add_mean = true");
    let scene = write(dir.path(), "g.toml", &text);
    let s = scene.to_str().unwrap();
    let o = speckle(dir.path(), &["fields", s, "--out", "out", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = speckle(dir.path(), &["mean", s, "--out", "m"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    let mean = npy_f64(&out.join("gaussian_beams_isotropic.mean.npy"));
    let alone = npy_f64(
        &dir.path()
            .join("m")
            .join("gaussian_beams_isotropic.mean.npy"),
    );
    assert_eq!(mean, alone);
    assert!(mean.iter().all(|m| m.is_finite()));
}

/// A `gaussian_grid` sensor image: `speckle fields` writes one PNG per realization and source,
/// with the near-field mean added (the scene's default).
#[test]
fn gaussian_grid_fields_draw_images() {
    let dir = tempfile::tempdir().unwrap();
    let text = include_str!("../../fuzz/corpus/gaussian_grid.toml");
    let scene = write(dir.path(), "g.toml", text);
    let s = scene.to_str().unwrap();
    let o = speckle(dir.path(), &["fields", s, "--out", "out", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    // R = 4 realizations of 1 source x 12 sensors, complex.
    let f = npy_f64(&out.join("gaussian_grid.fields.npy"));
    assert_eq!(f.len(), 2 * 4 * 12);
    assert!(f.iter().all(|x| x.is_finite()));
    let mean = npy_f64(&out.join("gaussian_grid.mean.npy"));
    assert_eq!(mean.len(), 2 * 12);
    assert!(mean.iter().all(|x| x.is_finite()));
    for r in 0..4 {
        let png = std::fs::read(out.join(format!("gaussian_grid.r{r}.s0.png"))).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }
    let sidecar = std::fs::read_to_string(out.join("gaussian_grid.fields.json")).unwrap();
    assert!(sidecar.contains("\"gaussian_grid\""), "{sidecar}");
}

/// `speckle bruteforce` (Bar et al. 2020, Fig. 7, Tables 1-2): its files, their sizes, the
/// runtime table in the sidecar, and a bad key named with exit code 2 (the physics:
/// `tests/nearfield_bruteforce.rs`).
#[test]
fn bruteforce_writes_its_entries_and_table() {
    let dir = tempfile::tempdir().unwrap();
    let study = "size = [8.0, 4.0]\nmean_free_path = 8.0\nconcentration = 20.0\n\
                 source_offset = 1.0\nsensor_shift = 0.5\nnodes = 24\nbinary_nodes = 8\n\
                 theta_max = 1.5\n\n[render]\npaths = 400\nnear_paths = 400\nchunk = 150\n\
                 biased_paths = 200\ntiming_paths = 80\n";
    let p = write(dir.path(), "t.toml", study);
    let o = speckle(
        dir.path(),
        &["bruteforce", p.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("speed-up"), "{}", stdout(&o));
    let out = dir.path().join("out");
    for (key, len) in [
        ("near", 2 * 72),
        ("near_stderr", 2 * 72),
        ("far", 72),
        ("far_stderr", 72),
        ("z", 72),
        ("far_binary", 72),
        ("far_binary_stderr", 72),
        ("far_biased", 72),
        ("far_biased_stderr", 72),
        ("binary_minus_apodized", 72),
        ("binary_minus_apodized_stderr", 72),
        ("biased_minus_apodized", 72),
        ("biased_minus_apodized_stderr", 72),
        ("z_binary", 72),
        ("z_biased", 72),
    ] {
        let v = npy_f64(&out.join(format!("t.bruteforce_{key}.npy")));
        assert_eq!(v.len(), len, "{key}");
        assert!(v.iter().all(|x| x.is_finite()), "{key}: {v:?}");
    }
    // The diagonal (entry 0, real part) is an intensity.
    assert!(npy_f64(&out.join("t.bruteforce_far.npy"))[0] > 0.0);
    assert!(npy_f64(&out.join("t.bruteforce_far_binary.npy"))[0] > 0.0);
    assert!(npy_f64(&out.join("t.bruteforce_far_biased.npy"))[0] > 0.0);
    assert!(npy_f64(&out.join("t.bruteforce_near.npy"))[0] > 0.0);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("t.bruteforce.json")).unwrap())
            .unwrap();
    assert_eq!(json["table"].as_array().unwrap().len(), 3);
    assert_eq!(json["plane_waves"]["sensor"], 48);
    assert_eq!(json["render"]["biased_reference_paths"], 200);
    assert!(json["binary_aperture"]["half_width_rad"].as_f64().unwrap() > 0.0);
    assert_eq!(
        json["files"]["bruteforce_near"]["shape"],
        serde_json::json!([2, 6, 6, 2])
    );
    assert!(
        std::fs::read_to_string(out.join("t.bruteforce.svg"))
            .unwrap()
            .contains("binary aperture")
    );
    // The same numbers on 3 threads.
    let o = speckle(
        dir.path(),
        &[
            "bruteforce",
            p.to_str().unwrap(),
            "--out",
            "out3",
            "--threads",
            "3",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for key in [
        "near",
        "near_stderr",
        "far",
        "far_stderr",
        "z",
        "far_binary",
        "far_biased",
        "biased_minus_apodized",
    ] {
        let file = format!("t.bruteforce_{key}.npy");
        assert_eq!(
            std::fs::read(out.join(&file)).unwrap(),
            std::fs::read(dir.path().join("out3").join(&file)).unwrap(),
            "{key}"
        );
    }
    let p = write(
        dir.path(),
        "t.toml",
        &study.replace("nodes = 24", "nodes = 2"),
    );
    let o = speckle(dir.path(), &["bruteforce", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("nodes"), "{}", stderr(&o));
}

/// `speckle sampling-gain` (Bar et al. 2020, Figs. 9-10): its files and their shapes, one plot
/// per case, and a bad key named with exit code 2 (the physics: `tests/nearfield_sampling.rs`).
#[test]
fn sampling_gain_writes_its_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let study = "[[cases]]\nname = \"box\"\nsize = [4.0, 2.0]\nmean_free_path = 2.0\n\
                 amplitude = [[0.0, 0.2], [6.0, 1.0]]\nreflection = true\n\n\
                 [[cases]]\nname = \"flat\"\ndimension = 2\nsize = [6.0, 2.0]\n\
                 mean_free_path = 2.0\n\n\
                 [render]\npaths = 400\nsteps = 2\nreference_paths = 400\n";
    let p = write(dir.path(), "s.toml", study);
    let o = speckle(
        dir.path(),
        &["sampling-gain", p.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    assert_eq!(
        npy_f64(&out.join("s.sampling_paths.npy")),
        vec![100.0, 400.0]
    );
    for key in ["seconds", "rmse", "stderr", "median_relative_stderr"] {
        let v = npy_f64(&out.join(format!("s.sampling_{key}.npy")));
        assert_eq!(v.len(), 2 * 3 * 2, "{key}");
        assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "{key}: {v:?}");
    }
    // Gains over the first strategy ("off"): 1 for itself.
    let g = npy_f64(&out.join("s.sampling_gain.npy"));
    assert_eq!(g.len(), 2 * 3 * 2);
    assert_eq!((g[0], g[1], g[6], g[7]), (1.0, 1.0, 1.0, 1.0));
    for c in 0..2 {
        let svg = std::fs::read_to_string(out.join(format!("s.sampling_gain.{c}.svg"))).unwrap();
        assert!(svg.contains("position_and_direction RMSE"));
    }
    assert!(out.join("s.sampling_gain.json").exists());
    // The same numbers on 1 thread.
    let o = speckle(
        dir.path(),
        &[
            "sampling-gain",
            p.to_str().unwrap(),
            "--out",
            "out1",
            "--threads",
            "1",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for key in ["rmse", "stderr", "median_relative_stderr"] {
        let file = format!("s.sampling_{key}.npy");
        assert_eq!(
            std::fs::read(out.join(&file)).unwrap(),
            std::fs::read(dir.path().join("out1").join(&file)).unwrap(),
            "{key}"
        );
    }
    let p = write(
        dir.path(),
        "s.toml",
        &study.replace("dimension = 2", "dimension = 2\namplitude = [[1.0, 1.0]]"),
    );
    let o = speckle(dir.path(), &["sampling-gain", p.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cases[1].amplitude"), "{}", stderr(&o));
}
