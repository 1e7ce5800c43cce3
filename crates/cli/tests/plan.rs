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
        "pilot of 2000 paths",
        "paths for 1%",
        "memory effect",
        "speckle grain",
        "suggested",
    ] {
        assert!(out.contains(want), "{want}: {out}");
    }
    // Pair 1 has a point sensor; pair 5 does not exist.
    for (pair, field) in [("1", "--pair 1"), ("5", "--pair")] {
        let o = speckle(d, &["plan", "p.toml", "--paths", "2000", "--pair", pair]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(field), "{}", stderr(&o));
    }
    assert!(!d.join("out").exists(), "plan writes nothing");
}
