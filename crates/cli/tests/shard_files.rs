//! Shard files as untrusted input (issue 27, items 1 and 2): every reproducer of the issue, run
//! through `speckle merge`. Crafted shards (headers that lie about `with_total`, `j`, the header
//! length; NaN or infinite numbers; a scene that names a file outside the shard's folder; an
//! escape sequence in a header string; shards that disagree) are sealed with valid checksums,
//! as a forger would, so that the checks behind the checksum are what is tested. Each must exit
//! with code 2 and a message that names the field, never panic (101), abort, block, print a
//! debug dump or quote a file; a damaged shard (one bit flipped) is refused by its checksum.
//!
//! Run time (release, 2 cores): a few seconds.

mod common;

use common::{speckle, stderr, write};
use serde_json::Value;
use speckle::runs::checksum::xxh64;
use std::path::{Path, PathBuf};
use std::process::Output;

/// One plane wave, three far-field sensors (J = 3).
const J3: &str = r#"
name = "j3"
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
tilts_deg = [0.0]
[[sensors]]
type = "far_arc"
angles_deg = [-10.0, 10.0]
n = 3
[render]
paths = 2003
seed = 5
realizations = 4
paths_per_realization = 101
"#;

/// A lossless isotropic box for the wave solver, 5 configurations.
const WAVE: &str = r#"
name = "w"
wavelength = 1.0
[medium]
size = [4.0, 4.0, 2.0]
mean_free_path = 4.0
[[sources]]
type = "plane_tilts"
tilts_deg = [0.0]
[[sensors]]
type = "far_arc"
angles_deg = [-10.0, 10.0]
n = 3
[render]
configurations = 5
seed = 3
"#;

/// A shard file's header and payload (format version 3: see `crates/runs/src/file.rs`).
struct Parts {
    header: Value,
    payload: Vec<u8>,
}

fn split(bytes: &[u8]) -> Parts {
    let n = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
    Parts {
        header: serde_json::from_slice(&bytes[24..24 + n]).unwrap(),
        payload: bytes[24 + n + 8..bytes.len() - 8].to_vec(),
    }
}

/// The bytes of a shard file of `parts`, with valid checksums.
fn seal(parts: &Parts) -> Vec<u8> {
    let header = serde_json::to_vec(&parts.header).unwrap();
    let mut out = b"SPKSHARD".to_vec();
    out.extend_from_slice(&3u32.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(header.len() as u64).to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(&xxh64(&out).to_le_bytes());
    out.extend_from_slice(&parts.payload);
    out.extend_from_slice(&xxh64(&parts.payload).to_le_bytes());
    out
}

/// Renders shard `spec` of `command` of the scene file `scene` in `dir` into `dir/out` and
/// returns its path.
fn shard(dir: &Path, command: &str, scene: &str, spec: &str, out: &str) -> PathBuf {
    let o = speckle(dir, &[command, scene, "--shard", spec, "--out", out, "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let n = spec.split('/').nth(1).unwrap();
    let i = spec.split('/').next().unwrap();
    let name = if scene.starts_with('w') { "w" } else { "j3" };
    let tag = if command == "covariance" {
        "cov"
    } else {
        command
    };
    let p = dir.join(out).join(format!("{name}.{tag}.{i}-of-{n}.shard"));
    assert!(p.exists(), "{}", p.display());
    p
}

fn merge(dir: &Path, files: &[&Path]) -> Output {
    let mut args = vec!["merge".to_string()];
    args.extend(files.iter().map(|f| f.to_string_lossy().into_owned()));
    args.extend(["--out".into(), "merged".into(), "--no-png".into()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    speckle(dir, &args)
}

/// `speckle merge` of `files` exits with 2 and a message containing `says`, without a panic,
/// a debug dump or output.
fn refused(dir: &Path, files: &[&Path], says: &str) {
    let o = merge(dir, files);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{says}: {e}");
    assert!(e.contains(says), "expected {says:?} in: {e}");
    for never in ["panicked", "MomentsSpec", "{ "] {
        assert!(!e.contains(never), "{never:?} in: {e}");
    }
    assert!(!dir.join("merged").exists(), "a refused merge wrote output");
}

/// `parts` with `edit` applied, written to `dir/name` with valid checksums.
fn crafted(dir: &Path, from: &Path, name: &str, edit: impl FnOnce(&mut Parts)) -> PathBuf {
    let mut parts = split(&std::fs::read(from).unwrap());
    edit(&mut parts);
    let p = dir.join(name);
    std::fs::write(&p, seal(&parts)).unwrap();
    p
}

fn set_f64(payload: &mut [u8], at: usize, x: f64) {
    payload[at..at + 8].copy_from_slice(&x.to_le_bytes());
}

#[test]
fn headers_that_lie_about_sizes_are_refused_before_any_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "j3.toml", J3);
    let cov = shard(d, "covariance", "j3.toml", "0/1", "s");
    let int = shard(d, "intensity", "j3.toml", "0/1", "s");
    // Item 1: a genuine covariance shard whose header says `with_total = false` (was a panic
    // in the covariance estimate).
    let f = crafted(d, &cov, "a.shard", |p| {
        p.header["data"]["with_total"] = false.into();
    });
    refused(d, &[&f], "data.with_total = false, not true");
    // `data.j = 2` for a scene of J = 3, with a payload of the size j = 2 implies (was a
    // panic writing the npy); and `data.j = 2^60` (was a capacity overflow).
    let f = crafted(d, &int, "b.shard", |p| {
        p.header["data"]["j"] = 2.into();
        let batch = 8 + 2 * 3 * 16;
        let mut smaller = Vec::new();
        for b in p.payload.chunks(batch) {
            smaller.extend_from_slice(&b[..8]);
            smaller.extend_from_slice(&b[8..8 + 32]);
            smaller.extend_from_slice(&b[8 + 48..8 + 48 + 32]);
        }
        p.payload = smaller;
    });
    refused(d, &[&f], "data.j = 2, not 3");
    let f = crafted(d, &int, "c.shard", |p| {
        p.header["data"]["j"] = (1u64 << 60).into();
    });
    refused(d, &[&f], "data.j = 1152921504606846976, not 3");
    // Without the scene (Python's `ShardFile.from_bytes`) the sizes must still match the file,
    // computed without overflow.
    let bytes = std::fs::read(&f).unwrap();
    let e = speckle::runs::ShardFile::from_bytes(&bytes, Path::new("c.shard")).unwrap_err();
    assert!(e.to_string().contains("truncated or damaged"), "{e}");
    // A 24-byte file declaring a 2^32-byte header (was an abort on allocation).
    let mut tiny = b"SPKSHARD".to_vec();
    tiny.extend_from_slice(&3u32.to_le_bytes());
    tiny.extend_from_slice(&0u32.to_le_bytes());
    tiny.extend_from_slice(&(1u64 << 32).to_le_bytes());
    let f = write(d, "d.shard", "");
    std::fs::write(&f, &tiny).unwrap();
    refused(
        d,
        &[&f],
        "header length 4294967296 does not fit in its 24 bytes",
    );
}

#[test]
fn damaged_and_non_finite_numbers_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "j3.toml", J3);
    write(d, "w.toml", WAVE);
    let cov = shard(d, "covariance", "j3.toml", "0/1", "s");
    // One bit flipped in the middle of a genuine shard's numbers (merged silently before).
    let mut bytes = std::fs::read(&cov).unwrap();
    let mid = bytes.len() - 8 - (split(&bytes).payload.len() / 2);
    bytes[mid] ^= 0x10;
    let f = d.join("flipped.shard");
    std::fs::write(&f, &bytes).unwrap();
    refused(
        d,
        &[&f],
        "numbers are damaged (their checksum does not match)",
    );
    // One bit flipped in the header.
    let mut bytes = std::fs::read(&cov).unwrap();
    bytes[40] ^= 0x01;
    std::fs::write(&f, &bytes).unwrap();
    refused(d, &[&f], "header is damaged");
    // NaN or infinite numbers behind valid checksums: batch sums, means (without the warning
    // that explains NaN means), fields, wave rows.
    let f = crafted(d, &cov, "sums.shard", |p| {
        set_f64(&mut p.payload, 8, f64::NAN)
    });
    refused(d, &[&f], "NaN or infinite value in the sums of batch 0");
    let f = crafted(d, &cov, "means.shard", |p| {
        let at = p.payload.len() - 16;
        set_f64(&mut p.payload, at, f64::INFINITY);
    });
    refused(d, &[&f], "NaN or infinite value in the speckle means");
    let fields = shard(d, "fields", "j3.toml", "0/1", "s");
    let f = crafted(d, &fields, "fields.shard", |p| {
        set_f64(&mut p.payload, 0, f64::NAN)
    });
    refused(d, &[&f], "NaN or infinite value in the fields");
    let wave = shard(d, "wave", "w.toml", "0/1", "s");
    let f = crafted(d, &wave, "wave.shard", |p| {
        set_f64(&mut p.payload, 16, f64::NEG_INFINITY)
    });
    refused(d, &[&f], "NaN or infinite value in the fields");
    // Finite numbers too large for a render overflow in the merge's sums (found by the shard
    // fuzzer): the merged estimate is refused.
    let f = crafted(d, &wave, "big.shard", |p| {
        set_f64(&mut p.payload, 16, 1e308)
    });
    refused(d, &[&f], "the merged wave is not finite");
}

#[test]
fn shards_that_disagree_are_named_without_a_debug_dump() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "j3.toml", J3);
    let a = shard(d, "covariance", "j3.toml", "0/2", "s");
    let b = shard(d, "covariance", "j3.toml", "1/2", "s");
    let f = crafted(d, &b, "b.shard", |p| {
        p.header["data"]["with_total"] = false.into();
    });
    refused(
        d,
        &[&a, &f],
        "shard 1/2 is not of the run its scene describes",
    );
    refused(d, &[&a, &f], "data.with_total = false, not true");
    let f = crafted(d, &b, "c.shard", |p| {
        p.header["data"]["paths"] = 2004.into();
    });
    refused(d, &[&a, &f], "data.paths = 2004, not 2003");
    let o = merge(d, &[&a, &b]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_shards_scene_never_quotes_the_files_it_names() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "j3.toml", J3);
    let cov = shard(d, "covariance", "j3.toml", "0/1", "s");
    // A header naming another folder as the scene's (`base = "/etc"`, `phase.file = "passwd"`
    // in the issue): the error names the file, never its contents.
    let other = d.join("elsewhere");
    std::fs::create_dir(&other).unwrap();
    write(&other, "secret", "TOP-SECRET-LINE\nmore\n");
    let f = crafted(d, &cov, "x.shard", |p| {
        let toml = p.header["scene_toml"].as_str().unwrap();
        let toml = toml.replace(
            "type = \"hg\"\ng = 0.4",
            "type = \"tabulated\"\nfile = \"secret\"",
        );
        assert!(toml.contains("secret"), "{toml}");
        p.header["scene_toml"] = toml.into();
        p.header["base"] = other.to_string_lossy().into_owned().into();
    });
    refused(d, &[&f], "phase.file: ");
    let e = stderr(&merge(d, &[&f]));
    assert!(!e.contains("TOP-SECRET"), "{e}");
    #[cfg(unix)]
    for (base, file) in [("/etc", "passwd"), ("/proc/self", "environ")] {
        let f = crafted(d, &cov, "y.shard", |p| {
            let toml = p.header["scene_toml"].as_str().unwrap();
            let toml = toml.replace(
                "type = \"hg\"\ng = 0.4",
                &format!("type = \"tabulated\"\nfile = \"{file}\""),
            );
            p.header["scene_toml"] = toml.into();
            p.header["base"] = base.into();
        });
        let o = merge(d, &[&f]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(
            e.contains("contents not shown") || e.contains("cannot read"),
            "{e}"
        );
        assert!(!e.contains("root:") && !e.contains("PATH="), "{e}");
    }
}

#[test]
fn header_strings_are_printed_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "j3.toml", J3);
    let cov = shard(d, "covariance", "j3.toml", "0/1", "s");
    let f = crafted(d, &cov, "x.shard", |p| {
        p.header["data"]["mean_warning"] = "\u{1b}[2J\u{1b}]0;owned\u{7}".into();
    });
    let o = merge(d, &[&f]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(!e.contains('\u{1b}') && !e.contains('\u{7}'), "{e:?}");
    assert!(e.contains("warning: \\u{1b}[2J"), "{e}");
}

#[cfg(unix)]
#[test]
fn a_fifo_given_as_a_shard_is_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = d.join("x.shard");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let start = std::time::Instant::now();
    let mut child = common::bin()
        .args(["merge", "x.shard", "--out", "merged"])
        .current_dir(d)
        .stdin(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > std::time::Duration::from_secs(10) {
            let _ = child.kill();
            panic!("speckle merge of a FIFO still runs after 10 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    let e = stderr(&child.wait_with_output().unwrap());
    assert_eq!(status.code(), Some(2), "{e}");
    assert!(e.contains("not a regular file"), "{e}");
}

#[test]
fn shards_of_a_bare_scene_file_name_merge_from_another_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(
        d,
        "amp.csv",
        "theta_deg,re,im\n0,1,0\n90,0.5,0.1\n180,0.2,0\n",
    );
    write(
        d,
        "j3.toml",
        &J3.replace(
            "type = \"hg\"\ng = 0.4",
            "type = \"tabulated\"\nfile = \"amp.csv\"",
        ),
    );
    let s = shard(d, "covariance", "j3.toml", "0/1", "s");
    let header = split(&std::fs::read(&s).unwrap()).header;
    let base = PathBuf::from(header["base"].as_str().unwrap());
    assert!(base.is_absolute(), "{}", base.display());
    assert_eq!(
        base.canonicalize().unwrap(),
        d.canonicalize().unwrap(),
        "base"
    );
    let away = d.join("away");
    std::fs::create_dir(&away).unwrap();
    let o = merge(&away, &[&s]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(away.join("merged/j3.cov.npy").exists());
}
