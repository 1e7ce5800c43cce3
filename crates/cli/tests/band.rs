//! `speckle covariance --band R`: the band of an image's covariance, its files and sidecar,
//! and what it refuses (the values against the dense render: `tests/band.rs`).

mod common;
use common::*;

const SCENE: &str = r#"
name = "b"
wavelength = 1.0
[medium]
size = [20.0, 20.0, 2.0]
mean_free_path = 4.0
[phase]
type = "hg"
g = 0.5
[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "far_grid"
theta_x_deg = [-5.0, 5.0]
theta_y_deg = [-2.5, 2.5]
nx = 9
ny = 5
[render]
paths = 2000
"#;

#[test]
fn band_writes_its_array_and_refuses_what_it_cannot_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "b.toml", SCENE);
    let o = speckle(d, &["covariance", "b.toml", "--band", "2", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.join("out");
    let header = std::fs::read(out.join("b.cov_band.npy")).unwrap();
    let text = String::from_utf8_lossy(&header[..128]);
    assert!(
        text.contains("'descr': '<c16'") && text.contains("'shape': (1, 5, 9, 1, 5, 5)"),
        "{text}"
    );
    let v = npy_f64(&out.join("b.cov_band.npy"));
    assert_eq!(v.len(), 2 * 5 * 9 * 5 * 5);
    // Pixel (0, 0): its own intensity at offset (0, 0) is positive, offsets above it NaN.
    let at = |y: usize, x: usize, dy: usize, dx: usize| v[2 * (((y * 9 + x) * 5 + dy) * 5 + dx)];
    assert!(at(0, 0, 2, 2) > 0.0 && at(0, 0, 0, 2).is_nan() && at(0, 0, 2, 0).is_nan());
    assert!(at(4, 8, 2, 2) > 0.0 && at(4, 8, 4, 2).is_nan());
    let json = std::fs::read_to_string(out.join("b.cov_band.json")).unwrap();
    for want in [
        "edge_correlation",
        "mean_correlation_by_offset",
        "\"radius\": 2",
    ] {
        assert!(json.contains(want), "{want}: {json}");
    }
    assert!(!out.join("b.cov.npy").exists());
    // A radius across the image; a scene without an image of sensors; shards.
    let o = speckle(d, &["covariance", "b.toml", "--band", "9", "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("band"), "{}", stderr(&o));
    let grid =
        "type = \"far_grid\"\ntheta_x_deg = [-5.0, 5.0]\ntheta_y_deg = [-2.5, 2.5]\nnx = 9\nny = 5";
    assert!(SCENE.contains(grid));
    write(
        d,
        "f.toml",
        &SCENE.replace(grid, "type = \"far\"\ndirection = [0.0, 0.0, 1.0]"),
    );
    let o = speckle(d, &["covariance", "f.toml", "--band", "1", "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("sensors: --band needs"),
        "{}",
        stderr(&o)
    );
    let o = speckle(
        d,
        &[
            "covariance",
            "b.toml",
            "--band",
            "1",
            "--shard",
            "1/2",
            "-q",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("shard"), "{}", stderr(&o));
}
