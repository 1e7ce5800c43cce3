//! End-to-end tests of the `speckle` binary: bad command lines exit with 2, renders write
//! loadable `.npy` and JSON files, and a cancelled render writes nothing (malformed scenes:
//! `malformed.rs`).

use std::path::Path;
use std::process::Command;

mod common;
use common::*;

/// A tiny valid scene: 2 plane waves, a 3 x 2 far-field image (J = 12).
const TINY: &str = r#"
name = "tiny"
wavelength = 1.0

[medium]
size = [8.0, 8.0, 3.0]
mean_free_path = 4.0
albedo = 0.9

[phase]
type = "hg"
g = 0.4

[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 3.0]

[[sensors]]
type = "far_grid"
theta_x_deg = [-5.0, 5.0]
theta_y_deg = [-2.0, 2.0]
nx = 3
ny = 2

[render]
paths = 4000
seed = 5
realizations = 3
paths_per_realization = 500

[output]
dir = "res"
png_realizations = 2
"#;

#[test]
fn bad_command_lines_exit_with_2() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let tiny = tiny.to_str().unwrap();
    for (args, expected) in [
        (vec!["check", "missing.toml"], "cannot read the scene file"),
        (vec!["covariance", tiny, "--paths", "1"], "render.paths"),
        (vec!["intensity", tiny, "--paths", "1"], "render.paths"),
        (vec!["covariance", tiny, "--threads", "0"], "--threads"),
        (
            vec!["fields", tiny, "--realizations", "0"],
            "render.realizations",
        ),
        (vec!["example", "nope"], "no example called"),
        (vec!["render"], "unrecognized subcommand"),
    ] {
        let o = speckle(dir.path(), &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{args:?}: {}", stderr(&o));
    }
    assert!(!dir.path().join("res").exists());
}

/// A parsed `.npy` header: (descr, fortran_order, shape) and the data offset.
fn npy_header(bytes: &[u8]) -> (String, bool, Vec<usize>, usize) {
    assert_eq!(&bytes[..6], b"\x93NUMPY", "magic");
    assert_eq!(bytes[6], 1, "version 1.0");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let offset = 10 + len;
    assert_eq!(offset % 16, 0, "data aligned");
    let h = std::str::from_utf8(&bytes[10..offset]).unwrap();
    assert!(h.ends_with('\n'));
    let field = |key: &str| {
        let start = h.find(&format!("'{key}': ")).unwrap() + key.len() + 4;
        &h[start..]
    };
    let descr = field("descr")[1..].split('\'').next().unwrap().to_string();
    let fortran = field("fortran_order").starts_with("True");
    let shape_text = field("shape");
    let shape = shape_text[1..shape_text.find(')').unwrap()]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    (descr, fortran, shape, offset)
}

/// The shape and the float64 numbers of a `.npy` file of dtype `descr` (`<c16`: re, im, ...).
fn load_npy_as(path: &Path, descr: &str) -> (Vec<usize>, Vec<f64>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (found, fortran, shape, offset) = npy_header(&bytes);
    assert_eq!(found, descr, "{}", path.display());
    assert!(!fortran);
    let per = if descr == "<c16" { 2 } else { 1 };
    let n: usize = shape.iter().product();
    assert_eq!(bytes.len() - offset, 8 * per * n, "{}", path.display());
    let data = bytes[offset..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    (shape, data)
}

/// The shape and the numbers of an int64 `.npy` file.
fn load_i8(path: &Path) -> (Vec<usize>, Vec<i64>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (descr, fortran, shape, offset) = npy_header(&bytes);
    assert_eq!(descr, "<i8", "{}", path.display());
    assert!(!fortran);
    let data = bytes[offset..]
        .chunks_exact(8)
        .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    (shape, data)
}

fn load_npy(path: &Path) -> (Vec<usize>, Vec<(f64, f64)>) {
    let (shape, data) = load_npy_as(path, "<c16");
    (shape, data.chunks_exact(2).map(|c| (c[0], c[1])).collect())
}

fn load_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

#[test]
fn covariance_writes_npy_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let o = speckle(dir.path(), &["covariance", tiny.to_str().unwrap(), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    for kind in ["cov", "cov_single", "cov_multiple", "cov_stderr"] {
        let (shape, data) = load_npy(&res.join(format!("tiny.{kind}.npy")));
        assert_eq!(shape, vec![12, 12], "{kind}");
        assert!(data.iter().all(|(a, b)| a.is_finite() && b.is_finite()));
    }
    let (_, cov) = load_npy(&res.join("tiny.cov.npy"));
    // Intensities are positive and the matrix is Hermitian.
    for i in 0..12 {
        assert!(cov[i * 12 + i].0 > 0.0);
        for j in 0..12 {
            let (a, b) = (cov[i * 12 + j], cov[j * 12 + i]);
            assert!((a.0 - b.0).abs() <= 1e-9 * a.0.abs().max(1.0) && (a.1 + b.1).abs() <= 1e-9);
        }
    }
    let (shape, _) = load_npy(&res.join("tiny.mean.npy"));
    assert_eq!(shape, vec![12]);
    assert!(res.join("tiny.cov.png").exists());
    let meta = load_json(&res.join("tiny.cov.json"));
    assert_eq!(meta["command"], "covariance");
    assert_eq!(meta["render"]["paths"], 4000);
    assert_eq!(meta["render"]["seed"], 5);
    assert_eq!(meta["render"]["coherence"], "forward_and_reversed");
    // The pairs and endpoints are tables beside the sidecar.
    assert_eq!(meta["pairs"]["count"], 12);
    assert_eq!(meta["pairs"]["file"], "tiny.cov.pairs.npy");
    let (shape, pairs) = load_i8(&res.join("tiny.cov.pairs.npy"));
    assert_eq!(shape, vec![12, 2]);
    assert_eq!(&pairs[14..16], &[1, 1], "pair 7: source 1, sensor 1");
    assert_eq!(meta["sources"]["count"], 2);
    assert_eq!(meta["sensors"]["count"], 6);
    let (shape, _) = load_npy_as(&res.join("tiny.cov.sensors.npy"), "<f8");
    assert_eq!(shape, vec![6, 7]);
    assert_eq!(meta["scene"]["medium"]["mean_free_path"], 4.0);
    assert_eq!(meta["derived"]["pairs"], 12);
    assert!(meta["summary"]["mean_diagonal_total"].as_f64().unwrap() > 0.0);
    assert!(meta["reproducibility"]["speckle_cli_version"].is_string());
    // No temporary file is left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&res)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let tiny = tiny.to_str().unwrap();
    for (threads, out) in [("1", "t1"), ("2", "t2"), ("3", "t3")] {
        let o = speckle(
            dir.path(),
            &["covariance", tiny, "-q", "--threads", threads, "--out", out],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let a = std::fs::read(dir.path().join("t1/tiny.cov.npy")).unwrap();
    for out in ["t2", "t3"] {
        let b = std::fs::read(dir.path().join(out).join("tiny.cov.npy")).unwrap();
        assert!(a == b, "{out} differs from t1");
    }
}

#[test]
fn fields_single_and_mean_write_their_files() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let tiny = tiny.to_str().unwrap();
    let o = speckle(dir.path(), &["fields", tiny, "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    let (shape, _) = load_npy(&res.join("tiny.fields.npy"));
    assert_eq!(shape, vec![3, 2, 6]);
    // PNGs for the first two realizations and both illuminations, none for the third.
    for r in 0..3 {
        for s in 0..2 {
            let p = res.join(format!("tiny.r{r}.s{s}.png"));
            assert_eq!(p.exists(), r < 2, "{}", p.display());
        }
    }
    let png = std::fs::read(res.join("tiny.r0.s0.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let meta = load_json(&res.join("tiny.fields.json"));
    assert_eq!(meta["render"]["realizations"], 3);
    assert_eq!(meta["sensor_grid"]["nx"], 3);
    assert_eq!(meta["sensor_grid"]["ny"], 2);

    let o = speckle(dir.path(), &["single", tiny, "-q", "--paths", "500"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&res.join("tiny.single.npy"));
    assert_eq!(shape, vec![12, 12]);
    assert_eq!(
        load_json(&res.join("tiny.single.json"))["render"]["paths"],
        500
    );

    let o = speckle(dir.path(), &["mean", tiny, "--out", "m"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&dir.path().join("m/tiny.mean.npy"));
    assert_eq!(shape, vec![12]);

    // Explicit pairs give a (R, J) field array.
    let explicit = TINY.replace(
        "wavelength = 1.0",
        "wavelength = 1.0\npairs = [[0, 0], [1, 5]]",
    );
    let p = write(dir.path(), "explicit.toml", &explicit);
    let o = speckle(
        dir.path(),
        &["fields", p.to_str().unwrap(), "-q", "--out", "e"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&dir.path().join("e/tiny.fields.npy"));
    assert_eq!(shape, vec![3, 2]);
}

#[test]
fn a_cancelled_render_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let tiny = tiny.to_str().unwrap();
    for args in [
        vec!["covariance", tiny, "--paths", "2000000"],
        vec!["intensity", tiny, "--paths", "20000000"],
        vec!["single", tiny, "--paths", "20000000"],
        vec!["fields", tiny, "--realizations", "64"],
    ] {
        let mut args = args;
        args.extend(["-q", "--cancel-after-paths", "1"]);
        let o = speckle(dir.path(), &args);
        assert_eq!(o.status.code(), Some(130), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("no output was written"),
            "{}",
            stderr(&o)
        );
        assert!(!dir.path().join("res").exists(), "{args:?} wrote output");
    }
}

#[cfg(unix)]
#[test]
fn ctrl_c_stops_a_render_and_writes_nothing() {
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let mut child = Command::new(env!("CARGO_BIN_EXE_speckle"))
        .args(["covariance", tiny.to_str().unwrap(), "-q"])
        .args(["--paths", "1000000000"])
        .current_dir(dir.path())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(700));
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(kill.success());
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "the render did not stop"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(status.code(), Some(130));
    assert!(!dir.path().join("res").exists());
}

#[test]
fn every_example_prints_and_checks() {
    let dir = tempfile::tempdir().unwrap();
    let o = speckle(dir.path(), &["example", "--list"]);
    assert!(o.status.success());
    let names: Vec<String> = stdout(&o).lines().map(str::to_string).collect();
    assert!(names.len() >= 5 && names[0] == "default", "{names:?}");
    for name in &names {
        let o = speckle(dir.path(), &["example", name]);
        assert!(o.status.success());
        // The embedded text is the file in scenes/ (or in crates/scene/scenes/).
        let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
        let file = [
            crate_dir.join("../../scenes"),
            crate_dir.join("../scene/scenes"),
        ]
        .iter()
        .map(|d| d.join(format!("{name}.toml")))
        .find(|f| f.exists())
        .unwrap_or_else(|| panic!("no scene file for the example {name}"));
        assert_eq!(stdout(&o), std::fs::read_to_string(&file).unwrap());
        let p = write(dir.path(), &format!("{name}.toml"), &stdout(&o));
        let o = speckle(dir.path(), &["check", p.to_str().unwrap()]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
    }
}

/// A tiny flatland scene: 2 tilted plane waves (default +y about +z), a 5-direction far arc with
/// default centre and axis, and a point sensor (J = 12); an asymmetric table with the mu-diff
/// header names.
const TINY_2D: &str = r#"
name = "flat"
dimension = 2
wavelength = 1.0

[medium]
size = [6.0, 6.0, 0.0]
mean_free_path = 3.0
albedo = 0.9

[phase]
type = "tabulated"
file = "amp.csv"

[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 10.0]

[[sensors]]
type = "far_arc"
angles_deg = [90.0, 270.0]
n = 5

[[sensors]]
type = "point"
position = [0.0, 10.0, 0.0]

[render]
paths = 3000
seed = 3

[output]
dir = "res"
"#;

#[test]
fn flatland_intensity_writes_float64_arrays_and_far_arc_angles() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "amp.csv",
        "theta_rad,re_s,im_s\n0,1,0\n1.5,0.8,0.3\n3.14159,0.3,0\n4.5,0.2,-0.1\n",
    );
    let p = write(dir.path(), "flat.toml", TINY_2D);
    let p = p.to_str().unwrap();
    let o = speckle(dir.path(), &["intensity", p, "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    let (shape, intensity) = load_npy_as(&res.join("flat.intensity.npy"), "<f8");
    assert_eq!(shape, vec![2, 6]);
    assert!(
        intensity.iter().all(|v| v.is_finite() && *v > 0.0),
        "{intensity:?}"
    );
    let (shape, se) = load_npy_as(&res.join("flat.intensity_stderr.npy"), "<f8");
    assert_eq!(shape, vec![2, 6]);
    assert!(se.iter().zip(&intensity).all(|(s, v)| *s > 0.0 && s < v));
    let (shape, single) = load_npy_as(&res.join("flat.intensity_single.npy"), "<f8");
    assert_eq!(shape, vec![2, 6]);
    assert!(single.iter().all(|v| v.is_finite()));

    let meta = load_json(&res.join("flat.intensity.json"));
    assert_eq!(meta["command"], "intensity");
    assert_eq!(meta["derived"]["dimension"], 2);
    assert_eq!(meta["files"]["intensity"], "flat.intensity.npy");
    assert_eq!(
        meta["files"]["intensity_stderr"],
        "flat.intensity_stderr.npy"
    );
    assert_eq!(meta["render"]["paths"], 3000);
    assert!(
        meta["units"]["far_field_sensor"]
            .as_str()
            .unwrap()
            .contains("sqrt(R)")
    );
    // The defaults are recorded: +y tilted about +z.
    assert_eq!(
        meta["scene"]["sources"][0]["direction"],
        serde_json::json!([0.0, 1.0, 0.0])
    );
    assert_eq!(
        meta["scene"]["sensors"][0]["axis"],
        serde_json::json!([0.0, 0.0, 1.0])
    );
    // Rows of the endpoint tables: entry, kind, x, y, z, p, q.
    let (shape, sources) = load_npy_as(&res.join("flat.intensity.sources.npy"), "<f8");
    assert_eq!(shape, vec![2, 7]);
    let tilted = &sources[7 + 2..7 + 5];
    let a = 10f64.to_radians();
    assert!((tilted[0] + a.sin()).abs() < 1e-12, "{tilted:?}");
    // The arc: +y rotated counter-clockwise by 90, 135, ..., 270 degrees, then the point.
    let (shape, sensors) = load_npy_as(&res.join("flat.intensity.sensors.npy"), "<f8");
    assert_eq!(shape, vec![6, 7]);
    for k in 0..5 {
        let s = &sensors[7 * k..7 * k + 7];
        let deg = 90.0 + 45.0 * k as f64;
        assert_eq!(s[1], 2.0, "far field: {s:?}");
        assert_eq!(s[5], deg, "{s:?}");
        assert_eq!(s[6], k as f64);
        let (sin, cos) = deg.to_radians().sin_cos();
        assert!(
            (s[2] + sin).abs() < 1e-12 && (s[3] - cos).abs() < 1e-12,
            "{s:?}"
        );
        assert_eq!(s[4], 0.0);
    }
    assert_eq!(sensors[7 * 5 + 1], 1.0, "a point sensor");

    // The same seed gives the covariance's diagonal exactly.
    let o = speckle(
        dir.path(),
        &["covariance", p, "-q", "--out", "c", "--no-png"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, cov) = load_npy(&dir.path().join("c/flat.cov.npy"));
    for (j, v) in intensity.iter().enumerate() {
        assert_eq!(cov[j * 12 + j].0, *v, "pair {j}");
    }

    // Explicit pairs give a (J,) array.
    let explicit = TINY_2D.replace(
        "wavelength = 1.0",
        "wavelength = 1.0\npairs = [[0, 0], [1, 5], [1, 2]]",
    );
    let p = write(dir.path(), "explicit.toml", &explicit);
    let o = speckle(
        dir.path(),
        &[
            "intensity",
            p.to_str().unwrap(),
            "-q",
            "--out",
            "e",
            "--paths",
            "500",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy_as(&dir.path().join("e/flat.intensity_stderr.npy"), "<f8");
    assert_eq!(shape, vec![3]);
}

#[test]
fn intensity_of_a_sensor_grid_writes_an_image_per_source() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let o = speckle(
        dir.path(),
        &["intensity", tiny.to_str().unwrap(), "-q", "--paths", "500"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    let (shape, _) = load_npy_as(&res.join("tiny.intensity.npy"), "<f8");
    assert_eq!(shape, vec![2, 6]);
    for s in 0..2 {
        let png = std::fs::read(res.join(format!("tiny.intensity.s{s}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    }
    let meta = load_json(&res.join("tiny.intensity.json"));
    assert_eq!(meta["derived"]["dimension"], 3);
    assert_eq!(meta["files"]["png"]["files"].as_array().unwrap().len(), 2);
}

/// A tiny flatland scene for the wave solver: a 10 x 4 wavelength box, mean free path 4
/// (about 16 isotropic scatterers per configuration), a plane wave, 3 far-field directions.
const WAVE_2D: &str = r#"
name = "wave2d"
dimension = 2
wavelength = 1.0

[medium]
size = [10.0, 4.0, 0.0]
mean_free_path = 4.0

[[sources]]
type = "plane"
direction = [0.0, 1.0, 0.0]

[[sensors]]
type = "far_arc"
angles_deg = [-20.0, 20.0]
n = 3

[render]
paths = 2000
seed = 9
configurations = 20

[output]
dir = "res"
"#;

#[test]
fn wave_writes_npy_and_json_independent_of_threads() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "wave2d.toml", WAVE_2D);
    let p = p.to_str().unwrap();
    for (threads, out) in [("1", "t1"), ("2", "t2")] {
        let o = speckle(
            dir.path(),
            &["wave", p, "-q", "--threads", threads, "--out", out],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let res = dir.path().join("t1");
    let arrays = [
        ("wave_cov", vec![3, 3]),
        ("wave_cov_stderr", vec![3, 3]),
        ("wave_mean", vec![3]),
        ("wave_mean_stderr", vec![3]),
        ("wave_fields", vec![20, 1, 3]),
    ];
    for (kind, want) in &arrays {
        let file = format!("wave2d.{kind}.npy");
        let (shape, data) = load_npy(&res.join(&file));
        assert_eq!(&shape, want, "{kind}");
        assert!(data.iter().all(|(a, b)| a.is_finite() && b.is_finite()));
        let other = std::fs::read(dir.path().join("t2").join(&file)).unwrap();
        assert!(
            std::fs::read(res.join(&file)).unwrap() == other,
            "{file} depends on the thread count"
        );
    }
    // A covariance: Hermitian with positive intensities.
    let (_, cov) = load_npy(&res.join("wave2d.wave_cov.npy"));
    for i in 0..3 {
        assert!(cov[i * 3 + i].0 > 0.0 && cov[i * 3 + i].1 == 0.0);
        for j in 0..3 {
            let (a, b) = (cov[i * 3 + j], cov[j * 3 + i]);
            assert!((a.0 - b.0).abs() <= 1e-12 * a.0.abs().max(1.0) && (a.1 + b.1).abs() <= 1e-12);
        }
    }
    assert!(res.join("wave2d.wave_cov.png").exists());
    let meta = load_json(&res.join("wave2d.wave.json"));
    assert_eq!(meta["command"], "wave");
    assert_eq!(meta["render"]["configurations"], 20);
    assert_eq!(meta["render"]["seed"], 9);
    assert_eq!(meta["files"]["wave_cov"], "wave2d.wave_cov.npy");
    // n |V| = sigma_s |V| / (4 / k) = 0.25 * 40 * 2 pi / 4 = 5 pi.
    let expected = meta["render"]["expected_scatterers"].as_f64().unwrap();
    assert!(
        (expected - 5.0 * std::f64::consts::PI).abs() < 1e-9,
        "{expected}"
    );
    let mean = meta["render"]["mean_scatterers"].as_f64().unwrap();
    assert!(mean > 0.5 * expected && mean < 1.5 * expected, "{mean}");
    let leftovers: Vec<_> = std::fs::read_dir(&res)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");

    // Without -q, the cost is announced before solving.
    let o = speckle(dir.path(), &["wave", p, "--no-png", "--out", "t3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("about 15.7 scatterers"),
        "{}",
        stdout(&o)
    );
    assert!(!dir.path().join("t3/wave2d.wave_cov.png").exists());

    // The Monte Carlo covariance has the same pairs in the same order.
    let o = speckle(dir.path(), &["covariance", p, "-q", "--out", "t1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&res.join("wave2d.cov.npy"));
    assert_eq!(shape, vec![3, 3]);

    // A sensor grid gives intensity images of the first `png_realizations` configurations.
    let iso = TINY
        .replace("albedo = 0.9\n", "")
        .replace("type = \"hg\"\ng = 0.4", "type = \"isotropic\"");
    let g = write(dir.path(), "grid.toml", &iso);
    let args = ["wave", g.to_str().unwrap(), "-q", "--configurations", "3"];
    let o = speckle(dir.path(), &[&args[..], &["--out", "g"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&dir.path().join("g/tiny.wave_fields.npy"));
    assert_eq!(shape, vec![3, 2, 6]);
    for r in 0..3 {
        for s in 0..2 {
            let png = dir.path().join(format!("g/tiny.wave.r{r}.s{s}.png"));
            assert_eq!(png.exists(), r < 2, "{}", png.display());
        }
    }

    // A cancelled wave render writes nothing.
    let o = speckle(
        dir.path(),
        &[
            "wave",
            p,
            "-q",
            "--configurations",
            "100000",
            "--cancel-after-paths",
            "1",
        ],
    );
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(!dir.path().join("res").exists());
}

#[test]
fn wave_rejects_what_it_does_not_model_and_names_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            WAVE_2D.replace(
                "mean_free_path = 4.0",
                "mean_free_path = 4.0\n[phase]\ntype = \"hg\"\ng = 0.3",
            ),
            vec![],
            "wave2d.toml: phase: the wave solver models isotropic point scatterers",
        ),
        (
            WAVE_2D.replace("mean_free_path = 4.0", "sigma_s = 0.25\nsigma_a = 0.01"),
            vec![],
            "wave2d.toml: medium.sigma_a: must be 0",
        ),
        (
            WAVE_2D.replace("configurations = 20", "configurations = 1"),
            vec![],
            "render.configurations: must be >= 2",
        ),
        (
            WAVE_2D.to_string(),
            vec!["--configurations", "1"],
            "render.configurations: must be >= 2",
        ),
        (
            WAVE_2D.replace("[10.0, 4.0, 0.0]", "[1000.0, 1000.0, 0.0]"),
            vec![],
            "wave2d.toml: medium: the box holds",
        ),
    ];
    for (text, extra, expected) in cases {
        let p = write(dir.path(), "wave2d.toml", &text);
        let mut args = vec!["wave", p.to_str().unwrap(), "-q"];
        args.extend(extra);
        let o = speckle(dir.path(), &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{expected}: {}", stderr(&o));
    }
    assert!(!dir.path().join("res").exists());
}
