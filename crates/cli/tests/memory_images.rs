//! `speckle memory-images` (Bar et al. 2019, Fig. 1): its files, their shapes and what the
//! sidecar says of them, and bad input named with exit code 2 (the physics:
//! `tests/memory_images.rs`).

mod common;
use common::*;

const STUDY: &str = r######"
wavelength_um = 0.5
thickness_um = 1000.0
mean_free_path_um = 100.0
width_um = 23000.0
g = [0.0, 0.9]
delta_mdeg = 2.5
tilts = [0, 1, 2]
pixels = 16
pixel_mdeg = 1.25
realizations = 2
window = 12

[render]
paths = 300
"######;

#[test]
fn memory_images_writes_images_insets_and_peaks() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.toml");
    std::fs::write(&p, STUDY).unwrap();
    let o = speckle(
        dir.path(),
        &["memory-images", p.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    let shapes = [
        ("images", vec![2, 2, 3, 16, 16]),
        ("correlation", vec![2, 3, 12, 12]),
        ("peak", vec![2, 3]),
        ("peak_stderr", vec![2, 3]),
        ("peak_realizations", vec![2, 2, 3]),
        ("peak_lag", vec![2, 3, 2]),
        ("tilts_mdeg", vec![3]),
    ];
    for (key, shape) in shapes {
        let (s, v) = load_f8(&out.join(format!("t.{key}.npy")));
        assert_eq!(s, shape, "{key}");
        assert!(v.iter().all(|x| x.is_finite()), "{key}");
    }
    // The untilted inset is the autocorrelation: 1 at lag 0, the centre of the window.
    let (_, c) = load_f8(&out.join("t.correlation.npy"));
    assert!((c[6 * 12 + 6] - 1.0).abs() < 1e-9);
    let (_, peak) = load_f8(&out.join("t.peak.npy"));
    assert!((peak[0] - 1.0).abs() < 1e-9 && (peak[3] - 1.0).abs() < 1e-9);
    let (_, tilts) = load_f8(&out.join("t.tilts_mdeg.npy"));
    assert_eq!(tilts, vec![0.0, 2.5, 5.0]);
    let png = std::fs::read(out.join("t.memory_images.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("t.memory_images.json")).unwrap())
            .unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 2);
    assert_eq!(
        json["geometry"]["shift_pixels"],
        serde_json::json!([0, 2, 4])
    );
    assert!(
        json["files"]["png"]["layout"]
            .as_str()
            .unwrap()
            .contains("a row per g")
    );
    // Bad input: exit code 2, the field named, nothing written.
    std::fs::write(&p, STUDY.replace("tilts = [0, 1, 2]", "tilts = [0, 2, 1]")).unwrap();
    let o = speckle(
        dir.path(),
        &["memory-images", p.to_str().unwrap(), "--out", "bad", "-q"],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("tilts[2]"), "{}", stderr(&o));
    assert!(!dir.path().join("bad").join("t.images.npy").exists());
}
