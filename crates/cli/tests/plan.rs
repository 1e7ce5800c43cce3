//! `speckle plan`: its report, and bad input named with exit code 2 (the predictions against
//! full renders: `tests/plan.rs`).

mod common;
use common::*;

const SCENE: &str = r#"
name = "p"
wavelength = 1.0
[medium]
size = [40.0, 40.0, 4.0]
mean_free_path = 2.0
[phase]
type = "hg"
g = 0.5
[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "far"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "point"
position = [0.0, 0.0, 10.0]
"#;

#[test]
fn plan_reports_and_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "p.toml", SCENE);
    let o = speckle(d, &["plan", "p.toml", "--paths", "2000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o) + &stderr(&o);
    for want in [
        "pilots of 2000 paths",
        "paths for 1%",
        "memory effect",
        "speckle grain",
        "suggested",
    ] {
        assert!(out.contains(want), "{want}: {out}");
    }
    // Pair 1 has a point sensor: its intensity only; pair 5 does not exist.
    let o = speckle(d, &["plan", "p.toml", "--paths", "2000", "--pair", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o) + &stderr(&o);
    assert!(
        out.contains("paths for 1%") && out.contains("pair 1 has other kinds"),
        "{out}"
    );
    let o = speckle(d, &["plan", "p.toml", "--paths", "2000", "--pair", "5"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--pair"), "{}", stderr(&o));
    // A pilot of fewer than 2 paths has no standard error.
    let o = speckle(d, &["plan", "p.toml", "--paths", "1"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--paths"), "{}", stderr(&o));
    // With [motion]: the pilot's decorrelation time.
    write(
        d,
        "m.toml",
        &format!("{SCENE}[motion]\ndiffusion = 0.01\nlags = [0.0, 0.1, 0.3, 1.0, 3.0, 10.0]\n"),
    );
    let o = speckle(d, &["plan", "m.toml", "--paths", "2000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o) + &stderr(&o);
    assert!(
        out.contains("tau_c") || out.contains("stays above 1/e"),
        "{out}"
    );
    // A scene of detectors (a fibre source and a fibre detector): the reading's error.
    let o = speckle(d, &["example", "tissue_fibre"]);
    write(d, "t.toml", &stdout(&o));
    let o = speckle(d, &["plan", "t.toml", "--paths", "2000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o) + &stderr(&o);
    assert!(
        out.contains("paths for 1%") && out.contains("detector reading"),
        "{out}"
    );
    assert!(!d.join("out").exists(), "plan writes nothing");
}
