//! Shard files: a self-describing header (JSON) and the shard's numbers (little-endian binary).
//!
//! ```text
//! bytes 0..8    b"SPKSHARD"
//! bytes 8..12   format version, u32 little-endian (1)
//! bytes 12..16  0 (reserved)
//! bytes 16..24  header length H, u64 little-endian
//! H bytes       the header, JSON (UTF-8): kind, shard, units, run hash, seed, the scene (TOML
//!               text, numbers exact), where its input files are, wall time, and the sizes below
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
//! ```
//!
//! Numbers are stored bit for bit, never through decimal text, so that a merge is exact. A file
//! whose length is not the one its header implies is refused as truncated.

use crate::{Kind, RunError, run_hash};
use num_complex::Complex64;
use serde_json::{Value, json};
use speckle_estimators::{CovarianceShard, FieldShard};
use speckle_scene::Problem;
use speckle_stats::{
    BatchSums, CMatrix, Layout, MomentsSpec, PairShare, PartialMoments, PartialRows, Shard,
};
use speckle_wave::WaveShard;
use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"SPKSHARD";
const VERSION: u32 = 2;

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

fn bad(path: &Path, reason: impl Into<String>) -> RunError {
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

fn layout_of(name: &str) -> Option<Layout> {
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
        let scene_toml = toml::to_string(&p.file).map_err(|e| {
            bad(
                Path::new(&p.origin),
                format!("the scene cannot be written as TOML: {e}"),
            )
        })?;
        let base = std::path::absolute(&p.base).unwrap_or_else(|_| p.base.clone());
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
        let mut out = Vec::with_capacity(24 + header.len() + self.payload_len() as usize);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&(header.len() as u64).to_le_bytes());
        out.extend_from_slice(&header);
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

    /// Reads a shard from its bytes (`path` names them in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, RunError> {
        let mut r = bytes;
        let (header, desc) = read_header(&mut r, path)?;
        let available = r.len() as u64;
        decode_payload(header, &desc, &mut r, available, path, &mut Vec::new())
    }

    /// Reads a shard file.
    pub fn read(path: &Path) -> Result<Self, RunError> {
        Self::read_reusing(path, &mut Vec::new())
    }

    /// [`ShardFile::read`] into vectors taken from `pool` where it has some (a merge hands
    /// each shard's batch sums back for the next: fresh pages for every shard cost as much as
    /// reading them).
    pub fn read_reusing(path: &Path, pool: &mut Vec<Vec<Complex64>>) -> Result<Self, RunError> {
        let file = std::fs::File::open(path).map_err(|e| bad(path, e.to_string()))?;
        let len = file.metadata().map_err(|e| bad(path, e.to_string()))?.len();
        let mut r = std::io::BufReader::with_capacity(1 << 20, file);
        let (header, desc) = read_header(&mut r, path)?;
        let rest = len.saturating_sub(24 + desc.header_len);
        decode_payload(header, &desc, &mut r, rest, path, pool)
    }

    /// Reads the header of a shard file only.
    pub fn read_header(path: &Path) -> Result<Header, RunError> {
        let file = std::fs::File::open(path).map_err(|e| bad(path, e.to_string()))?;
        Ok(read_header(&mut std::io::BufReader::new(file), path)?.0)
    }
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

/// The parts of the header that size the payload.
struct Desc {
    header_len: u64,
    json: Value,
}

fn read_header(r: &mut impl Read, path: &Path) -> Result<(Header, Desc), RunError> {
    let mut head = [0u8; 24];
    r.read_exact(&mut head)
        .map_err(|_| bad(path, "not a speckle shard file (too short)"))?;
    if &head[..8] != MAGIC {
        return Err(bad(path, "not a speckle shard file"));
    }
    let version = u32::from_le_bytes(head[8..12].try_into().unwrap_or_default());
    if version != VERSION {
        return Err(bad(
            path,
            format!("shard format version {version}; this speckle reads version {VERSION}"),
        ));
    }
    let len = u64::from_le_bytes(head[16..24].try_into().unwrap_or_default());
    if len > 1 << 32 {
        return Err(bad(path, "corrupt header length"));
    }
    let mut text = vec![0u8; len as usize];
    r.read_exact(&mut text)
        .map_err(|_| bad(path, "truncated header"))?;
    let json: Value =
        serde_json::from_slice(&text).map_err(|e| bad(path, format!("corrupt header: {e}")))?;
    let field = |k: &str| {
        json.get(k)
            .ok_or_else(|| bad(path, format!("header lacks `{k}`")))
    };
    let uint = |k: &str| {
        field(k)?
            .as_u64()
            .ok_or_else(|| bad(path, format!("header `{k}` is not an integer")))
    };
    let text_of = |k: &str| -> Result<String, RunError> {
        Ok(field(k)?
            .as_str()
            .ok_or_else(|| bad(path, format!("header `{k}` is not a string")))?
            .to_string())
    };
    let pair = |k: &str| -> Result<(usize, usize), RunError> {
        let v = field(k)?;
        let n = |i: usize| v.get(i).and_then(Value::as_u64).map(|x| x as usize);
        match (n(0), n(1)) {
            (Some(a), Some(b)) => Ok((a, b)),
            _ => Err(bad(path, format!("header `{k}` is not a pair of integers"))),
        }
    };
    let kind_tag = text_of("kind")?;
    let kind = Kind::from_tag(&kind_tag)
        .ok_or_else(|| bad(path, format!("unknown render `{kind_tag}`")))?;
    let (i, n) = pair("shard")?;
    let shard = Shard::new(i, n).map_err(|e| bad(path, e.to_string()))?;
    let (a, b) = pair("units")?;
    let total = uint("total_units")? as usize;
    if a > b || b > total || shard.units(total) != (a..b) {
        return Err(bad(
            path,
            format!("shard {shard} cannot hold units {a}..{b} of {total}"),
        ));
    }
    let header = Header {
        kind,
        shard,
        units: a..b,
        total,
        run_hash: text_of("run_hash")?,
        seed: uint("seed")?,
        name: text_of("name")?,
        origin: text_of("origin")?,
        base: PathBuf::from(text_of("base")?),
        scene_toml: text_of("scene_toml")?,
        version: text_of("speckle_version")?,
        wall_time_s: field("wall_time_s")?.as_f64().unwrap_or(0.0),
        threads: uint("threads")? as usize,
    };
    let data = field("data")?.clone();
    Ok((
        header,
        Desc {
            header_len: len,
            json: data,
        },
    ))
}

/// Reads `n` complex numbers.
fn read_c16(
    r: &mut impl Read,
    n: usize,
    buf: &mut Vec<u8>,
    pool: &mut Vec<Vec<Complex64>>,
) -> std::io::Result<Vec<Complex64>> {
    let mut out = pool.pop().unwrap_or_default();
    out.clear();
    out.reserve(n);
    const CHUNK: usize = 1 << 16;
    let mut left = n;
    while left > 0 {
        let take = left.min(CHUNK);
        buf.resize(take * 16, 0);
        r.read_exact(buf)?;
        out.extend(buf.chunks_exact(16).map(|c| {
            let f = |b: &[u8]| f64::from_le_bytes(b.try_into().unwrap_or_default());
            Complex64::new(f(&c[..8]), f(&c[8..]))
        }));
        left -= take;
    }
    Ok(out)
}

fn read_u64(r: &mut impl Read) -> std::io::Result<u64> {
    let mut b = [0u8; 8];
    r.read_exact(&mut b)?;
    Ok(u64::from_le_bytes(b))
}

fn decode_payload(
    header: Header,
    desc: &Desc,
    r: &mut impl Read,
    available: u64,
    path: &Path,
    pool: &mut Vec<Vec<Complex64>>,
) -> Result<ShardFile, RunError> {
    let d = &desc.json;
    let uint = |k: &str| {
        d.get(k).and_then(Value::as_u64).ok_or_else(|| {
            bad(
                path,
                format!("header `data.{k}` is missing or not an integer"),
            )
        })
    };
    let j = uint("j")? as usize;
    let rows = header.units.len();
    // The share of the pairs whose means the shard holds (covariance, fields with the mean).
    let share = match d.get("mean_pairs") {
        None | Some(Value::Null) => None,
        Some(v) => {
            let n = |i: usize| v.get(i).and_then(Value::as_u64).map(|x| x as usize);
            match (n(0), n(1)) {
                (Some(a), Some(b)) if a <= b && b <= j && header.shard.units(j) == (a..b) => {
                    Some(a..b)
                }
                _ => {
                    return Err(bad(
                        path,
                        "header `data.mean_pairs` is not the shard's pairs",
                    ));
                }
            }
        }
    };
    let add_mean = d.get("add_mean").and_then(Value::as_bool).unwrap_or(false);
    if (header.kind == Kind::Covariance || (header.kind == Kind::Fields && add_mean))
        != share.is_some()
    {
        return Err(bad(
            path,
            "header `data.mean_pairs` is missing or out of place",
        ));
    }
    let share_len = share.as_ref().map_or(0, |s| s.len());
    let expected = match header.kind {
        Kind::Covariance | Kind::Intensity => {
            let layout = d
                .get("layout")
                .and_then(Value::as_str)
                .and_then(layout_of)
                .ok_or_else(|| bad(path, "header `data.layout` is missing or unknown"))?;
            let spec = MomentsSpec {
                paths: uint("paths")?,
                j,
                layout,
                parts: uint("parts")? as usize,
                with_total: d
                    .get("with_total")
                    .and_then(Value::as_bool)
                    .unwrap_or(false),
            };
            if spec.batches().count() != header.total {
                return Err(bad(path, "the batch count does not match the path count"));
            }
            Err(spec)
        }
        Kind::Fields => Ok(((rows * j + share_len) * 16) as u64),
        Kind::Wave => Ok((rows * j * 16 + rows * 8 + 8) as u64),
    };
    let need = match &expected {
        Err(spec) => payload_moments(spec, rows) + share_len as u64 * 16,
        Ok(n) => *n,
    };
    if available != need {
        return Err(bad(
            path,
            format!(
                "truncated or damaged: {available} bytes of numbers where shard {} needs {need}",
                header.shard
            ),
        ));
    }
    let io = |e: std::io::Error| bad(path, format!("reading: {e}"));
    let mut buf = Vec::new();
    let data = match expected {
        Err(spec) => {
            let mut batches = Vec::with_capacity(rows);
            for _ in 0..rows {
                let paths = read_u64(r).map_err(io)?;
                let sums = (0..spec.parts)
                    .map(|_| read_c16(r, spec.kept(), &mut buf, pool))
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(io)?;
                batches.push(BatchSums { paths, sums });
            }
            let moments = PartialMoments {
                spec,
                shard: header.shard,
                units: header.units.clone(),
                batches,
            };
            moments.check().map_err(|e| bad(path, e.to_string()))?;
            let m = CovarianceShard { moments };
            match share {
                Some(pairs) => {
                    let values = read_c16(r, pairs.len(), &mut buf, &mut Vec::new()).map_err(io)?;
                    let warning = d
                        .get("mean_warning")
                        .and_then(Value::as_str)
                        .map(str::to_string);
                    ShardData::Covariance(m, PairShare { pairs, values }, warning)
                }
                None => ShardData::Moments(m),
            }
        }
        Ok(_) => {
            let values = read_c16(r, rows * j, &mut buf, &mut Vec::new()).map_err(io)?;
            let rows_of = PartialRows {
                shard: header.shard,
                units: header.units.clone(),
                total: header.total,
                rows: CMatrix::from_vec(rows, j, values),
            };
            if header.kind == Kind::Fields {
                let pairs = share.unwrap_or(0..0);
                let values = read_c16(r, pairs.len(), &mut buf, &mut Vec::new()).map_err(io)?;
                ShardData::Fields(FieldShard {
                    rows: rows_of,
                    add_mean,
                    mean: PairShare { pairs, values },
                    paths_per_realization: uint("paths_per_realization")?,
                })
            } else {
                let counts = (0..rows)
                    .map(|_| read_u64(r).map(|n| n as usize))
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(io)?;
                let expected = f64::from_bits(read_u64(r).map_err(io)?);
                ShardData::Wave(WaveShard {
                    rows: rows_of,
                    scatterer_counts: counts,
                    expected_scatterers: expected,
                })
            }
        }
    };
    Ok(ShardFile { header, data })
}
