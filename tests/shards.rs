//! Sharded runs: merging the shards of a run gives bitwise the single run, for 1, 2, 3 and 7
//! shards rendered on 1, 2 or 3 threads, for the covariance, intensity, fields and wave
//! renders (every value, standard error, field, mean and scatterer count compared bit for bit,
//! shards passed through their file bytes and merged in reverse order); a missing shard is
//! named by index and rendering it alone completes the merge; shards of other runs, overlapping
//! shards and damaged files are refused; shard files merge from disk, their scene's relative
//! input files found from anywhere, and a changed input file is refused.
//!
//! Path counts make the splits uneven: 10 007 paths are 127 batches (126 of 79 and one of 53),
//! so 7 shards hold 18 or 19 batches; 9 realizations of 503 paths are two work items each; 11
//! wave configurations.
//!
//! Run time (release, 2 cores): about 10 s.

use speckle::estimators::{CovarianceEstimate, MatrixEstimate, NoProgress};
use speckle::runs::{Kind, Outcome, RunError, ShardFile, merge, merge_files, render, render_shard};
use speckle::scene::{Overrides, Problem, load_file, load_str};
use speckle::stats::{Shard, ShardError};
use std::path::{Path, PathBuf};

/// A slab with absorption and HG scattering, a plane wave and a point source, far-field
/// sensors in transmission and reflection and a point sensor (`J = 6`), first directions
/// from the phase function.
const MC: &str = r#"
name = "mc"
wavelength = 0.3
[medium]
size = [6.0, 5.0, 2.0]
center = [0.1, -0.2, 0.0]
mean_free_path = 0.8
albedo = 0.95
[phase]
type = "hg"
g = 0.6
[[sources]]
type = "plane"
direction = [0.1, 0.05, 1.0]
[[sources]]
type = "point"
position = [-1.0, 0.5, -2.5]
[[sensors]]
type = "far"
direction = [0.2, 0.0, 1.0]
[[sensors]]
type = "far"
direction = [-0.3, 0.1, -1.0]
[[sensors]]
type = "point"
position = [0.5, 0.0, 3.0]
[render]
paths = 10007
seed = 11
realizations = 9
paths_per_realization = 503
first_direction = "phase"
first_direction_axis = [0.0, 0.0, 1.0]
"#;

/// A small lossless isotropic box for the wave solver (about 40 scatterers), 11
/// configurations, two plane waves and three far-field sensors.
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

fn problem(kind: Kind, over: &Overrides) -> Problem {
    let text = if kind == Kind::Wave { WAVE } else { MC };
    load_str(text, "test", Path::new("."), "t", over).unwrap()
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

fn matrix_bits(m: &MatrixEstimate, out: &mut Vec<u64>) {
    for z in m.value.as_slice().iter().chain(m.std_error.as_slice()) {
        out.extend([z.re.to_bits(), z.im.to_bits()]);
    }
    out.push(m.samples);
}

fn covariance_bits(e: &CovarianceEstimate, out: &mut Vec<u64>) {
    let CovarianceEstimate {
        single,
        multiple,
        total,
        paths,
    } = e;
    for m in [single, multiple, total] {
        matrix_bits(m, out);
    }
    out.push(*paths);
}

/// Every number of an outcome, as bits.
fn bits(o: &Outcome) -> Vec<u64> {
    let mut v = Vec::new();
    let c = |z: &[num_complex::Complex64], v: &mut Vec<u64>| {
        v.extend(z.iter().flat_map(|z| [z.re.to_bits(), z.im.to_bits()]))
    };
    match o {
        Outcome::Covariance(e, means) => {
            covariance_bits(e, &mut v);
            c(&means.values, &mut v);
            v.push(u64::from(means.warning.is_some()));
        }
        Outcome::Intensity(e) => covariance_bits(e, &mut v),
        Outcome::Fields(f) => {
            c(f.fields.as_slice(), &mut v);
            c(&f.mean, &mut v);
            v.push(f.paths_per_realization);
        }
        Outcome::Wave(w) => {
            c(w.fields.as_slice(), &mut v);
            c(&w.mean, &mut v);
            c(&w.mean_std_error, &mut v);
            matrix_bits(&w.covariance, &mut v);
            v.extend(w.scatterer_counts.iter().map(|&n| n as u64));
            v.extend([
                w.configurations,
                w.mean_scatterers.to_bits(),
                w.expected_scatterers.to_bits(),
            ]);
        }
    }
    v
}

fn shard(p: &Problem, kind: Kind, i: usize, n: usize, threads: usize) -> ShardFile {
    let s = Shard::new(i, n).unwrap();
    in_pool(threads, || render_shard(p, kind, s, &NoProgress).unwrap())
}

/// Through the bytes of its file.
fn reread(s: &ShardFile) -> ShardFile {
    ShardFile::from_bytes(&s.to_bytes(), Path::new("mem")).unwrap()
}

#[test]
fn merged_shards_are_bitwise_the_single_run() {
    let over = Overrides::default();
    for kind in Kind::ALL {
        let p = problem(kind, &over);
        let whole = in_pool(1, || render(&p, kind, &NoProgress).unwrap());
        let whole_bits = bits(&whole);
        assert_eq!(
            bits(&in_pool(3, || render(&p, kind, &NoProgress).unwrap())),
            whole_bits,
            "{kind:?}: whole runs on 1 and 3 threads"
        );
        for n in [1, 2, 3, 7] {
            let mut shards: Vec<ShardFile> = (0..n)
                .map(|i| reread(&shard(&p, kind, i, n, 1 + i % 3)))
                .collect();
            shards.reverse();
            let merged = in_pool(2, || merge(shards, &over).unwrap());
            assert_eq!(merged.shards, n);
            assert_eq!(
                bits(&merged.outcome),
                whole_bits,
                "{kind:?}: {n} shards differ from the single run"
            );
        }
        // Shards of different counts that tile the run: 0/2, then 2/4 and 3/4.
        let mixed = vec![
            shard(&p, kind, 3, 4, 1),
            shard(&p, kind, 0, 2, 2),
            shard(&p, kind, 2, 4, 1),
        ];
        let merged = merge(mixed, &over).unwrap();
        assert_eq!(bits(&merged.outcome), whole_bits, "{kind:?}: 0/2, 2/4, 3/4");
    }
}

#[test]
fn a_missing_shard_is_named_and_rendering_it_alone_completes_the_merge() {
    let over = Overrides::default();
    for kind in [Kind::Covariance, Kind::Wave] {
        let p = problem(kind, &over);
        let whole = bits(&render(&p, kind, &NoProgress).unwrap());
        let mut shards: Vec<ShardFile> = [0, 1, 2, 4, 6]
            .into_iter()
            .map(|i| shard(&p, kind, i, 7, 2))
            .collect();
        let e = merge(shards.clone(), &over).unwrap_err();
        match &e {
            RunError::Shard(ShardError::Missing { missing, count, .. }) => {
                assert_eq!((missing.as_slice(), *count), (&[3, 5][..], 7), "{e}");
            }
            _ => panic!("{kind:?}: {e}"),
        }
        assert!(
            e.to_string().starts_with("shards 3/7, 5/7 are missing"),
            "{e}"
        );
        shards.push(shard(&p, kind, 5, 7, 1));
        let e = merge(shards.clone(), &over).unwrap_err();
        assert!(e.to_string().starts_with("shard 3/7 is missing"), "{e}");
        shards.push(shard(&p, kind, 3, 7, 3));
        assert_eq!(bits(&merge(shards, &over).unwrap().outcome), whole);
    }
}

fn error_of(shards: Vec<ShardFile>) -> String {
    merge(shards, &Overrides::default())
        .map(|_| ())
        .unwrap_err()
        .to_string()
}

#[test]
fn shards_of_other_runs_overlapping_shards_and_damaged_files_are_refused() {
    let over = Overrides::default();
    let p = problem(Kind::Covariance, &over);
    let a = shard(&p, Kind::Covariance, 0, 2, 2);
    let seed = problem(
        Kind::Covariance,
        &Overrides {
            seed: Some(12),
            ..Default::default()
        },
    );
    let paths = problem(
        Kind::Covariance,
        &Overrides {
            paths: Some(10_008),
            ..Default::default()
        },
    );
    let e = error_of(vec![a.clone(), shard(&seed, Kind::Covariance, 1, 2, 2)]);
    assert!(e.contains("different seeds (12 and 11)"), "{e}");
    let e = error_of(vec![a.clone(), shard(&paths, Kind::Covariance, 1, 2, 2)]);
    assert!(e.contains("different scenes or render settings"), "{e}");
    let e = error_of(vec![a.clone(), shard(&p, Kind::Intensity, 1, 2, 2)]);
    assert!(
        e.contains("different renders (intensity and covariance)"),
        "{e}"
    );
    let e = error_of(vec![a.clone(), shard(&p, Kind::Covariance, 1, 3, 2)]);
    assert!(
        e.contains("shards 0/2 (batches 0..63) and 1/3 (batches 42..84) overlap"),
        "{e}"
    );
    let e = error_of(vec![a.clone(), a.clone()]);
    assert!(e.contains("overlap"), "{e}");
    // Damaged files.
    let bytes = a.to_bytes();
    let e = ShardFile::from_bytes(&bytes[..bytes.len() - 8], Path::new("x.shard")).unwrap_err();
    assert!(
        e.to_string().starts_with("x.shard: truncated or damaged"),
        "{e}"
    );
    let e = ShardFile::from_bytes(b"not a shard at all, really", Path::new("y")).unwrap_err();
    assert_eq!(e.to_string(), "y: not a speckle shard file");
    assert!(matches!(error_of(vec![]).as_str(), "no shards to merge"));
    // A wave shard whose scatterer count is beyond the solver (a fuzz finding: their sum
    // overflowed and panicked) is refused.
    let w = problem(Kind::Wave, &over);
    let mut b = shard(&w, Kind::Wave, 1, 2, 2);
    if let speckle::runs::ShardData::Wave(s) = &mut b.data {
        s.scatterer_counts[0] = usize::MAX;
    }
    let e = error_of(vec![shard(&w, Kind::Wave, 0, 2, 2), b]);
    assert!(e.contains("scatterers, above the solver's limit"), "{e}");
}

/// A scene with a phase table next to it, rendered in shards into files and merged from
/// them; then the table changes, and the merge is refused.
#[test]
fn shard_files_merge_from_disk_and_find_the_scenes_input_files() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir(&scenes).unwrap();
    let table = "theta_deg,re,im\n0,1,0\n60,0.6,0.1\n120,0.3,0\n180,0.2,0\n";
    std::fs::write(scenes.join("amp.csv"), table).unwrap();
    let text = MC.replace(
        "[phase]\ntype = \"hg\"\ng = 0.6",
        "[phase]\ntype = \"tabulated\"\nfile = \"amp.csv\"",
    );
    std::fs::write(scenes.join("t.toml"), &text).unwrap();
    let over = Overrides {
        paths: Some(3001),
        ..Default::default()
    };
    let p = load_file(&scenes.join("t.toml"), &over).unwrap();
    let whole = bits(&render(&p, Kind::Covariance, &NoProgress).unwrap());
    let files: Vec<PathBuf> = (0..3)
        .map(|i| {
            let s = shard(&p, Kind::Covariance, i, 3, 2);
            let path = dir.path().join(s.file_name());
            std::fs::write(&path, s.to_bytes()).unwrap();
            path
        })
        .collect();
    assert!(files[1].ends_with("mc.cov.1-of-3.shard"), "{files:?}");
    let m = merge_files(&files, &Overrides::default()).unwrap();
    assert_eq!(bits(&m.outcome), whole);
    assert_eq!(m.count, Some(3));
    let e = merge_files(&files[..2], &Overrides::default()).unwrap_err();
    assert!(e.to_string().starts_with("shard 2/3 is missing"), "{e}");
    std::fs::write(scenes.join("amp.csv"), table.replace("0.6,0.1", "0.7,0.1")).unwrap();
    let e = merge_files(&files, &Overrides::default()).unwrap_err();
    assert!(e.to_string().contains("no longer builds to the run"), "{e}");
}
