//! End-to-end tests of sharded runs through the binary: `--shard I/N` writes one shard file,
//! `speckle merge` of the shards writes byte for byte the single run's arrays (covariance,
//! intensity, fields, wave, and the readings of detectors in a layered medium from a point and
//! a fibre source; shards on 1 to 3 threads, files given in any order); a missing
//! shard is named by index with exit code 2 and rendering it completes the merge; commands that
//! render whole runs only (g1, map, single) refuse `--shard` naming it; a cancelled
//! shard writes nothing; bad shard specifications and shards of other runs exit with 2.
//!
//! Run time (release, 2 cores): a few seconds.

mod common;

use common::{speckle, stderr};
use std::path::{Path, PathBuf};

fn ok(dir: &Path, args: &[&str]) {
    let o = speckle(dir, args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
}

/// 2 plane waves, a 3 x 2 far-field image (J = 12); 10 007 paths are 127 uneven batches.
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
paths = 10007
seed = 5
realizations = 9
paths_per_realization = 503
"#;

/// Two fibre detectors in a layered, refracting slab lit by a point source and a fibre.
const FIBRES: &str = r#"
name = "fib"
wavelength = 785e-7
[medium]
size = [2.0, 2.0, 1.0]
center = [0.0, 0.0, 0.5]
layers = [0.2, 0.8]
host_index = 1.4
outside_index = 1.0
[[medium.materials]]
sigma_s = 40.0
sigma_a = 0.2
phase = { type = "hg", g = 0.8 }
[[medium.materials]]
sigma_s = 60.0
sigma_a = 0.1
phase = { type = "hg", g = 0.9 }
[[sources]]
type = "point"
position = [-0.2, 0.0, 0.0]
[[sources]]
type = "fibre"
position = [0.0, 0.3, 0.0]
radius = 0.05
numerical_aperture = 0.4
[[sensors]]
type = "detector"
position = [0.2, 0.0, 0.0]
radius = 0.05
[[sensors]]
type = "detector"
position = [0.4, 0.0, 0.0]
radius = 0.1
numerical_aperture = 0.5
[render]
paths = 20011
seed = 7
"#;

/// A lossless isotropic box for the wave solver, 11 configurations.
const WAVE: &str = r#"
name = "w"
wavelength = 1.0
[medium]
size = [4.0, 4.0, 2.0]
mean_free_path = 4.0
[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 5.0]
[[sensors]]
type = "far_arc"
angles_deg = [-10.0, 10.0]
n = 3
[render]
configurations = 11
seed = 3
"#;

fn npy_files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "npy"))
        .collect();
    v.sort();
    v
}

fn shard_files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|d| {
            d.map(|e| e.unwrap().path().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn merged_shards_write_the_single_runs_arrays() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tiny.toml"), TINY).unwrap();
    std::fs::write(d.join("w.toml"), WAVE).unwrap();
    std::fs::write(d.join("fib.toml"), FIBRES).unwrap();
    for (command, scene, n) in [
        ("covariance", "tiny.toml", 3),
        ("intensity", "tiny.toml", 7),
        ("intensity", "fib.toml", 3),
        ("fields", "tiny.toml", 2),
        ("wave", "w.toml", 3),
    ] {
        let single = d.join(format!("{command}-{scene}-single"));
        let shards = d.join(format!("{command}-{scene}-shards"));
        let merged = d.join(format!("{command}-{scene}-merged"));
        let (single_s, shards_s, merged_s) = (
            single.to_str().unwrap(),
            shards.to_str().unwrap(),
            merged.to_str().unwrap(),
        );
        ok(d, &[command, scene, "--out", single_s, "-q", "--no-png"]);
        for i in 0..n {
            let spec = format!("{i}/{n}");
            let threads = (1 + i % 3).to_string();
            ok(
                d,
                &[
                    command,
                    scene,
                    "--shard",
                    &spec,
                    "--threads",
                    &threads,
                    "--out",
                    shards_s,
                    "-q",
                ],
            );
        }
        let mut files = shard_files(&shards);
        assert_eq!(files.len(), n, "{command}: {files:?}");
        assert!(files.iter().all(|f| f.ends_with(&format!("-of-{n}.shard"))));
        files.reverse();
        let mut args = vec!["merge"];
        args.extend(files.iter().map(String::as_str));
        args.extend(["--out", merged_s, "--no-png"]);
        ok(d, &args);
        let a = npy_files(&single);
        assert!(!a.is_empty());
        assert_eq!(a.len(), npy_files(&merged).len(), "{command}");
        for f in a {
            let m = merged.join(f.file_name().unwrap());
            assert!(
                std::fs::read(&f).unwrap() == std::fs::read(&m).unwrap(),
                "{command}: {} differs from the single run's",
                m.display()
            );
        }
    }
}

#[test]
fn a_missing_shard_is_named_and_rendering_it_completes_the_merge() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tiny.toml"), TINY).unwrap();
    let shard = |i: usize| {
        ok(
            d,
            &[
                "covariance",
                "tiny.toml",
                "--shard",
                &format!("{i}/7"),
                "--out",
                "s",
                "-q",
            ],
        )
    };
    for i in [0, 1, 2, 4, 6] {
        shard(i);
    }
    let merge = || {
        let files = shard_files(&d.join("s"));
        let mut args = vec!["merge"];
        args.extend(files.iter().map(String::as_str));
        args.extend(["--out", "m", "--no-png"]);
        speckle(d, &args)
    };
    let o = merge();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("shards 3/7, 5/7 are missing"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("m").exists(), "a refused merge wrote output");
    // A cancelled shard writes nothing: the merge still names it.
    let o = speckle(
        d,
        &[
            "covariance",
            "tiny.toml",
            "--shard",
            "3/7",
            "--out",
            "s",
            "-q",
            "--cancel-after-paths",
            "1",
        ],
    );
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert_eq!(shard_files(&d.join("s")).len(), 5);
    shard(3);
    shard(5);
    let o = merge();
    assert!(o.status.success(), "{}", stderr(&o));
    ok(
        d,
        &[
            "covariance",
            "tiny.toml",
            "--out",
            "single",
            "-q",
            "--no-png",
        ],
    );
    for name in ["tiny.cov.npy", "tiny.cov_stderr.npy", "tiny.cov_single.npy"] {
        assert!(
            std::fs::read(d.join("m").join(name)).unwrap()
                == std::fs::read(d.join("single").join(name)).unwrap(),
            "{name}"
        );
    }
}

#[test]
fn bad_shard_specifications_and_shards_of_other_runs_exit_with_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tiny.toml"), TINY).unwrap();
    for bad in ["7/7", "1/0", "x/2", "3"] {
        let o = speckle(d, &["covariance", "tiny.toml", "--shard", bad, "-q"]);
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", stderr(&o));
        assert!(stderr(&o).contains("shard"), "{}", stderr(&o));
    }
    ok(
        d,
        &[
            "covariance",
            "tiny.toml",
            "--shard",
            "0/2",
            "--out",
            "a",
            "-q",
        ],
    );
    ok(
        d,
        &[
            "covariance",
            "tiny.toml",
            "--shard",
            "1/2",
            "--seed",
            "6",
            "--out",
            "b",
            "-q",
        ],
    );
    let (a, b) = (&shard_files(&d.join("a"))[0], &shard_files(&d.join("b"))[0]);
    let o = speckle(d, &["merge", a, b, "--out", "m"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("different seeds (6 and 5)"),
        "{}",
        stderr(&o)
    );
    let o = speckle(d, &["merge", a, a, "--out", "m"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("overlap"), "{}", stderr(&o));
    std::fs::write(d.join("junk.shard"), b"not a shard").unwrap();
    let o = speckle(d, &["merge", "junk.shard"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("not a speckle shard file"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("m").exists());
}

#[test]
fn commands_that_render_whole_runs_refuse_a_shard_naming_it() {
    // They ignored --shard and rendered the whole run before.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = format!("{TINY}\n[motion]\ndiffusion = 1e-3\nlags = [0.0, 1.0]\n");
    std::fs::write(d.join("tiny.toml"), scene).unwrap();
    for command in ["g1", "map", "single"] {
        let o = speckle(
            d,
            &[command, "tiny.toml", "--shard", "0/2", "--out", "o", "-q"],
        );
        assert_eq!(o.status.code(), Some(2), "{command}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("shard") && stderr(&o).contains("whole runs only"),
            "{command}: {}",
            stderr(&o)
        );
        assert!(!d.join("o").exists(), "{command} wrote output");
    }
}
