//! `speckle emc` (electric-field Monte Carlo, the baseline of Bar et al. 2019): its files and
//! their shapes, the sidecar's bin, and bad input named with exit code 2 (the physics:
//! `tests/emc.rs`).

mod common;
use common::*;

const SCENE: &str = r#"
name = "e"
wavelength = 1.0
[medium]
size = [20.0, 20.0, 2.0]
mean_free_path = 1.0
albedo = 0.95
[phase]
type = "hg"
g = 0.5
[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 1.0]
[[sensors]]
type = "far_arc"
angles_deg = [-20.0, 20.0]
n = 5
[render]
realizations = 3
paths_per_realization = 20000
"#;

#[test]
fn emc_writes_intensities_and_fields() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "e.toml", SCENE);
    let o = speckle(d, &["emc", "e.toml", "--out", "out", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.join("out");
    let (shape, i) = load_f8(&out.join("e.emc_intensity.npy"));
    assert_eq!(shape, vec![2, 5]);
    assert!(i.iter().all(|v| v.is_finite() && *v > 0.0), "{i:?}");
    assert_eq!(
        load_f8(&out.join("e.emc_intensity_stderr.npy")).0,
        vec![2, 5]
    );
    // Complex fields: (R, sources, sensors) pairs of float64.
    assert_eq!(npy_f64(&out.join("e.emc_fields.npy")).len(), 2 * 3 * 2 * 5);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("e.emc.json")).unwrap()).unwrap();
    // The sensors are 10 degrees apart: bins of half that, at most 2 degrees.
    assert!((json["render"]["cone_deg"].as_f64().unwrap() - 2.0).abs() < 1e-12);
    assert_eq!(json["render"]["realizations"], 3);
    // Bad input: a point sensor, a bad cone, one realization.
    write(
        d,
        "p.toml",
        &SCENE.replace(
            "type = \"far_arc\"\nangles_deg = [-20.0, 20.0]\nn = 5",
            "type = \"point\"\nposition = [0.0, 0.0, 10.0]",
        ),
    );
    let o = speckle(d, &["emc", "p.toml", "--out", "bad", "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("sensors[0]"), "{}", stderr(&o));
    for args in [
        ["--cone-deg", "0"],
        ["--cone-deg", "nan"],
        ["--realizations", "1"],
    ] {
        let o = speckle(
            d,
            &["emc", "e.toml", "--out", "bad", "-q", args[0], args[1]],
        );
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(args[0].trim_start_matches("--").split('-').next().unwrap()));
    }
    assert!(!d.join("bad").join("e.emc_intensity.npy").exists());
    // A scene of detectors is refused naming `sensors`.
    let o = speckle(d, &["example", "tissue_fibre"]);
    write(d, "t.toml", &stdout(&o));
    let o = speckle(d, &["emc", "t.toml", "--out", "bad", "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("sensors"), "{}", stderr(&o));
}
