//! Reading shard files as untrusted input: a shard may be damaged in transit, or crafted.
//!
//! - Only regular files are opened (a FIFO, a device or a directory is refused before it is
//!   opened, so nothing blocks), without blocking.
//! - The header length is at most [`MAX_HEADER_BYTES`] and fits in the file before it is
//!   allocated; the header's checksum is verified before any of its fields is used.
//! - Every size the header states (`data.j`, `paths`, `parts`, `layout`, `with_total`,
//!   `paths_per_realization`, `add_mean`, the units) is parsed strictly and, with checked
//!   arithmetic, must give exactly the payload's length; in a merge it must also be what the
//!   run's scene implies ([`Expected`]), both before the numbers are read.
//! - The payload's checksum is verified before the numbers are returned, and every number must
//!   be finite (the speckle means of a covariance may be NaN only where the shard records the
//!   warning that explains them, as a single run's are).
//!
//! Messages name the file and the header field; they never quote the file's contents beyond
//! the field names and integers they check.

use crate::checksum::{Hashing, Xxh64};
use crate::file::{MAGIC, VERSION, bad, layout_of};
use crate::{Header, Kind, RunError, ShardData, ShardFile, field_options};
use num_complex::Complex64;
use serde_json::Value;
use speckle_estimators::{CovarianceShard, FieldShard, detector_shard_spec, shard_spec};
use speckle_scene::Problem;
use speckle_stats::{
    BatchSums, CMatrix, Layout, MomentsSpec, PairShare, PartialMoments, PartialRows, Shard,
};
use speckle_wave::WaveShard;
use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Largest header a shard file may declare (bytes): four times the largest scene file, for the
/// scene's TOML text inside the JSON.
pub const MAX_HEADER_BYTES: u64 = 4 * speckle_scene::safe::MAX_SCENE_BYTES;

/// The sizes of a shard's numbers, as its header states them, as its numbers are, or as its
/// run's scene implies.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Shape {
    /// Batch sums (covariance, intensity).
    Moments(MomentsSpec),
    /// Field realizations.
    Fields {
        j: usize,
        paths_per_realization: u64,
        add_mean: bool,
    },
    /// Wave configurations.
    Wave { j: usize },
}

impl Shape {
    /// The first header field in which `other` differs from `self`, as `data.FIELD = other's,
    /// not self's`.
    fn difference(&self, other: &Shape) -> Option<String> {
        match (self, other) {
            (Shape::Moments(a), Shape::Moments(b)) => a.difference(b).map(|d| format!("data.{d}")),
            (
                Shape::Fields {
                    j,
                    paths_per_realization,
                    add_mean,
                },
                Shape::Fields {
                    j: j2,
                    paths_per_realization: p2,
                    add_mean: a2,
                },
            ) => [
                ("j", j2.to_string(), j.to_string()),
                (
                    "paths_per_realization",
                    p2.to_string(),
                    paths_per_realization.to_string(),
                ),
                ("add_mean", a2.to_string(), add_mean.to_string()),
            ]
            .into_iter()
            .find(|(_, a, b)| a != b)
            .map(|(f, a, b)| format!("data.{f} = {a}, not {b}")),
            (Shape::Wave { j }, Shape::Wave { j: j2 }) => {
                (j != j2).then(|| format!("data.j = {j2}, not {j}"))
            }
            _ => Some("numbers of another render".into()),
        }
    }

    /// The shape of numbers in memory.
    fn of(data: &ShardData) -> Shape {
        match data {
            ShardData::Moments(m) | ShardData::Covariance(m, ..) => Shape::Moments(m.moments.spec),
            ShardData::Fields(f) => Shape::Fields {
                j: f.rows.rows.cols(),
                paths_per_realization: f.paths_per_realization,
                add_mean: f.add_mean,
            },
            ShardData::Wave(w) => Shape::Wave {
                j: w.rows.rows.cols(),
            },
        }
    }
}

/// What every shard of a run must hold, from the run's scene.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Expected {
    shape: Shape,
    /// The run's units.
    total: usize,
    /// The wave solver's expected number of scatterers.
    scatterers: Option<f64>,
}

impl Expected {
    /// What a render of `kind` of `p` holds.
    pub(crate) fn of(p: &Problem, kind: Kind) -> Result<Self, RunError> {
        let j = p.pairs();
        let moments = |diagonal| {
            let opts = crate::covariance_options(p);
            let spec = if p.scene.has_detectors() {
                detector_shard_spec(&p.scene, &opts)
            } else {
                shard_spec(j, &opts, diagonal)
            };
            Self {
                shape: Shape::Moments(spec),
                total: spec.batches().count(),
                scatterers: None,
            }
        };
        Ok(match kind {
            Kind::Covariance => moments(false),
            Kind::Intensity => moments(true),
            Kind::Fields => {
                let o = field_options(p);
                Self {
                    shape: Shape::Fields {
                        j,
                        paths_per_realization: o.paths_per_realization,
                        add_mean: o.add_mean,
                    },
                    total: o.realizations,
                    scatterers: None,
                }
            }
            Kind::Wave => {
                let scene = p.box_scene().map_err(|e| p.in_document(e))?;
                Self {
                    shape: Shape::Wave { j },
                    total: p.render.configurations,
                    scatterers: Some(speckle_wave::expected_scatterers(&scene)?),
                }
            }
        })
    }

    /// Checks a shard's units and the shape its header states or its numbers have.
    fn check(&self, header: &Header, shape: &Shape, path: &Path) -> Result<(), RunError> {
        let off = |d: String| {
            bad(
                path,
                format!(
                    "shard {} is not of the run its scene describes: it has {d}",
                    header.shard
                ),
            )
        };
        if header.total != self.total {
            return Err(off(format!(
                "total_units = {}, not {}",
                header.total, self.total
            )));
        }
        self.shape.difference(shape).map_or(Ok(()), |d| Err(off(d)))
    }

    /// Checks a shard in memory (of [`crate::merge`]) as [`ShardFile::read_checked`] checks a
    /// file.
    pub(crate) fn check_data(&self, s: &ShardFile, path: &Path) -> Result<(), RunError> {
        self.check(&s.header, &Shape::of(&s.data), path)?;
        self.check_scatterers(&s.data, path)
    }

    fn check_scatterers(&self, data: &ShardData, path: &Path) -> Result<(), RunError> {
        if let (Some(e), ShardData::Wave(w)) = (self.scatterers, data)
            && e.to_bits() != w.expected_scatterers.to_bits()
        {
            return Err(bad(
                path,
                "its expected number of scatterers is not that of its scene",
            ));
        }
        Ok(())
    }
}

/// The parts of the header that size the payload.
pub(crate) struct Desc {
    /// The file's length less the header and the checksums: the payload's.
    payload: u64,
    json: Value,
}

impl ShardFile {
    /// Reads a shard from its bytes (`path` names them in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, RunError> {
        let mut r = bytes;
        let (header, desc) = read_head(&mut r, bytes.len() as u64, path)?;
        decode(header, &desc, None, &mut r, path, &mut Vec::new())
    }

    /// Reads a shard file.
    pub fn read(path: &Path) -> Result<Self, RunError> {
        Self::read_reusing(path, &mut Vec::new())
    }

    /// [`ShardFile::read`] into vectors taken from `pool` where it has some (a merge hands
    /// each shard's batch sums back for the next: fresh pages for every shard cost as much as
    /// reading them).
    pub fn read_reusing(path: &Path, pool: &mut Vec<Vec<Complex64>>) -> Result<Self, RunError> {
        let (mut r, len) = open(path)?;
        let (header, desc) = read_head(&mut r, len, path)?;
        decode(header, &desc, None, &mut r, path, pool)
    }

    /// [`ShardFile::read_reusing`] of a shard of the run `expected` describes, checked against
    /// it before its numbers are read.
    pub(crate) fn read_checked(
        path: &Path,
        expected: &Expected,
        pool: &mut Vec<Vec<Complex64>>,
    ) -> Result<Self, RunError> {
        let (mut r, len) = open(path)?;
        let (header, desc) = read_head(&mut r, len, path)?;
        decode(header, &desc, Some(expected), &mut r, path, pool)
    }

    /// Reads the header of a shard file only (its checksum verified).
    pub fn read_header(path: &Path) -> Result<Header, RunError> {
        let (mut r, len) = open(path)?;
        Ok(read_head(&mut r, len, path)?.0)
    }
}

/// Opens the regular file `path` (never a FIFO or a device) and returns a reader and its length.
fn open(path: &Path) -> Result<(std::io::BufReader<std::fs::File>, u64), RunError> {
    let (file, len) = speckle_scene::safe::open_regular(path, u64::MAX)
        .map_err(|why| bad(path, format!("cannot read it: {why}")))?;
    Ok((std::io::BufReader::with_capacity(1 << 20, file), len))
}

fn read_u64(r: &mut impl Read) -> std::io::Result<u64> {
    let mut b = [0u8; 8];
    r.read_exact(&mut b)?;
    Ok(u64::from_le_bytes(b))
}

/// Reads the header of a file of `len` bytes and verifies its checksum.
fn read_head(r: &mut impl Read, len: u64, path: &Path) -> Result<(Header, Desc), RunError> {
    let mut r = Hashing {
        inner: r,
        hash: Xxh64::new(),
    };
    let mut head = [0u8; 24];
    r.read_exact(&mut head)
        .map_err(|_| bad(path, "not a speckle shard file (too short)"))?;
    if &head[..8] != MAGIC {
        return Err(bad(path, "not a speckle shard file"));
    }
    let version = u32::from_le_bytes([head[8], head[9], head[10], head[11]]);
    if version != VERSION {
        return Err(bad(
            path,
            format!(
                "shard format version {version}; this speckle reads version {VERSION} (render \
                 the shards again with this speckle)"
            ),
        ));
    }
    let mut b = [0u8; 8];
    b.copy_from_slice(&head[16..24]);
    let n = u64::from_le_bytes(b);
    // The header and both checksums must fit in the file before the header is allocated.
    let payload = len
        .checked_sub(40)
        .and_then(|rest| rest.checked_sub(n))
        .filter(|_| n <= MAX_HEADER_BYTES)
        .ok_or_else(|| {
            bad(
                path,
                format!(
                    "truncated or damaged: its header length {n} does not fit in its {len} bytes \
                     (or exceeds {MAX_HEADER_BYTES})"
                ),
            )
        })?;
    let mut text = vec![0u8; n as usize];
    r.read_exact(&mut text)
        .map_err(|_| bad(path, "truncated header"))?;
    let sum = r.hash.digest();
    let stored = read_u64(&mut r.inner).map_err(|_| bad(path, "truncated header"))?;
    if stored != sum {
        return Err(bad(
            path,
            "the header is damaged (its checksum does not match); copy or render the shard again",
        ));
    }
    let json: Value =
        serde_json::from_slice(&text).map_err(|e| bad(path, format!("corrupt header: {e}")))?;
    Ok((parse_header(&json, path)?, Desc { payload, json }))
}

fn parse_header(json: &Value, path: &Path) -> Result<Header, RunError> {
    let field = |k: &str| {
        json.get(k)
            .ok_or_else(|| bad(path, format!("header lacks `{k}`")))
    };
    let uint = |k: &str| {
        field(k)?
            .as_u64()
            .ok_or_else(|| bad(path, format!("header `{k}` is not an integer")))
    };
    let size = |k: &str| {
        usize::try_from(uint(k)?).map_err(|_| bad(path, format!("header `{k}` is too large")))
    };
    let text_of = |k: &str| -> Result<String, RunError> {
        Ok(field(k)?
            .as_str()
            .ok_or_else(|| bad(path, format!("header `{k}` is not a string")))?
            .to_string())
    };
    let pair = |k: &str| -> Result<(usize, usize), RunError> {
        pair_of(field(k)?)
            .ok_or_else(|| bad(path, format!("header `{k}` is not a pair of integers")))
    };
    let kind_tag = text_of("kind")?;
    let kind = Kind::from_tag(&kind_tag).ok_or_else(|| {
        bad(
            path,
            format!(
                "header `kind` is not a render ({})",
                speckle_scene::safe::excerpt(&kind_tag)
            ),
        )
    })?;
    let (i, n) = pair("shard")?;
    let shard = Shard::new(i, n).map_err(|e| bad(path, e.to_string()))?;
    let (a, b) = pair("units")?;
    let total = size("total_units")?;
    if a > b || b > total || shard.units(total) != (a..b) {
        return Err(bad(
            path,
            format!("shard {shard} cannot hold units {a}..{b} of {total}"),
        ));
    }
    let wall_time_s = field("wall_time_s")?
        .as_f64()
        .filter(|t| t.is_finite() && *t >= 0.0)
        .ok_or_else(|| bad(path, "header `wall_time_s` is not a duration"))?;
    Ok(Header {
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
        wall_time_s,
        threads: size("threads")?,
    })
}

/// A JSON pair of integers that fit in `usize`.
fn pair_of(v: &Value) -> Option<(usize, usize)> {
    let n = |i: usize| v.get(i)?.as_u64().and_then(|x| usize::try_from(x).ok());
    match v.as_array()?.len() {
        2 => Some((n(0)?, n(1)?)),
        _ => None,
    }
}

/// The shape the header's `data` states, its fields parsed strictly (no defaults).
fn shape_of(kind: Kind, d: &Value, path: &Path) -> Result<Shape, RunError> {
    let uint = |k: &str| {
        d.get(k).and_then(Value::as_u64).ok_or_else(|| {
            bad(
                path,
                format!("header `data.{k}` is missing or not an integer"),
            )
        })
    };
    let size = |k: &str| {
        usize::try_from(uint(k)?).map_err(|_| bad(path, format!("header `data.{k}` is too large")))
    };
    let flag = |k: &str| {
        d.get(k).and_then(Value::as_bool).ok_or_else(|| {
            bad(
                path,
                format!("header `data.{k}` is missing or not true or false"),
            )
        })
    };
    Ok(match kind {
        Kind::Covariance | Kind::Intensity => Shape::Moments(MomentsSpec {
            paths: uint("paths")?,
            j: size("j")?,
            layout: d
                .get("layout")
                .and_then(Value::as_str)
                .and_then(layout_of)
                .ok_or_else(|| bad(path, "header `data.layout` is missing or unknown"))?,
            parts: size("parts")?,
            with_total: flag("with_total")?,
        }),
        Kind::Fields => Shape::Fields {
            j: size("j")?,
            paths_per_realization: uint("paths_per_realization")?,
            add_mean: flag("add_mean")?,
        },
        Kind::Wave => Shape::Wave { j: size("j")? },
    })
}

/// Entries a batch keeps per part (`MomentsSpec::kept`), without overflow.
fn kept(spec: &MomentsSpec) -> Option<u128> {
    let j = spec.j as u128;
    match spec.layout {
        Layout::Hermitian => j.checked_mul(j + 1).map(|n| n / 2),
        Layout::General => j.checked_mul(j),
        Layout::HermitianDiagonal | Layout::GeneralDiagonal => Some(j),
    }
}

/// The payload's length for `rows` units of `shape` and `share` means, or `None` if it
/// overflows (then no file holds it).
fn payload_len(shape: &Shape, rows: usize, share: usize) -> Option<u128> {
    let (rows, share) = (rows as u128, share as u128);
    let c16 = |n: u128| n.checked_mul(16);
    let body = match shape {
        Shape::Moments(spec) => {
            let batch = c16(kept(spec)?.checked_mul(spec.parts as u128)?)?.checked_add(8)?;
            rows.checked_mul(batch)?
        }
        Shape::Fields { j, .. } => c16(rows.checked_mul(*j as u128)?)?,
        Shape::Wave { j } => c16(rows.checked_mul(*j as u128)?)?
            .checked_add(rows * 8)?
            .checked_add(8)?,
    };
    body.checked_add(share * 16)
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
            let f = |b: &[u8]| {
                let mut w = [0u8; 8];
                w.copy_from_slice(b);
                f64::from_le_bytes(w)
            };
            Complex64::new(f(&c[..8]), f(&c[8..]))
        }));
        left -= take;
    }
    Ok(out)
}

fn finite(v: &[Complex64]) -> bool {
    v.iter().all(|z| z.re.is_finite() && z.im.is_finite())
}

/// Decodes the payload of a shard whose header was read, checked against `expected` (the run's
/// scene) when given, and verifies its checksum.
fn decode(
    header: Header,
    desc: &Desc,
    expected: Option<&Expected>,
    r: &mut impl Read,
    path: &Path,
    pool: &mut Vec<Vec<Complex64>>,
) -> Result<ShardFile, RunError> {
    let d = desc.json.get("data").unwrap_or(&Value::Null);
    let shape = shape_of(header.kind, d, path)?;
    if let Some(e) = expected {
        e.check(&header, &shape, path)?;
    }
    let j = match &shape {
        Shape::Moments(spec) => spec.j,
        Shape::Fields { j, .. } | Shape::Wave { j } => *j,
    };
    let rows = header.units.len();
    // The share of the pairs whose means the shard holds (covariance, fields with the mean).
    let share = match d.get("mean_pairs") {
        None | Some(Value::Null) => None,
        Some(v) => match pair_of(v) {
            Some((a, b)) if header.shard.units(j) == (a..b) => Some(a..b),
            _ => {
                return Err(bad(
                    path,
                    "header `data.mean_pairs` is not the shard's pairs",
                ));
            }
        },
    };
    let wants_means = match shape {
        Shape::Fields { add_mean, .. } => add_mean,
        _ => header.kind == Kind::Covariance,
    };
    if wants_means != share.is_some() {
        return Err(bad(
            path,
            "header `data.mean_pairs` is missing or out of place",
        ));
    }
    let share_len = share.as_ref().map_or(0, Range::len);
    if let Shape::Moments(spec) = &shape
        && spec.batches().count() != header.total
    {
        return Err(bad(path, "the batch count does not match the path count"));
    }
    let need = payload_len(&shape, rows, share_len);
    if need != Some(u128::from(desc.payload)) {
        let need = need.map_or("more than any file holds".into(), |n| n.to_string());
        return Err(bad(
            path,
            format!(
                "truncated or damaged: {} bytes of numbers where shard {} needs {need}",
                desc.payload, header.shard
            ),
        ));
    }
    let warning = match d.get("mean_warning") {
        None | Some(Value::Null) => None,
        Some(Value::String(w)) => Some(w.clone()),
        Some(_) => return Err(bad(path, "header `data.mean_warning` is not a string")),
    };
    // Every size is now bounded by the file's length.
    let mut h = Hashing {
        inner: &mut *r,
        hash: Xxh64::new(),
    };
    let data = read_numbers(&header, shape, share, warning, &mut h, path, pool)?;
    let sum = h.hash.digest();
    let stored = read_u64(r).map_err(|e| bad(path, format!("reading: {e}")))?;
    if stored != sum {
        return Err(bad(
            path,
            "its numbers are damaged (their checksum does not match); copy or render the shard \
             again",
        ));
    }
    if let Some(e) = expected {
        e.check_scatterers(&data, path)?;
    }
    Ok(ShardFile { header, data })
}

/// Reads the payload of `shape`, every number finite.
fn read_numbers(
    header: &Header,
    shape: Shape,
    share: Option<Range<usize>>,
    warning: Option<String>,
    r: &mut impl Read,
    path: &Path,
    pool: &mut Vec<Vec<Complex64>>,
) -> Result<ShardData, RunError> {
    let io = |e: std::io::Error| bad(path, format!("reading: {e}"));
    let not_finite = |what: &str| {
        bad(
            path,
            format!(
                "shard {} holds a NaN or infinite value in {what}; a render never writes one \
                 (the file is damaged or not speckle's)",
                header.shard
            ),
        )
    };
    let rows = header.units.len();
    let mut buf = Vec::new();
    Ok(match shape {
        Shape::Moments(spec) => {
            let mut batches = Vec::with_capacity(rows);
            for k in header.units.clone() {
                let paths = read_u64(r).map_err(io)?;
                let sums = (0..spec.parts)
                    .map(|_| read_c16(r, spec.kept(), &mut buf, pool))
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(io)?;
                if !sums.iter().all(|s| finite(s)) {
                    return Err(not_finite(&format!("the sums of batch {k}")));
                }
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
                    // A single run's means are NaN where their quadrature fails, with a
                    // warning that says so; never infinite.
                    let explained = |z: &Complex64| {
                        (z.re.is_finite() || (z.re.is_nan() && warning.is_some()))
                            && (z.im.is_finite() || (z.im.is_nan() && warning.is_some()))
                    };
                    if !values.iter().all(explained) {
                        return Err(not_finite("the speckle means"));
                    }
                    ShardData::Covariance(m, PairShare { pairs, values }, warning)
                }
                None => ShardData::Moments(m),
            }
        }
        Shape::Fields {
            j,
            paths_per_realization,
            add_mean,
        } => {
            let rows_of = read_rows(header, j, r, &mut buf).map_err(io)?;
            if !finite(rows_of.rows.as_slice()) {
                return Err(not_finite("the fields"));
            }
            let pairs = share.unwrap_or(0..0);
            let values = read_c16(r, pairs.len(), &mut buf, &mut Vec::new()).map_err(io)?;
            if !finite(&values) {
                return Err(not_finite("the speckle means"));
            }
            ShardData::Fields(FieldShard {
                rows: rows_of,
                add_mean,
                mean: PairShare { pairs, values },
                paths_per_realization,
            })
        }
        Shape::Wave { j } => {
            let rows_of = read_rows(header, j, r, &mut buf).map_err(io)?;
            if !finite(rows_of.rows.as_slice()) {
                return Err(not_finite("the fields"));
            }
            let counts = (0..rows)
                .map(|_| read_u64(r).map(|n| usize::try_from(n).unwrap_or(usize::MAX)))
                .collect::<Result<Vec<_>, _>>()
                .map_err(io)?;
            let expected = f64::from_bits(read_u64(r).map_err(io)?);
            if !(expected.is_finite() && expected >= 0.0) {
                return Err(not_finite("the expected number of scatterers"));
            }
            ShardData::Wave(WaveShard {
                rows: rows_of,
                scatterer_counts: counts,
                expected_scatterers: expected,
            })
        }
    })
}

/// The shard's rows of `j` complex numbers.
fn read_rows(
    header: &Header,
    j: usize,
    r: &mut impl Read,
    buf: &mut Vec<u8>,
) -> std::io::Result<PartialRows> {
    let rows = header.units.len();
    let values = read_c16(r, rows * j, buf, &mut Vec::new())?;
    Ok(PartialRows {
        shard: header.shard,
        units: header.units.clone(),
        total: header.total,
        rows: CMatrix::from_vec(rows, j, values),
    })
}
