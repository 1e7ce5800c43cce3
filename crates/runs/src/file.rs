//! Shard files: a self-describing header (JSON) and the shard's numbers (little-endian binary),
//! each followed by its checksum.
//!
//! ```text
//! bytes 0..8    b"SPKSHARD"
//! bytes 8..12   format version, u32 little-endian (3)
//! bytes 12..16  0 (reserved)
//! bytes 16..24  header length H, u64 little-endian (at most MAX_HEADER_BYTES)
//! H bytes       the header, JSON (UTF-8): kind, shard, units, run hash, seed, the scene (TOML
//!               text, numbers exact), where its input files are, wall time, and the sizes below
//! 8 bytes       the header's checksum: XXH64 (seed 0) of bytes 0..24 + H, u64 little-endian
//! payload       covariance, intensity: for each batch of the shard, its path count (u64) and
//!               each part's sum in its kept entries (the upper triangle, row by row, of a
//!               Hermitian sum; every entry otherwise), complex128 (re, im as f64); then, for a
//!               covariance, the speckle means of the shard's share of the pairs (header
//!               `data.mean_pairs`, complex128 each);
//!               fields: the rows (realizations x J complex128, before the mean is added),
//!               then with `data.add_mean` the means of the shard's share of the pairs
//!               (`data.mean_pairs`, complex128 each);
//!               wave: the rows (configurations x J complex128), the scatterer count of each
//!               configuration (u64), the expected count (f64)
//! 8 bytes       the payload's checksum: XXH64 (seed 0) of the payload, u64 little-endian
//! ```
//!
//! Numbers are stored bit for bit, never through decimal text, so that a merge is exact. Shard
//! files are read as untrusted input (`read.rs`): the checksums find damage in transit, and
//! every size in the header is checked against the file's length (and, in a merge, against the
//! scene) before anything is allocated.

use crate::checksum::xxh64;
use crate::{Kind, RunError, run_hash};
use num_complex::Complex64;
use serde_json::{Value, json};
use speckle_estimators::{CovarianceShard, FieldShard};
use speckle_scene::Problem;
use speckle_stats::{Layout, MomentsSpec, PairShare, Shard};
use speckle_wave::WaveShard;
use std::ops::Range;
use std::path::{Path, PathBuf};

pub(crate) const MAGIC: &[u8; 8] = b"SPKSHARD";
pub(crate) const VERSION: u32 = 3;

/// What a shard file says about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// The render.
    pub kind: Kind,
    /// Which shard.
    pub shard: Shard,
    /// Its units (batches, realizations or configurations) among the run's.
    pub units: Range<usize>,
    /// The run's number of units.
    pub total: usize,
    /// The run hash ([`run_hash`]).
    pub run_hash: String,
    /// The seed.
    pub seed: u64,
    /// The scene's name (output prefix).
    pub name: String,
    /// Where the scene came from (a path, `<embedded NAME>`, `<dict>`).
    pub origin: String,
    /// The directory its relative input files are looked up in (absolute).
    pub base: PathBuf,
    /// The scene as parsed and validated, with its overrides and defaults, as TOML.
    pub scene_toml: String,
    /// The crate version that rendered it.
    pub version: String,
    /// Wall time of the shard's render, in seconds.
    pub wall_time_s: f64,
    /// Threads the shard ran on.
    pub threads: usize,
}

/// A shard's numbers.
#[derive(Debug, Clone, PartialEq)]
pub enum ShardData {
    /// Batch sums of a covariance or intensity render.
    Moments(CovarianceShard),
    /// Batch sums of a covariance render and the speckle means of the shard's share of the
    /// pairs, with the warning for NaN means.
    Covariance(CovarianceShard, PairShare, Option<String>),
    /// Realizations of a field render.
    Fields(FieldShard),
    /// Configurations of the wave solver.
    Wave(WaveShard),
}

/// One shard of a run: its header and its numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct ShardFile {
    /// What it is.
    pub header: Header,
    /// Its numbers.
    pub data: ShardData,
}

pub(crate) fn bad(path: &Path, reason: impl Into<String>) -> RunError {
    RunError::File {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

fn layout_name(l: Layout) -> &'static str {
    match l {
        Layout::Hermitian => "hermitian",
        Layout::HermitianDiagonal => "hermitian_diagonal",
        Layout::General => "general",
        Layout::GeneralDiagonal => "general_diagonal",
    }
}

pub(crate) fn layout_of(name: &str) -> Option<Layout> {
    [
        Layout::Hermitian,
        Layout::HermitianDiagonal,
        Layout::General,
        Layout::GeneralDiagonal,
    ]
    .into_iter()
    .find(|l| layout_name(*l) == name)
}

impl ShardFile {
    /// A shard of `p`'s render of `kind` with its numbers `data`, rendered in `wall` seconds.
    pub fn new(p: &Problem, kind: Kind, data: ShardData, wall: f64) -> Result<Self, RunError> {
        let (shard, units, total) = match &data {
            ShardData::Moments(m) | ShardData::Covariance(m, ..) => (
                m.moments.shard,
                m.moments.units.clone(),
                m.moments.spec.batches().count(),
            ),
            ShardData::Fields(f) => (f.rows.shard, f.rows.units.clone(), f.rows.total),
            ShardData::Wave(w) => (w.rows.shard, w.rows.units.clone(), w.rows.total),
        };
        let (scene_toml, base) = scene_source(p)?;
        Ok(Self {
            header: Header {
                kind,
                shard,
                units,
                total,
                run_hash: run_hash(p, kind),
                seed: p.render.seed,
                name: p.name.clone(),
                origin: p.origin.clone(),
                base,
                scene_toml,
                version: env!("CARGO_PKG_VERSION").to_string(),
                wall_time_s: wall,
                threads: rayon::current_num_threads(),
            },
            data,
        })
    }

    /// The file name it is written under: `<name>.<tag>.<i>-of-<n>.shard`.
    pub fn file_name(&self) -> String {
        let h = &self.header;
        format!(
            "{}.{}.{}-of-{}.shard",
            h.name,
            h.kind.tag(),
            h.shard.index,
            h.shard.count
        )
    }

    /// The header as JSON, with the sizes of the payload.
    fn header_json(&self) -> Value {
        let h = &self.header;
        let data = match &self.data {
            ShardData::Moments(m) => moments_json(m),
            ShardData::Covariance(m, mean, warning) => {
                let mut d = moments_json(m);
                d["mean_pairs"] = json!([mean.pairs.start, mean.pairs.end]);
                d["mean_warning"] = json!(warning);
                d
            }
            ShardData::Fields(f) => {
                json!({"j": f.rows.rows.cols(), "paths_per_realization": f.paths_per_realization,
                       "add_mean": f.add_mean, "mean_pairs": [f.mean.pairs.start, f.mean.pairs.end]})
            }
            ShardData::Wave(w) => json!({"j": w.rows.rows.cols()}),
        };
        json!({
            "format": "speckle shard",
            "kind": h.kind.tag(),
            "command": h.kind.command(),
            "shard": [h.shard.index, h.shard.count],
            "units": [h.units.start, h.units.end],
            "total_units": h.total,
            "unit": h.kind.unit(),
            "run_hash": h.run_hash,
            "seed": h.seed,
            "name": h.name,
            "origin": h.origin,
            "base": h.base.to_string_lossy(),
            "scene_toml": h.scene_toml,
            "speckle_version": h.version,
            "wall_time_s": h.wall_time_s,
            "threads": h.threads,
            "data": data,
        })
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let header = serde_json::to_vec(&self.header_json()).unwrap_or_default();
        let mut out = Vec::with_capacity(40 + header.len() + self.payload_len() as usize);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&(header.len() as u64).to_le_bytes());
        out.extend_from_slice(&header);
        out.extend_from_slice(&xxh64(&out).to_le_bytes());
        let payload = out.len();
        let c16 = |out: &mut Vec<u8>, v: &[Complex64]| {
            for z in v {
                out.extend_from_slice(&z.re.to_le_bytes());
                out.extend_from_slice(&z.im.to_le_bytes());
            }
        };
        let batches = |out: &mut Vec<u8>, m: &CovarianceShard| {
            for b in &m.moments.batches {
                out.extend_from_slice(&b.paths.to_le_bytes());
                for s in &b.sums {
                    c16(out, s);
                }
            }
        };
        match &self.data {
            ShardData::Moments(m) => batches(&mut out, m),
            ShardData::Covariance(m, mean, _) => {
                batches(&mut out, m);
                c16(&mut out, &mean.values);
            }
            ShardData::Fields(f) => {
                c16(&mut out, f.rows.rows.as_slice());
                c16(&mut out, &f.mean.values);
            }
            ShardData::Wave(w) => {
                c16(&mut out, w.rows.rows.as_slice());
                for &n in &w.scatterer_counts {
                    out.extend_from_slice(&(n as u64).to_le_bytes());
                }
                out.extend_from_slice(&w.expected_scatterers.to_le_bytes());
            }
        }
        let sum = xxh64(&out[payload..]);
        out.extend_from_slice(&sum.to_le_bytes());
        out
    }

    fn payload_len(&self) -> u64 {
        match &self.data {
            ShardData::Moments(m) => payload_moments(&m.moments.spec, m.moments.units.len()),
            ShardData::Covariance(m, mean, _) => {
                payload_moments(&m.moments.spec, m.moments.units.len())
                    + mean.values.len() as u64 * 16
            }
            ShardData::Fields(f) => {
                ((f.rows.rows.as_slice().len() + f.mean.values.len()) * 16) as u64
            }
            ShardData::Wave(w) => {
                (w.rows.rows.as_slice().len() * 16 + w.scatterer_counts.len() * 8 + 8) as u64
            }
        }
    }
}

/// The scene of `p` as TOML and the absolute folder its input files are looked up in: what a
/// shard or tile file keeps to rebuild the problem.
pub(crate) fn scene_source(p: &Problem) -> Result<(String, PathBuf), RunError> {
    let scene_toml = toml::to_string(&p.file).map_err(|e| {
        bad(
            Path::new(&p.origin),
            format!("the scene cannot be written as TOML: {e}"),
        )
    })?;
    // A scene given by a bare file name has the empty folder: the current one.
    let base = if p.base.as_os_str().is_empty() {
        Path::new(".")
    } else {
        &p.base
    };
    let base = std::path::absolute(base).unwrap_or_else(|_| base.to_path_buf());
    Ok((scene_toml, base))
}

/// The header's description of batch sums.
fn moments_json(m: &CovarianceShard) -> Value {
    let s = &m.moments.spec;
    json!({"paths": s.paths, "j": s.j, "layout": layout_name(s.layout),
           "parts": s.parts, "with_total": s.with_total})
}

/// Payload bytes of `batches` batches of a moments run.
fn payload_moments(spec: &MomentsSpec, batches: usize) -> u64 {
    batches as u64 * (8 + spec.parts as u64 * spec.kept() as u64 * 16)
}
