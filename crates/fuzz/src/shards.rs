//! Shard files as untrusted input (issue 27): genuine shards of every sharded render
//! (covariance, intensity, fields, wave) of small scenes, mutated as a damaged copy or a forger
//! would make them, then read and merged with the run's other shards.
//!
//! The mutations: bytes flipped, the file truncated or extended (checksums left as they are);
//! a header field set to an extreme or to another type (sizes of 0, 2^32, 2^60, `u64::MAX`,
//! negative, fractional, `null`, strings, flags swapped), the header's folder `base` moved to
//! the sandbox's root (whose `outside.csv` no message may quote), its scene text mutated as the
//! scene fuzzer mutates scenes or made to name `secret.csv` or `outside.csv` as its phase table,
//! a number of the payload set to NaN or an infinity, an escape sequence in `mean_warning`; each
//! resealed with valid checksums (a forger can compute them).
//!
//! The oracle: no panic or hang; no message that quotes a file (not even an excerpt: a shard's
//! scene may name any file); a merge that succeeds gives finite numbers (a covariance's means
//! NaN only with their warning).

use crate::{Finding, OUTSIDE, Rng, SECRET, Tally, mutate, watched};
use speckle::estimators::CovarianceEstimate;
use speckle::phase::Complex64;
use speckle::runs::checksum::xxh64;
use speckle::runs::{Kind, Outcome, ShardFile, merge, render_shard};
use speckle::scene::{Overrides, load_str};
use speckle::stats::{NoProgress, Shard};
use std::path::Path;
use std::time::Instant;

/// A scene for the path-traced renders: a tabulated phase read from the scene's folder.
const PATHS: &str = r#"
name = "fz"
wavelength = 1.0
[medium]
size = [6.0, 6.0, 2.0]
mean_free_path = 3.0
albedo = 0.9
[phase]
type = "tabulated"
file = "amp.csv"
[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 4.0]
[[sensors]]
type = "far_arc"
angles_deg = [-10.0, 10.0]
n = 2
[render]
paths = 600
seed = 3
realizations = 3
paths_per_realization = 40
"#;

/// A lossless isotropic box for the wave solver.
const WAVE: &str = r#"
name = "fzw"
wavelength = 1.0
[medium]
size = [3.0, 3.0, 1.5]
mean_free_path = 4.0
[[sources]]
type = "plane_tilts"
tilts_deg = [0.0]
[[sensors]]
type = "far_arc"
angles_deg = [-10.0, 10.0]
n = 2
[render]
configurations = 3
seed = 3
"#;

/// The bytes of both shards of a split in two of every sharded render, the scenes' files in
/// `base` (the sandbox's scene folder).
pub fn genuine(base: &Path) -> Vec<Vec<Vec<u8>>> {
    let mut runs = Vec::new();
    for (text, kinds) in [
        (
            PATHS,
            &[Kind::Covariance, Kind::Intensity, Kind::Fields][..],
        ),
        (WAVE, &[Kind::Wave][..]),
    ] {
        let p = load_str(text, "fz.toml", base, "fz", &Overrides::default())
            .expect("the fuzzer's shard scenes load");
        for &kind in kinds {
            runs.push(
                (0..2)
                    .map(|i| {
                        let s = Shard { index: i, count: 2 };
                        render_shard(&p, kind, s, &NoProgress)
                            .expect("the fuzzer's shards render")
                            .to_bytes()
                    })
                    .collect(),
            );
        }
    }
    runs
}

/// A shard file's header (JSON) and payload, if `bytes` has the layout of one.
fn split(bytes: &[u8]) -> Option<(serde_json::Value, Vec<u8>)> {
    let n = usize::try_from(u64::from_le_bytes(bytes.get(16..24)?.try_into().ok()?)).ok()?;
    let end = 24usize.checked_add(n)?;
    let header = serde_json::from_slice(bytes.get(24..end)?).ok()?;
    let payload = bytes.get(end + 8..bytes.len().checked_sub(8)?)?.to_vec();
    Some((header, payload))
}

/// The bytes of a shard file of `header` and `payload`, with valid checksums.
fn seal(header: &serde_json::Value, payload: &[u8]) -> Vec<u8> {
    let h = serde_json::to_vec(header).unwrap_or_default();
    let mut out = bytes_of_prefix(&h);
    out.extend_from_slice(&xxh64(&out).to_le_bytes());
    out.extend_from_slice(payload);
    out.extend_from_slice(&xxh64(payload).to_le_bytes());
    out
}

fn bytes_of_prefix(header: &[u8]) -> Vec<u8> {
    let mut out = b"SPKSHARD".to_vec();
    out.extend_from_slice(&3u32.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(header.len() as u64).to_le_bytes());
    out.extend_from_slice(header);
    out
}

/// Values a header field may be set to.
fn extreme(rng: &mut Rng) -> serde_json::Value {
    use serde_json::json;
    let values = [
        json!(0),
        json!(1),
        json!(2),
        json!(3),
        json!(1u64 << 32),
        json!(1u64 << 60),
        json!(u64::MAX),
        json!(-1),
        json!(2.5),
        json!(1e308),
        json!(null),
        json!(true),
        json!(false),
        json!("x"),
        json!([0, 1]),
        json!([1, 0]),
        json!([0, u64::MAX]),
        json!({}),
        json!("\u{1b}[2J\u{1b}]0;t\u{7}"),
    ];
    rng.pick(&values).clone()
}

/// A variant of the shard `bytes`, and what was done.
pub fn mutate_shard(bytes: &[u8], rng: &mut Rng) -> (Vec<u8>, String) {
    let Some((mut header, mut payload)) = split(bytes) else {
        return (bytes.to_vec(), "unchanged".into());
    };
    let what = match rng.below(8) {
        0 => {
            let mut b = bytes.to_vec();
            let at = rng.below(b.len());
            b[at] ^= 1 << rng.below(8);
            return (b, format!("bit flipped at byte {at}"));
        }
        1 => {
            let mut b = bytes.to_vec();
            let n = rng.below(b.len());
            if rng.below(2) == 0 {
                b.truncate(n);
                return (b, format!("truncated to {n} bytes"));
            }
            b.extend(std::iter::repeat_n(0u8, n % 64 + 1));
            return (b, "extended".into());
        }
        2 | 3 => {
            let keys = [
                "j",
                "paths",
                "parts",
                "layout",
                "with_total",
                "mean_pairs",
                "mean_warning",
                "add_mean",
                "paths_per_realization",
            ];
            let key = *rng.pick(&keys);
            let v = extreme(rng);
            let what = format!("data.{key} = {v}");
            header["data"][key] = v;
            what
        }
        4 => {
            let keys = [
                "kind",
                "shard",
                "units",
                "total_units",
                "seed",
                "threads",
                "wall_time_s",
                "origin",
                "name",
                "base",
                "run_hash",
                "speckle_version",
            ];
            let key = *rng.pick(&keys);
            let v = extreme(rng);
            let what = format!("{key} = {v}");
            header[key] = v;
            what
        }
        5 => {
            // Another folder, or a phase table that is a secret or outside the folder.
            let base = header["base"].as_str().unwrap_or("").to_string();
            let root = Path::new(&base)
                .parent()
                .map(|p| p.to_string_lossy().into_owned());
            let toml = header["scene_toml"].as_str().unwrap_or("").to_string();
            let (file, folder) = match rng.below(3) {
                0 => ("outside.csv", root.unwrap_or(base)),
                1 => ("secret.csv", base),
                _ => ("amp.csv", root.unwrap_or(base)),
            };
            let toml = toml.replace("\"amp.csv\"", &format!("\"{file}\""));
            header["scene_toml"] = toml.into();
            header["base"] = folder.clone().into();
            format!("phase.file = {file} in {folder}")
        }
        6 => {
            let toml = header["scene_toml"].as_str().unwrap_or("").to_string();
            let others = vec![("shard".to_string(), toml.clone())];
            header["scene_toml"] = mutate(&toml, &others, rng).into();
            "scene_toml mutated".into()
        }
        _ => {
            if payload.len() < 16 {
                return (bytes.to_vec(), "unchanged".into());
            }
            let at = 8 * rng.below(payload.len() / 8);
            let x = *rng.pick(&[f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e308]);
            payload[at..at + 8].copy_from_slice(&x.to_le_bytes());
            format!("payload word {} = {x}", at / 8)
        }
    };
    (seal(&header, &payload), what)
}

/// Whether `message` quotes a file a shard's scene names (not even an excerpt).
fn echo(message: &str) -> Option<Finding> {
    (message.contains(OUTSIDE) || message.contains(&SECRET[..6]))
        .then(|| Finding::Echo(format!("a shard's error quotes a file: {message}")))
}

fn finite(v: &[Complex64]) -> bool {
    v.iter().all(|z| z.re.is_finite() && z.im.is_finite())
}

/// The oracle: reads each of `files` and merges them as one run.
pub fn check_shards(files: &[Vec<u8>]) -> Result<(), Finding> {
    let mut shards = Vec::new();
    for b in files {
        match ShardFile::from_bytes(b, Path::new("fz.shard")) {
            Ok(s) => shards.push(s),
            Err(e) => return echo(&e.to_string()).map_or(Ok(()), Err),
        }
    }
    let out = match merge(shards, &Overrides::default()) {
        Ok(m) => m.outcome,
        Err(e) => return echo(&e.to_string()).map_or(Ok(()), Err),
    };
    let est_finite = |e: &CovarianceEstimate| {
        [&e.total, &e.single, &e.multiple]
            .iter()
            .all(|m| finite(m.value.as_slice()) && finite(m.std_error.as_slice()))
    };
    let ok = match &out {
        Outcome::Covariance(e, means) => {
            est_finite(e) && (means.warning.is_some() || finite(&means.values))
        }
        Outcome::Intensity(e) => est_finite(e),
        Outcome::Fields(f) => finite(f.fields.as_slice()) && finite(&f.mean),
        Outcome::Wave(w) => {
            finite(w.fields.as_slice())
                && finite(&w.mean)
                && finite(w.covariance.value.as_slice())
                && w.mean_scatterers.is_finite()
        }
    };
    if ok {
        Ok(())
    } else {
        Err(Finding::NotFinite(format!(
            "a merge of shards gave non-finite {:?} numbers",
            out.kind()
        )))
    }
}

/// Merges the genuine runs, then variants with one shard mutated, from `seed`, until `inputs`
/// inputs or `seconds` have passed; stops at the first hang.
pub fn run_shards(seed: u64, inputs: u64, seconds: f64, base: &Path) -> Tally {
    let runs = genuine(base);
    let start = Instant::now();
    let mut rng = Rng::new(seed);
    let mut tally = Tally::default();
    let mut n = 0usize;
    while tally.inputs < inputs && start.elapsed().as_secs_f64() < seconds {
        let mut files = runs[n % runs.len()].clone();
        let what = if n < runs.len() {
            "genuine".to_string()
        } else {
            let k = rng.below(files.len());
            let (b, mut what) = mutate_shard(&files[k], &mut rng);
            files[k] = b;
            // Sometimes a second mutation, or the other shard dropped.
            match rng.below(6) {
                0 => {
                    let (b, w) = mutate_shard(&files[k], &mut rng);
                    files[k] = b;
                    what = format!("{what}; {w}");
                }
                1 => {
                    files.remove(1 - k);
                    what = format!("{what}; alone");
                }
                _ => {}
            }
            format!("shard {k} of a {}: {what}", n % runs.len())
        };
        n += 1;
        tally.inputs += 1;
        if let Err(f) = watched(move || check_shards(&files)) {
            let hang = f == Finding::Hang;
            tally.findings.push((f, what));
            if hang {
                break;
            }
        }
    }
    tally
}
