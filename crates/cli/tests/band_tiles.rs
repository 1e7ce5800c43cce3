//! `speckle covariance --band R --tile I/N` and `speckle merge` of the tiles: the merged band
//! is bitwise the whole `--band R` render (arrays and the sidecar's summary), with two sources
//! (tiles interleaved per `s1`), for tiles rendered on different thread counts and given in any
//! order, also with `--single-beyond`; and what is refused: missing, duplicate, damaged and
//! foreign tiles (another seed, radius, split or `--single-beyond`), more tiles than rows,
//! `--band auto` with `--tile`, tiles mixed with shards, `--single-beyond` not below the band's
//! radius.

mod common;
use common::*;
use std::path::Path;

/// A 9 x 5 far-field image lit by two plane waves (`S = 2`, `J = 90`).
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
[[sources]]
type = "plane"
direction = [0.05, 0.0, 1.0]
[[sensors]]
type = "far_grid"
theta_x_deg = [-5.0, 5.0]
theta_y_deg = [-2.5, 2.5]
nx = 9
ny = 5
[render]
paths = 1500
"#;

fn run(d: &Path, args: &[&str]) -> std::process::Output {
    let o = speckle(d, args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    o
}

/// Renders tiles `which` of `n` of radius `r` into `dir` (extra arguments `more`).
fn tiles(d: &Path, dir: &str, r: &str, n: usize, which: &[usize], more: &[&str]) {
    for &i in which {
        let t = format!("{i}/{n}");
        let threads = (1 + i % 3).to_string();
        let mut args = vec![
            "covariance",
            "b.toml",
            "--band",
            r,
            "--tile",
            &t,
            "-q",
            "--out",
            dir,
            "--threads",
            &threads,
        ];
        args.extend_from_slice(more);
        run(d, &args);
    }
}

fn tile_paths(d: &Path, dir: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d.join(dir))
        .unwrap()
        .map(|e| e.unwrap().path().to_string_lossy().into_owned())
        .filter(|p| p.ends_with(".tile"))
        .collect();
    v.sort();
    v
}

fn summary(path: &Path) -> serde_json::Value {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["summary"].clone()
}

#[test]
fn merged_tiles_are_bitwise_the_whole_band() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "b.toml", SCENE);
    run(
        d,
        &[
            "covariance",
            "b.toml",
            "--band",
            "2",
            "-q",
            "--out",
            "whole",
            "--threads",
            "2",
        ],
    );
    for n in [3usize, 5] {
        let t = format!("t{n}");
        tiles(d, &t, "2", n, &(0..n).rev().collect::<Vec<_>>(), &[]);
        let mut paths = tile_paths(d, &t);
        assert_eq!(paths.len(), n);
        paths.reverse();
        let m = format!("m{n}");
        let mut args = vec!["merge", "--out", m.as_str()];
        args.extend(paths.iter().map(String::as_str));
        run(d, &args);
        for f in ["b.cov_band.npy", "b.cov_band_stderr.npy"] {
            let (a, b) = (
                std::fs::read(d.join("whole").join(f)).unwrap(),
                std::fs::read(d.join(&m).join(f)).unwrap(),
            );
            assert!(a == b, "{f} of {n} tiles differs from the whole render's");
        }
        let (a, mut b) = (
            summary(&d.join("whole/b.cov_band.json")),
            summary(&d.join(&m).join("b.cov_band.json")),
        );
        assert_eq!(b["merged_tiles"], n);
        b.as_object_mut().unwrap().remove("merged_tiles");
        // Bitwise: serde_json prints every f64 exactly (shortest round trip).
        assert_eq!(a, b);
    }
}

#[test]
fn bad_tiles_are_refused_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "b.toml", SCENE);
    tiles(d, "t", "1", 3, &[0, 1, 2], &[]);
    let t = tile_paths(d, "t");
    let refused = |paths: &[&str], want: &str| {
        let mut args = vec!["merge", "--out", "m"];
        args.extend_from_slice(paths);
        let o = speckle(d, &args);
        assert!(!o.status.success(), "{paths:?} merged");
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
        assert!(!d.join("m").join("b.cov_band.npy").exists());
    };
    refused(&[&t[0], &t[2]], "tile 1/3 of the band are missing");
    refused(&[&t[0], &t[1], &t[1], &t[2]], "are the same tile");
    // Tiles of another seed, radius or split.
    tiles(d, "seed", "1", 3, &[1], &["--seed", "9"]);
    refused(
        &[&t[0], &tile_paths(d, "seed")[0], &t[2]],
        "different seeds",
    );
    tiles(d, "radius", "2", 3, &[1], &[]);
    refused(&[&t[0], &tile_paths(d, "radius")[0], &t[2]], "band radii");
    tiles(d, "split", "1", 2, &[1], &[]);
    refused(&[&t[0], &t[1], &tile_paths(d, "split")[0]], "splits");
    // Damaged and truncated tiles.
    let mut bytes = std::fs::read(&t[1]).unwrap();
    let n = bytes.len();
    bytes[n - 100] ^= 1;
    std::fs::write(d.join("damaged.tile"), &bytes).unwrap();
    refused(&[&t[0], "damaged.tile", &t[2]], "checksum mismatch");
    std::fs::write(d.join("short.tile"), &bytes[..n - 16]).unwrap();
    refused(&[&t[0], "short.tile", &t[2]], "truncated");
    // Tiles and shards together.
    run(
        d,
        &["covariance", "b.toml", "--shard", "0/2", "-q", "--out", "s"],
    );
    refused(
        &[&t[0], "s/b.cov.0-of-2.shard"],
        "cannot be merged together",
    );
    // What `covariance` refuses.
    for (args, want) in [
        (&["--band", "1", "--tile", "0/6"][..], "--tile 0/6"),
        (&["--band", "1", "--tile", "3/3"][..], "--tile <I/N>"),
        (
            &["--band", "auto", "--tile", "0/2"][..],
            "tile: --tile needs the radius",
        ),
        (&["--tile", "0/2"][..], "--band"),
        (&["--band", "1", "--shard", "0/2"][..], "shard"),
    ] {
        let mut all = vec!["covariance", "b.toml", "-q", "--out", "x"];
        all.extend_from_slice(args);
        let o = speckle(d, &all);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        assert!(!d.join("x").exists());
    }
}

/// `--single-beyond R1`: tiles with it merge bitwise into the whole render with it (arrays and
/// summary, which states R1 and the single-only entries); tiles with and without it are not
/// merged together; `R1 >= R` (given, or against the radius `--band auto` chose) and the flag
/// without `--band` are refused naming the flag, writing nothing.
#[test]
fn single_beyond_tiles_merge_bitwise_and_bad_radii_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "b.toml", SCENE);
    let one = ["--single-beyond", "1"];
    let mut args = vec![
        "covariance",
        "b.toml",
        "--band",
        "2",
        "-q",
        "--out",
        "whole",
    ];
    args.extend_from_slice(&one);
    run(d, &args);
    let whole = summary(&d.join("whole/b.cov_band.json"));
    assert_eq!(whole["single_beyond"]["radius"], 1);
    // 2 sources, 9 x 5 pixels: the offsets of max(|dy|, |dx|) = 2 inside the image.
    let within = |r: usize, n: usize| n + (1..=r).map(|k| 2 * (n - k)).sum::<usize>();
    let outer = 4 * (within(2, 5) * within(2, 9) - within(1, 5) * within(1, 9));
    assert_eq!(whole["single_beyond"]["single_only_entries"], outer);
    tiles(d, "t", "2", 3, &[2, 0, 1], &one);
    let paths = tile_paths(d, "t");
    let mut args = vec!["merge", "--out", "m"];
    args.extend(paths.iter().map(String::as_str));
    run(d, &args);
    for f in ["b.cov_band.npy", "b.cov_band_stderr.npy"] {
        let (a, b) = (
            std::fs::read(d.join("whole").join(f)).unwrap(),
            std::fs::read(d.join("m").join(f)).unwrap(),
        );
        assert!(a == b, "{f} of the tiles differs from the whole render's");
    }
    let mut merged = summary(&d.join("m/b.cov_band.json"));
    merged.as_object_mut().unwrap().remove("merged_tiles");
    assert_eq!(whole, merged);
    // A tile without the option among tiles with it.
    tiles(d, "plain", "2", 3, &[1], &[]);
    let o = speckle(
        d,
        &[
            "merge",
            "--out",
            "x",
            &paths[0],
            &tile_paths(d, "plain")[0],
            &paths[2],
        ],
    );
    assert!(!o.status.success() && stderr(&o).contains("--single-beyond radii"));
    assert!(!d.join("x").exists());
    for (args, want) in [
        (
            &["--band", "2", "--single-beyond", "2"][..],
            "--single-beyond",
        ),
        (
            &["--band", "2", "--single-beyond", "3", "--tile", "0/2"][..],
            "--single-beyond",
        ),
        (
            &["--band", "auto", "--single-beyond", "9"][..],
            "--single-beyond",
        ),
        (&["--single-beyond", "1"][..], "--band"),
    ] {
        let mut all = vec!["covariance", "b.toml", "-q", "--out", "x"];
        all.extend_from_slice(args);
        let o = speckle(d, &all);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        assert!(!d.join("x").exists());
    }
}
