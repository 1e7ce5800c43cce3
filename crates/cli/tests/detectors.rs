//! End-to-end tests of detector sensors (fibres, issue 25): `speckle g1` and `speckle
//! intensity` render them, with `C(0)` of `g1` bitwise the intensity of the same seed; the other
//! commands refuse them naming `sensors`; bad input exits with code 2 naming the field.

mod common;
use common::*;

/// The tissue-like cube with a point source and a fibre on the face `z = 0`; `{detector}` is
/// replaced by the detector's keys and `{medium}` by extra medium keys.
const SCENE: &str = r#"
name = "f"
wavelength = 500e-7

[medium]
size = [1.0, 1.0, 1.0]
center = [0.0, 0.0, 0.5]
sigma_s = 20.0
sigma_a = 0.1
{medium}

[phase]
type = "hg"
g = 0.8

[[sources]]
type = "point"
position = [-0.1, 0.0, 0.0]

[[sensors]]
type = "detector"
{detector}

[motion]
diffusion = 1e-7
lags = [0.0, 1e-6, 1e-5]

[render]
paths = 20000
seed = 4
"#;

const FIBRE: &str = "position = [0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 0.5";

fn scene(detector: &str, medium: &str) -> String {
    SCENE
        .replace("{detector}", detector)
        .replace("{medium}", medium)
}

/// A point detector (no radius): the fluence at the point.
const POINT: &str = "position = [0.1, 0.0, 0.0]\nweighting = \"fluence\"";

#[test]
fn g1_and_intensity_render_detectors_and_agree_at_lag_zero() {
    for detector in [FIBRE, POINT] {
        let dir = tempfile::tempdir().unwrap();
        let s = write(dir.path(), "f.toml", &scene(detector, ""));
        let s = s.to_str().unwrap();
        let o = speckle(dir.path(), &["g1", s, "--out", "out", "-q"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let o = speckle(dir.path(), &["intensity", s, "--out", "out", "-q"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = dir.path().join("out");
        let c = npy_f64(&out.join("f.correlation.npy"));
        let i = npy_f64(&out.join("f.intensity.npy"));
        let g = npy_f64(&out.join("f.g1.npy"));
        // Complex arrays read as (re, im) pairs.
        assert_eq!(c[0], i[0], "{detector}: C(0) is the reading");
        assert!(i[0] > 0.0);
        assert_eq!((g[0], g[1]), (1.0, 0.0));
        assert!(g[2] < 1.0 && g[4] < g[2] && g[4] > 0.0, "{detector}: {g:?}");
    }
}

#[test]
fn field_commands_refuse_detectors_naming_sensors() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(dir.path(), "f.toml", &scene(FIBRE, ""));
    let s = s.to_str().unwrap();
    for cmd in [
        "covariance",
        "fields",
        "mean",
        "single",
        "wave",
        "map",
        "tracking",
    ] {
        let o = speckle(dir.path(), &[cmd, s, "--out", "out", "-q"]);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("f.toml: sensors: the sensors are detectors"),
            "{cmd}: {}",
            stderr(&o)
        );
    }
    assert!(!dir.path().join("out").exists());
}

#[test]
fn bad_detectors_exit_2_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.0",
            "",
            "sensors[0].radius",
        ),
        (
            "position = [0.1, 0.0, 0.2]\nweighting = \"fluence\"",
            "",
            "sensors[0].position",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nnumerical_aperture = 1.5",
            "",
            "sensors[0].numerical_aperture",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = -0.1",
            "",
            "sensors[0].radius",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = nan",
            "",
            "sensors[0].radius",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.6",
            "",
            "sensors[0].radius",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 0.0",
            "",
            "sensors[0].numerical_aperture",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 1.2",
            "",
            "sensors[0].numerical_aperture",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = nan",
            "",
            "sensors[0].numerical_aperture",
        ),
        (
            "position = [0.1, 0.0, 0.3]\nradius = 0.05",
            "",
            "sensors[0].position",
        ),
        (
            "position = [0.1, 0.0, -2.0]\nradius = 0.05",
            "",
            "sensors[0].position",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.05\naxis = [0.0, 0.0, 1.0]",
            "",
            "sensors[0].axis",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.05\nweighting = \"radiance\"",
            "",
            "sensors[0]: unknown variant `radiance`, expected `flux` or `fluence`",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.05",
            "host_index = 0.5",
            "host_index",
        ),
        (
            "position = [0.1, 0.0, 0.0]\nradius = 0.05",
            "host_index = nan",
            "host_index",
        ),
    ];
    for (detector, medium, field) in cases {
        let s = write(dir.path(), "bad.toml", &scene(detector, medium));
        let o = speckle(dir.path(), &["g1", s.to_str().unwrap(), "-q"]);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{detector} {medium}: {}",
            stderr(&o)
        );
        assert!(
            stderr(&o).contains(field),
            "{detector} {medium}: expected {field} in {}",
            stderr(&o)
        );
    }
    // Detectors and other sensors together.
    let mixed = scene(FIBRE, "") + "\n[[sensors]]\ntype = \"point\"\nposition = [0.0, 0.0, 0.0]\n";
    let s = write(dir.path(), "mixed.toml", &mixed);
    let o = speckle(dir.path(), &["g1", s.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("sensors[1]"), "{}", stderr(&o));
}

#[test]
fn refractive_faces_render_with_detectors_and_are_refused_by_field_renders() {
    let dir = tempfile::tempdir().unwrap();
    let medium = "host_index = 1.4\noutside_index = 1.0";
    let s = write(dir.path(), "f.toml", &scene(FIBRE, medium));
    let o = speckle(
        dir.path(),
        &["g1", s.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let i = npy_f64(&dir.path().join("out/f.correlation.npy"));
    assert!(i[0] > 0.0 && i[0].is_finite());
    // The same medium with a point sensor: every field render refuses it, naming the key.
    let field = scene(FIBRE, medium).replace(
        "type = \"detector\"\nposition = [0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 0.5",
        "type = \"point\"\nposition = [0.1, 0.0, 0.0]",
    );
    let s = write(dir.path(), "p.toml", &field);
    for cmd in ["covariance", "intensity", "g1", "mean", "wave"] {
        let o = speckle(
            dir.path(),
            &[cmd, s.to_str().unwrap(), "--out", "out2", "-q"],
        );
        assert_eq!(o.status.code(), Some(2), "{cmd}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("medium.outside_index"),
            "{cmd}: {}",
            stderr(&o)
        );
    }
}

/// The scene with its point source replaced by a fibre source of keys `fibre`.
fn fibre_source(fibre: &str, sensor: Option<&str>) -> String {
    let s = scene(FIBRE, "").replace(
        "type = \"point\"\nposition = [-0.1, 0.0, 0.0]",
        &format!("type = \"fibre\"\n{fibre}"),
    );
    match sensor {
        Some(sensor) => s.replace(
            "type = \"detector\"\nposition = [0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 0.5",
            sensor,
        ),
        None => s,
    }
}

#[test]
fn fibre_sources_render_with_detectors_and_bad_ones_exit_2_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let good = "position = [-0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 0.4";
    let s = write(dir.path(), "f.toml", &fibre_source(good, None));
    let o = speckle(
        dir.path(),
        &["g1", s.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let c = npy_f64(&dir.path().join("out/f.correlation.npy"));
    assert!(c[0] > 0.0 && c[0].is_finite() && c[4] < c[0], "{c:?}");
    // The sidecar's tables describe the fibre (kind 5: centre, radius, aperture) and the
    // detector (kind 4).
    let src = npy_f64(&dir.path().join("out/f.g1.sources.npy"));
    assert_eq!(src, [0.0, 5.0, -0.1, 0.0, 0.0, 0.05, 0.4]);
    let sen = npy_f64(&dir.path().join("out/f.g1.sensors.npy"));
    assert_eq!(sen, [0.0, 4.0, 0.1, 0.0, 0.0, 0.05, 0.5]);
    let cases = [
        (
            "position = [-0.1, 0.0, 0.0]\nradius = 0.0",
            "sources[0].radius",
        ),
        (
            "position = [-0.1, 0.0, 0.0]\nradius = nan",
            "sources[0].radius",
        ),
        (
            "position = [-0.1, 0.0, 0.3]\nradius = 0.05",
            "sources[0].position",
        ),
        (
            "position = [-0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 1.5",
            "sources[0].numerical_aperture",
        ),
        (
            "position = [-0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = -1",
            "sources[0].numerical_aperture",
        ),
        // Pointing out of the medium, and a cone that crosses the face.
        (
            "position = [-0.1, 0.0, 0.0]\nradius = 0.05\naxis = [0.0, 0.0, -1.0]",
            "sources[0].axis",
        ),
        (
            "position = [-0.1, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 0.5\naxis = [1.0, 0.0, 0.2]",
            "sources[0].axis",
        ),
        (
            "position = [-0.1, 0.0, 0.0]\nradius = 0.05\ncolour = 1",
            "colour",
        ),
    ];
    for (fibre, field) in cases {
        let s = write(dir.path(), "bad.toml", &fibre_source(fibre, None));
        let o = speckle(dir.path(), &["g1", s.to_str().unwrap(), "-q"]);
        assert_eq!(o.status.code(), Some(2), "{fibre}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(field),
            "{fibre}: expected {field} in {}",
            stderr(&o)
        );
    }
    // A fibre source with a point sensor: it has no field.
    let point = fibre_source(good, Some("type = \"point\"\nposition = [0.1, 0.0, 0.0]"));
    let s = write(dir.path(), "p.toml", &point);
    for cmd in ["g1", "intensity", "covariance"] {
        let o = speckle(dir.path(), &[cmd, s.to_str().unwrap(), "-q"]);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {}", stderr(&o));
        assert!(stderr(&o).contains("sources[0]"), "{cmd}: {}", stderr(&o));
    }
}

#[test]
fn a_point_sensor_on_a_face_far_from_its_source_draws_advice() {
    // The issue's new user: the tissue cube (mu_s = 100 /cm) with a point sensor on the face
    // 5 mm (50 mean free paths) from the source. The warning names the sensor and the fix; the
    // fibre itself, and the 2023 paper's DCS scene (5 mean free paths), draw none.
    let dir = tempfile::tempdir().unwrap();
    let tissue = speckle(dir.path(), &["example", "tissue_fibre"]);
    let text = String::from_utf8(tissue.stdout).unwrap();
    let point = text.replace(
        "type = \"detector\"\nposition = [0.25, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 0.5",
        "type = \"point\"\nposition = [0.25, 0.0, 0.0]",
    );
    assert_ne!(point, text);
    let cases = [
        ("point.toml", point, true),
        ("fibre.toml", text, false),
        (
            "dcs.toml",
            String::from_utf8(speckle(dir.path(), &["example", "dcs"]).stdout).unwrap(),
            false,
        ),
    ];
    for (name, scene, warned) in cases {
        let s = write(dir.path(), name, &scene);
        let o = speckle(
            dir.path(),
            &[
                "intensity",
                s.to_str().unwrap(),
                "--paths",
                "2000",
                "-q",
                "--out",
                "o",
            ],
        );
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let e = stderr(&o);
        assert_eq!(e.contains("warning"), warned, "{name}: {e}");
        if warned {
            assert!(
                e.contains("sensors[0] is a point on a face") && e.contains("50 mean free paths"),
                "{e}"
            );
            assert!(e.contains("weighting = \"fluence\""), "{e}");
        }
    }
}
