//! `speckle wave --mean-plot` (Bar et al. 2019, Fig. 4b): on a small flatland scene (a point
//! source and three point sensors) it writes the wave solver's files and the figure's: the SVG
//! (log-scale y axis, the scene's length unit, a legend of the three curves), the `.npy`
//! arrays in pair order and the JSON sidecar; scenes that are not point-to-point, `[motion]`
//! and `--multislice` are refused, naming the field or flag.

mod common;
use common::*;

/// A 16 x 8 wavelength rectangle, mean free path 10, a point source and three point sensors
/// at d = 2, 6, 10; `extra` is appended (more sources or sensors).
fn scene(extra: &str) -> String {
    format!(
        r#"name = "m"
dimension = 2
wavelength = 1.0
units = {{ length = "um" }}

[medium]
size = [16.0, 8.0, 0.0]
mean_free_path = 10.0

[[sources]]
type = "point"
position = [-7.0, 0.0, 0.0]

[[sensors]]
type = "point_grid"
origin = [-5.0, 0.0, 0.0]
step_x = [4.0, 0.0, 0.0]
step_y = [0.0, 1.0, 0.0]
nx = 3
ny = 1

[render]
configurations = 100
seed = 3
{extra}"#
    )
}

#[test]
fn mean_plot_writes_the_figure_arrays_and_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "m.toml", &scene(""));
    let o = speckle(
        dir.path(),
        &["wave", "m.toml", "--mean-plot", "--threads", "2", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    for f in [
        "m.wave_mean.npy",
        "m.wave_mean_stderr.npy",
        "m.mean_plot.svg",
        "m.mean_plot.json",
        "m.mean_distance.npy",
        "m.mean_closed.npy",
        "m.mean_free.npy",
        "m.mean_z.npy",
    ] {
        assert!(out.join(f).is_file(), "{f} missing: {}", stdout(&o));
    }
    let (shape, d) = load_f8(&out.join("m.mean_distance.npy"));
    assert_eq!(shape, vec![3]);
    assert_eq!(d, vec![2.0, 6.0, 10.0]);
    let (shape, z) = load_f8(&out.join("m.mean_z.npy"));
    assert_eq!(shape, vec![3, 2]);
    assert!(z.iter().all(|z| z.is_finite()), "{z:?}");
    // The closed form is the attenuated free-space field e^{-d / 20} e^{ikd} / sqrt(d).
    let closed = npy_f64(&out.join("m.mean_closed.npy"));
    let free = npy_f64(&out.join("m.mean_free.npy"));
    for (i, &d) in [2.0f64, 6.0, 10.0].iter().enumerate() {
        let abs = |v: &[f64]| v[2 * i].hypot(v[2 * i + 1]);
        assert!((abs(&free) - 1.0 / d.sqrt()).abs() < 1e-12);
        assert!((abs(&closed) - (-d / 20.0).exp() / d.sqrt()).abs() < 1e-9);
    }
    let svg = std::fs::read_to_string(out.join("m.mean_plot.svg")).unwrap();
    for text in [
        "closed form, Eq. 20",
        "wave solver, mean +- SE",
        "free space |G0|",
        "(log scale)",
        "distance d = |x2 - x1| (um)",
    ] {
        assert!(svg.contains(text), "the figure lacks {text:?}");
    }
    assert!(!svg.contains("NaN"));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("m.mean_plot.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 3);
    assert_eq!(json["units"]["length"], "um");
    assert!(
        json["summary"]["max_abs_z"].as_f64().unwrap() < 5.0,
        "{json}"
    );
}

#[test]
fn mean_plot_refuses_what_it_cannot_plot() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, text: &str, more: &[&str]| {
        write(dir.path(), name, text);
        let mut args = vec!["wave", name, "--mean-plot", "-q", "--threads", "2"];
        args.extend_from_slice(more);
        let o = speckle(dir.path(), &args);
        assert!(!o.status.success(), "{name} was accepted");
        stderr(&o)
    };
    let plane = "[[sources]]\ntype = \"plane\"\ndirection = [0.0, 1.0, 0.0]\n";
    let e = run("plane.toml", &scene(plane), &[]);
    assert!(
        e.contains("sources") && e.contains("not a point source"),
        "{e}"
    );
    let far = "[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0.0, 10.0]\nn = 2\n";
    let e = run("far.toml", &scene(far), &[]);
    assert!(
        e.contains("sensors") && e.contains("not a point sensor"),
        "{e}"
    );
    let e = run("ms.toml", &scene(""), &["--multislice"]);
    assert!(e.contains("--multislice"), "{e}");
    assert!(!dir.path().join("out").exists());
}
