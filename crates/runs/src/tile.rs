//! Tiles of a covariance band (`speckle covariance --band R --tile I/N`) and their streaming
//! merge (`speckle merge`).
//!
//! A tile renders every path of the run but keeps only the band entries of the pixels in its
//! rows: the `I`-th (from 0, as `--shard`) of `N` contiguous blocks of image rows, as equal as
//! possible (`Shard::units` of the `ny` rows). Its entries are bitwise the whole band's
//! (`speckle_estimators::ImageBand::new_tile`). A tile file:
//!
//! ```text
//! bytes 0..8    b"SPKTILE\0"
//! bytes 8..12   format version, u32 little-endian (1)
//! bytes 12..16  0 (reserved)
//! bytes 16..24  header length H, u64 little-endian (at most MAX_HEADER_BYTES)
//! H bytes       the header, JSON (UTF-8): tile, rows, radius, single_beyond (`--single-beyond`
//!               or null; absent: null), shape, run hash, seed, paths, the scene (TOML), where
//!               its input files are, wall time
//! 8 bytes       the header's checksum: XXH64 (seed 0) of bytes 0..24 + H, u64 little-endian
//! payload       the tile's values, then its standard errors: complex128 (re, im as f64
//!               little-endian), shape (S, rows, nx, S, 2R + 1, 2R + 1) each
//! 8 bytes       the payload's checksum: XXH64 (seed 0) of the payload, u64 little-endian
//! ```
//!
//! The merge ([`merge_tiles`]) never holds the band: it checks every tile's header against the
//! others and the rebuilt scene, then reads the tiles pixel by pixel (their checksums, the
//! intensities, then the correlation summaries), and writes each array as the `.npy` header of
//! the whole shape followed by the tiles' blocks in array order ([`BandTiles::write`]; with
//! `S > 1` the tiles interleave per `s1`). Plain sequential writes rather than a memory-mapped
//! output: the output protocol (`speckle-output`) stages every file and renames it into place,
//! so a stream into its staged file keeps a failed or interrupted merge from leaving a partial
//! final file, and needs no `unsafe` mapping.

use crate::checksum::{Xxh64, xxh64};
use crate::file::{bad, scene_source};
use crate::{Kind, RunError, run_hash};
use num_complex::Complex64;
use serde_json::{Value, json};
use speckle_estimators::{BandCorrelation, BandEstimate, ImageBand};
use speckle_scene::{Overrides, Problem, load_str_unquoted};
use speckle_stats::{Shard, ShardError};
use std::io::{Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The first bytes of a tile file.
pub const TILE_MAGIC: &[u8; 8] = b"SPKTILE\0";
const TILE_VERSION: u32 = 1;

/// What a tile file says about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct TileHeader {
    /// Which tile (`index` from 0 of `count`).
    pub tile: Shard,
    /// Its image rows.
    pub rows: Range<usize>,
    /// The band's half-width in pixels.
    pub radius: usize,
    /// The offset beyond which entries hold single scattering only (`--single-beyond`), if
    /// any (absent from tiles of earlier speckles: none).
    pub single_beyond: Option<usize>,
    /// The shape of each of its arrays, `(S, rows, nx, S, 2R + 1, 2R + 1)`.
    pub shape: [usize; 6],
    /// The run hash of the covariance render ([`run_hash`]).
    pub run_hash: String,
    /// The seed.
    pub seed: u64,
    /// Sub-paths of the render (every tile renders them all).
    pub paths: u64,
    /// The scene's name (output prefix).
    pub name: String,
    /// Where the scene came from.
    pub origin: String,
    /// The directory its relative input files are looked up in (absolute).
    pub base: PathBuf,
    /// The scene as parsed and validated, as TOML.
    pub scene_toml: String,
    /// The crate version that rendered it.
    pub version: String,
    /// Wall time of the tile's render, in seconds.
    pub wall_time_s: f64,
}

impl TileHeader {
    /// Elements of each of the tile's two arrays.
    fn elements(&self) -> u64 {
        self.shape.iter().map(|&n| n as u64).product()
    }
}

/// The rows of tile `tile` of an image of `ny` rows; an error naming `--tile` when there are
/// more tiles than rows.
pub fn tile_rows(ny: usize, tile: Shard) -> Result<Range<usize>, RunError> {
    if tile.count > ny {
        return Err(ShardError::Invalid(format!(
            "--tile {tile}: {} tiles of an image of {ny} rows (at most {ny}: a tile is whole rows)",
            tile.count
        ))
        .into());
    }
    Ok(tile.units(ny))
}

/// The file name of tile `tile` of `name`: `<name>.cov_band.<i>-of-<n>.tile`.
pub fn tile_file_name(name: &str, tile: Shard) -> String {
    format!("{name}.cov_band.{}-of-{}.tile", tile.index, tile.count)
}

/// The bytes of the tile file of `est`, tile `tile` of `p`'s band render, rendered in `wall`
/// seconds.
pub fn tile_bytes(
    p: &Problem,
    tile: Shard,
    est: &BandEstimate,
    wall: f64,
) -> Result<Vec<u8>, RunError> {
    let (scene_toml, base) = scene_source(p)?;
    let rows = est.band.rows();
    let header = json!({
        "format": "speckle band tile",
        "tile": [tile.index, tile.count],
        "rows": [rows.start, rows.end],
        "radius": est.band.radius(),
        "single_beyond": est.band.single_beyond(),
        "shape": est.band.shape(),
        "run_hash": run_hash(p, Kind::Covariance),
        "seed": p.render.seed,
        "paths": est.paths,
        "name": p.name,
        "origin": p.origin,
        "base": base.to_string_lossy(),
        "scene_toml": scene_toml,
        "speckle_version": env!("CARGO_PKG_VERSION"),
        "wall_time_s": wall,
    });
    let header = serde_json::to_vec(&header).unwrap_or_default();
    let mut out = Vec::with_capacity(40 + header.len() + 32 * est.value.len());
    out.extend_from_slice(TILE_MAGIC);
    out.extend_from_slice(&TILE_VERSION.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(header.len() as u64).to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(&xxh64(&out).to_le_bytes());
    let payload = out.len();
    for z in est.value.iter().chain(&est.std_error) {
        out.extend_from_slice(&z.re.to_le_bytes());
        out.extend_from_slice(&z.im.to_le_bytes());
    }
    let sum = xxh64(&out[payload..]);
    out.extend_from_slice(&sum.to_le_bytes());
    Ok(out)
}

/// Whether the file `path` is a regular file that starts as a tile file (for `speckle merge`,
/// which takes shards and tiles). Never opens anything but a regular file (a FIFO would
/// block): what is not one is left to the shard reader's refusal.
pub fn is_tile_file(path: &Path) -> bool {
    let mut head = [0u8; 8];
    speckle_scene::safe::open_regular(path, u64::MAX)
        .is_ok_and(|(mut f, _)| f.read_exact(&mut head).is_ok() && &head == TILE_MAGIC)
}

/// Reads and checks the header of the tile file `path`; returns it and the payload's offset.
/// The file's length must be exactly what the header describes.
pub fn read_tile_header(path: &Path) -> Result<(TileHeader, u64), RunError> {
    let (mut file, len) = speckle_scene::safe::open_regular(path, u64::MAX)
        .map_err(|why| bad(path, format!("cannot read it: {why}")))?;
    let mut head = [0u8; 24];
    file.read_exact(&mut head)
        .map_err(|_| bad(path, "not a speckle tile file (too short)"))?;
    if &head[..8] != TILE_MAGIC {
        return Err(bad(path, "not a speckle tile file"));
    }
    let version = u32::from_le_bytes([head[8], head[9], head[10], head[11]]);
    if version != TILE_VERSION {
        return Err(bad(
            path,
            format!(
                "tile format version {version}; this speckle reads version {TILE_VERSION} \
                 (render the tiles again with this speckle)"
            ),
        ));
    }
    let h = u64::from_le_bytes(head[16..24].try_into().expect("8 bytes"));
    if h > crate::MAX_HEADER_BYTES || h + 32 > len {
        return Err(bad(
            path,
            format!("a header length of {h} bytes is not valid"),
        ));
    }
    let mut text = vec![0u8; h as usize];
    let mut sum = [0u8; 8];
    file.read_exact(&mut text)
        .and_then(|()| file.read_exact(&mut sum))
        .map_err(|e| bad(path, format!("cannot read its header: {e}")))?;
    let mut hash = Xxh64::new();
    hash.update(&head);
    hash.update(&text);
    if hash.digest() != u64::from_le_bytes(sum) {
        return Err(bad(path, "its header is damaged (checksum mismatch)"));
    }
    let v: Value = serde_json::from_slice(&text)
        .map_err(|e| bad(path, format!("its header is not JSON: {e}")))?;
    let header = parse_header(&v).map_err(|what| bad(path, format!("its header: {what}")))?;
    let payload = 32 * header.elements();
    if len != 24 + h + 8 + payload + 8 {
        return Err(bad(
            path,
            format!(
                "{len} bytes where its header describes {} (truncated or damaged)",
                24 + h + 16 + payload
            ),
        ));
    }
    Ok((header, 24 + h + 8))
}

fn parse_header(v: &Value) -> Result<TileHeader, String> {
    let num = |key: &str| v[key].as_u64().ok_or_else(|| format!("`{key}` is missing"));
    let text = |key: &str| {
        v[key]
            .as_str()
            .map(str::to_string)
            .ok_or_else(|| format!("`{key}` is missing"))
    };
    let pair = |key: &str| -> Result<[usize; 2], String> {
        match v[key].as_array().map(Vec::as_slice) {
            Some([a, b]) => match (a.as_u64(), b.as_u64()) {
                (Some(a), Some(b)) => Ok([a as usize, b as usize]),
                _ => Err(format!("`{key}` is not two counts")),
            },
            _ => Err(format!("`{key}` is not two counts")),
        }
    };
    if v["format"].as_str() != Some("speckle band tile") {
        return Err("not of a band tile".into());
    }
    let [index, count] = pair("tile")?;
    let tile = Shard::new(index, count).map_err(|e| e.to_string())?;
    let [y0, y1] = pair("rows")?;
    let shape: Vec<usize> = v["shape"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|n| n.as_u64().map(|n| n as usize))
                .collect()
        })
        .unwrap_or_default();
    let shape: [usize; 6] = shape
        .try_into()
        .map_err(|_| "`shape` is not six counts".to_string())?;
    // Sizes must not overflow (the file's length is checked against them next).
    shape
        .iter()
        .try_fold(32u64, |a, &n| a.checked_mul(n as u64))
        .ok_or("`shape` overflows")?;
    Ok(TileHeader {
        tile,
        rows: y0..y1,
        radius: num("radius")? as usize,
        single_beyond: match &v["single_beyond"] {
            Value::Null => None,
            n => Some(n.as_u64().ok_or("`single_beyond` is not a count or null")? as usize),
        },
        shape,
        run_hash: text("run_hash")?,
        seed: num("seed")?,
        paths: num("paths")?,
        name: text("name")?,
        origin: text("origin")?,
        base: PathBuf::from(text("base")?),
        scene_toml: text("scene_toml")?,
        version: text("speckle_version")?,
        wall_time_s: v["wall_time_s"].as_f64().unwrap_or(0.0),
    })
}

/// One tile to merge: its file, header and payload offset.
#[derive(Debug, Clone)]
struct Tile {
    path: PathBuf,
    header: TileHeader,
    payload: u64,
}

/// The two arrays of a band.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BandArray {
    /// `cov_band`: the covariance.
    Value,
    /// `cov_band_stderr`: its standard errors.
    StdError,
}

/// Checked tiles of one band render, ready to be written ([`merge_tiles`]).
#[derive(Debug, Clone)]
pub struct BandTiles {
    /// The problem the tiles were rendered from (with the merge's overrides of the output
    /// settings).
    pub problem: Problem,
    /// The whole band.
    pub band: ImageBand,
    /// Its correlation summaries, bitwise the whole render's.
    pub correlation: BandCorrelation,
    /// Sub-paths of the render.
    pub paths: u64,
    /// Sum of the tiles' wall times, in seconds.
    pub wall_time_s: f64,
    /// The tiles in row order.
    tiles: Vec<Tile>,
}

fn mismatch(what: String) -> RunError {
    RunError::Shard(ShardError::Mismatch(what))
}

/// Checks the tile files `paths` (in any order) of one band render: every tile of one split,
/// each once, of the same run (run hash, seed, radius), rebuilt into its problem (with
/// `overrides`) whose image and band they fit; reads them once to verify their checksums and
/// collect the intensities, and once more for the correlation summaries. Memory: the image's
/// intensities and one pixel's elements, never a tile.
pub fn merge_tiles(paths: &[PathBuf], overrides: &Overrides) -> Result<BandTiles, RunError> {
    let mut tiles = paths
        .iter()
        .map(|p| {
            let (header, payload) = read_tile_header(p)?;
            Ok(Tile {
                path: p.clone(),
                header,
                payload,
            })
        })
        .collect::<Result<Vec<_>, RunError>>()?;
    let Some(first) = tiles.first() else {
        return Err(ShardError::NoShards.into());
    };
    let label = |t: &Tile| format!("{} (tile {})", t.path.display(), t.header.tile);
    let h0 = &first.header;
    for t in &tiles[1..] {
        let h = &t.header;
        let other = |what: &str, a: &dyn std::fmt::Display, b: &dyn std::fmt::Display| {
            mismatch(format!(
                "{} and {} are of different {what} ({b} and {a}); tiles of one band render \
                 only can be merged",
                label(t),
                label(first)
            ))
        };
        if h.seed != h0.seed {
            return Err(other("seeds", &h0.seed, &h.seed));
        }
        if h.radius != h0.radius {
            return Err(other("band radii", &h0.radius, &h.radius));
        }
        if h.single_beyond != h0.single_beyond {
            let r1 = |r: Option<usize>| r.map_or("none".to_string(), |r| r.to_string());
            return Err(other(
                "--single-beyond radii",
                &r1(h0.single_beyond),
                &r1(h.single_beyond),
            ));
        }
        if h.tile.count != h0.tile.count {
            return Err(other("splits (tile counts)", &h0.tile.count, &h.tile.count));
        }
    }
    let count = h0.tile.count;
    tiles.sort_by_key(|t| t.header.tile.index);
    for w in tiles.windows(2) {
        if w[0].header.tile.index == w[1].header.tile.index {
            return Err(mismatch(format!(
                "{} and {} are the same tile",
                label(&w[0]),
                label(&w[1])
            )));
        }
    }
    let missing: Vec<String> = (0..count)
        .filter(|i| !tiles.iter().any(|t| t.header.tile.index == *i))
        .map(|i| format!("{i}/{count}"))
        .collect();
    if !missing.is_empty() {
        return Err(mismatch(format!(
            "tile{} {} of the band are missing (every tile 0/{count} .. {}/{count} is needed)",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", "),
            count - 1
        )));
    }
    let h0 = &tiles[0].header;
    let problem = load_str_unquoted(
        &h0.scene_toml,
        &h0.origin,
        Path::new(&h0.base),
        &h0.name,
        overrides,
    )?;
    if run_hash(&problem, Kind::Covariance) != h0.run_hash {
        return Err(mismatch(format!(
            "the scene of {} no longer builds to the run it was rendered from (an input file \
             it names changed since, or another speckle version); render the tiles again",
            label(&tiles[0])
        )));
    }
    let grid = problem.grid.as_ref().ok_or_else(|| {
        mismatch("the tiles' scene has no image of sensors: not a band render".into())
    })?;
    let (nx, ny) = (grid.nx, grid.ny);
    let band = ImageBand::of_tile(&problem.scene, nx, ny, h0.radius, 0..ny).or_else(|e| {
        // A band too large to render whole may still be merged: its shape is what counts.
        ImageBand::of_tile(&problem.scene, nx, ny, h0.radius, 0..1).map_err(|_| e)
    })?;
    let band = match h0.single_beyond {
        Some(r1) => band.with_single_beyond(r1)?,
        None => band,
    };
    for t in &tiles {
        let h = &t.header;
        let rows = tile_rows(ny, h.tile)?;
        let tile = ImageBand::of_tile(&problem.scene, nx, ny, h.radius, rows.clone())?;
        if h.rows != rows || h.shape != tile.shape() || h.paths != tiles[0].header.paths {
            return Err(bad(
                &t.path,
                format!(
                    "its rows {:?} and shape {:?} are not tile {} of the band (rows {rows:?}, \
                     shape {:?})",
                    h.rows,
                    h.shape,
                    h.tile,
                    tile.shape()
                ),
            ));
        }
    }
    let paths = tiles[0].header.paths;
    let wall_time_s = tiles.iter().map(|t| t.header.wall_time_s).sum();
    let mut merged = BandTiles {
        problem,
        correlation: BandCorrelation::new(&band, no_intensities(&band)),
        band,
        paths,
        wall_time_s,
        tiles,
    };
    merged.summarise()?;
    Ok(merged)
}

/// Zero intensities of the band's `S ny nx` pixels (filled by the merge's first pass).
fn no_intensities(band: &ImageBand) -> Vec<f64> {
    let [s, ny, nx, ..] = band.whole_shape();
    vec![0.0; s * ny * nx]
}

impl BandTiles {
    /// Elements of one pixel (`S (2R + 1)^2`).
    fn pixel(&self) -> usize {
        let [_, _, _, s, w, _] = self.band.whole_shape();
        s * w * w
    }

    /// Calls `f(s1, y, x, elements)` for every pixel of array `which`, in array order, reading
    /// the tiles block by block.
    fn each_pixel(
        &self,
        which: BandArray,
        mut f: impl FnMut(usize, usize, usize, &[Complex64]),
    ) -> Result<(), RunError> {
        let [s, _, nx, ..] = self.band.whole_shape();
        let pixel = self.pixel();
        let (mut bytes, mut values) = (vec![0u8; 16 * pixel], vec![Complex64::ZERO; pixel]);
        for s1 in 0..s {
            for t in &self.tiles {
                let mut r = self.block(t, which, s1)?;
                for y in t.header.rows.clone() {
                    for x in 0..nx {
                        r.read_exact(&mut bytes)
                            .map_err(|e| bad(&t.path, format!("cannot read it: {e}")))?;
                        decode(&bytes, &mut values);
                        f(s1, y, x, &values);
                    }
                }
            }
        }
        Ok(())
    }

    /// A reader at the start of tile `t`'s block of source `s1` in array `which`.
    fn block(
        &self,
        t: &Tile,
        which: BandArray,
        s1: usize,
    ) -> Result<std::io::BufReader<std::fs::File>, RunError> {
        let (mut file, _) = speckle_scene::safe::open_regular(&t.path, u64::MAX)
            .map_err(|why| bad(&t.path, format!("cannot read it: {why}")))?;
        let at = t.payload + self.offset(t, which, s1);
        file.seek(SeekFrom::Start(at))
            .map_err(|e| bad(&t.path, format!("cannot read it: {e}")))?;
        Ok(std::io::BufReader::with_capacity(1 << 20, file))
    }

    /// Bytes from tile `t`'s payload to its block of `s1` in `which`.
    fn offset(&self, t: &Tile, which: BandArray, s1: usize) -> u64 {
        let elements = t.header.elements();
        let block = elements / self.band.whole_shape()[0] as u64;
        let array = if which == BandArray::Value {
            0
        } else {
            elements
        };
        16 * (array + s1 as u64 * block)
    }

    /// The merge's two passes: checksums and intensities, then the correlation summaries.
    fn summarise(&mut self) -> Result<(), RunError> {
        for t in &self.tiles {
            let (mut file, _) = speckle_scene::safe::open_regular(&t.path, u64::MAX)
                .map_err(|why| bad(&t.path, format!("cannot read it: {why}")))?;
            file.seek(SeekFrom::Start(t.payload))
                .map_err(|e| bad(&t.path, format!("cannot read it: {e}")))?;
            let mut r = std::io::BufReader::with_capacity(1 << 20, file);
            let (mut hash, mut left, mut buf) =
                (Xxh64::new(), 32 * t.header.elements(), vec![0u8; 1 << 20]);
            while left > 0 {
                let n = left.min(buf.len() as u64) as usize;
                r.read_exact(&mut buf[..n])
                    .map_err(|e| bad(&t.path, format!("cannot read it: {e}")))?;
                hash.update(&buf[..n]);
                left -= n as u64;
            }
            let mut sum = [0u8; 8];
            r.read_exact(&mut sum)
                .map_err(|e| bad(&t.path, format!("cannot read it: {e}")))?;
            if hash.digest() != u64::from_le_bytes(sum) {
                return Err(bad(&t.path, "its numbers are damaged (checksum mismatch)"));
            }
        }
        let [_, ny, nx, _, w, _] = self.band.whole_shape();
        let r = self.band.radius();
        let mut intensity = no_intensities(&self.band);
        self.each_pixel(BandArray::Value, |s1, y, x, v| {
            intensity[(s1 * ny + y) * nx + x] = v[(s1 * w + r) * w + r].re;
        })?;
        let mut c = BandCorrelation::new(&self.band, intensity);
        self.each_pixel(BandArray::Value, |s1, y, x, v| c.add_pixel(s1, y, x, v))?;
        self.correlation = c;
        Ok(())
    }

    /// Writes array `which` as a `.npy` file of the whole band's shape: its header, then the
    /// tiles' blocks in array order (for each `s1`, the tiles in row order), copied through a
    /// buffer. Bitwise the whole render's file.
    pub fn write(&self, which: BandArray, out: &mut dyn Write) -> std::io::Result<()> {
        out.write_all(&speckle_scene::npy::c16_header(&self.band.whole_shape()))?;
        for s1 in 0..self.band.whole_shape()[0] {
            for t in &self.tiles {
                let r = self
                    .block(t, which, s1)
                    .map_err(|e| std::io::Error::other(e.to_string()))?;
                let len = 16 * t.header.elements() / self.band.whole_shape()[0] as u64;
                let copied = std::io::copy(&mut r.take(len), out)?;
                if copied != len {
                    return Err(std::io::Error::other(format!(
                        "{}: shorter than when it was checked",
                        t.path.display()
                    )));
                }
            }
        }
        Ok(())
    }

    /// Number of tiles merged.
    pub fn tiles(&self) -> usize {
        self.tiles.len()
    }

    /// Kept entries of the whole band (inside the image): `S^2` times the offsets `(dy, dx)`
    /// within the radius summed over the pixels that they keep in the image.
    pub fn kept_entries(&self) -> usize {
        self.band.whole_entries_within(self.band.radius())
    }
}

/// Decodes little-endian complex128 `bytes` into `out`.
fn decode(bytes: &[u8], out: &mut [Complex64]) {
    for (z, b) in out.iter_mut().zip(bytes.chunks_exact(16)) {
        let f = |k: usize| f64::from_le_bytes(b[k..k + 8].try_into().expect("8 bytes"));
        *z = Complex64::new(f(0), f(8));
    }
}
