//! `speckle seeing-through` (Katz et al. 2014; Bar et al. 2019, Fig. 13): its files, their
//! shapes and what the sidecar says of them, and bad input named with exit code 2 (the physics:
//! `tests/seeing_through.rs`).

mod common;
use common::*;

const STUDY: &str = r######"
wavelength_um = 0.5
thickness_um = 1000.0
mean_free_path_um = 100.0
width_um = 23000.0
g = [0.95, 0.8]
object = ["##.", ".#."]
object_step_mdeg = 2.5
pixels = 16
pixel_mdeg = 1.25
realizations = 2
window = 12

[render]
paths = 300

[retrieval]
hio = 50
er = 10
starts = 2
"######;

#[test]
fn seeing_through_writes_images_autocorrelations_and_reconstructions() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.toml");
    std::fs::write(&p, STUDY).unwrap();
    let o = speckle(
        dir.path(),
        &["seeing-through", p.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    let shapes = [
        ("object", vec![12, 12]),
        ("object_autocorrelation", vec![12, 12]),
        ("images", vec![2, 2, 16, 16]),
        ("autocorrelation", vec![2, 12, 12]),
        ("predicted_autocorrelation", vec![2, 12, 12]),
        ("reconstruction", vec![2, 12, 12]),
        ("memory_correlation", vec![2, 3]),
        ("memory_correlation_stderr", vec![2, 3]),
        ("separation_mdeg", vec![3]),
    ];
    for (key, shape) in shapes {
        let (s, v) = load_f8(&out.join(format!("t.{key}.npy")));
        assert_eq!(s, shape, "{key}");
        assert!(v.iter().all(|x| x.is_finite()), "{key}");
    }
    let (_, object) = load_f8(&out.join("t.object.npy"));
    assert_eq!(object.iter().sum::<f64>(), 3.0);
    // Autocorrelations are 1 at lag 0, the centre of the window.
    let (_, ac) = load_f8(&out.join("t.autocorrelation.npy"));
    assert_eq!(ac[6 * 12 + 6], 1.0);
    let (_, sep) = load_f8(&out.join("t.separation_mdeg.npy"));
    assert_eq!(sep[0], 0.0);
    assert!((sep[1] - 2.5).abs() < 1e-12 && (sep[2] - 2.5 * 2f64.sqrt()).abs() < 1e-12);
    let png = std::fs::read(out.join("t.seeing_through.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("t.seeing_through.json")).unwrap())
            .unwrap();
    assert_eq!(json["cases"].as_array().unwrap().len(), 2);
    assert_eq!(
        json["files"]["images"]["shape"],
        serde_json::json!([2, 2, 16, 16])
    );
    assert!(
        json["files"]["png"]["layout"]
            .as_str()
            .unwrap()
            .contains("a row per case")
    );
    // Bad input: exit code 2, the field named, nothing written.
    std::fs::write(&p, STUDY.replace("window = 12", "window = 6")).unwrap();
    let o = speckle(
        dir.path(),
        &["seeing-through", p.to_str().unwrap(), "--out", "bad", "-q"],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("window"), "{}", stderr(&o));
    assert!(!dir.path().join("bad").join("t.images.npy").exists());
}
