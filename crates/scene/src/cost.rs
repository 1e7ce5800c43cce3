//! Up-front estimates of what a command will cost (peak memory and a rough wall time), the
//! limits of the outputs (PNG sizes, file counts), and the guard that refuses, before any work,
//! what exceeds the machine.
//!
//! The times come from the speeds of one machine (a 2-core x86-64 with AVX-512, the figures of
//! `docs/performance.md`) and a diffusion estimate of the vertices per path; they are meant to
//! tell minutes from days, not to be exact. The guard ([`guard`]) refuses, naming the field that
//! drives the cost, a command whose memory exceeds the machine's (`MemTotal`) or whose time
//! exceeds [`MAX_SECONDS`]; `force` lets it through. Scenes whose paths are effectively endless
//! ([`MAX_VERTICES_PER_PATH`]) are refused even then, unless `render.max_vertices` bounds them.

use crate::SceneError;
use crate::problem::Problem;
use crate::validate::invalid;
use speckle_medium::{AnyMedium, DVec3, Dimension, Medium};
use speckle_phase::PhaseFunction;

/// Rough times above this (seconds) are refused without `force`: a day.
pub const MAX_SECONDS: f64 = 86_400.0;

/// Expected vertices per path above which paths are effectively endless (days per path, and
/// free flights below the resolution of positions long before): refused, even with `force`,
/// unless `render.max_vertices` bounds them.
pub const MAX_VERTICES_PER_PATH: f64 = 1e10;

/// Pixels of one PNG image at most (64 Mi: 64 MiB of gray levels before compression).
pub const MAX_PNG_PIXELS: f64 = (1u64 << 26) as f64;

/// PNG files of one command at most.
pub const MAX_PNG_FILES: usize = 10_000;

// Single-thread speeds of the reference machine (seconds per operation).
/// A vertex: flight, roulette, direction, connection bookkeeping (`dcs.toml`'s 200 000 paths
/// of about 150 vertices took 0.5 s on two threads; was 1.5e-7, which put the time of renders
/// with few endpoints 5 times too high).
const VERTEX_S: f64 = 3.5e-8;
/// One endpoint leg of a connection (113 M/s).
const LEG_S: f64 = 9e-9;
/// The cost of one vMF lobe of a Gaussian beam's connection (a complex square root, logarithm
/// and exponential, and the beam's share of the first-vertex mixture's density), in plain
/// legs: measured on `scenes/importance_sampling.toml` (10 beams, 3 lobes) against the plain
/// scenes `default.toml` and `memory_effect.toml` on the same machine (was 8, which left
/// Gaussian-beam renders 7 times further below their time than plain ones).
const GAUSSIAN_LEG: f64 = 55.0;

/// `beams` Gaussian-beam endpoints of a phase function of `lobes` vMF amplitude lobes, in plain
/// legs (the `legs` of [`covariance_seconds`]).
pub fn gaussian_legs(beams: f64, lobes: usize) -> f64 {
    beams * lobes.max(1) as f64 * GAUSSIAN_LEG
}
/// One pair's product of legs, and its addition to a sum.
const PAIR_S: f64 = 4e-9;
/// One complex multiply-add of the rank-K covariance update (8 flops at 60 GFLOP/s).
const MAC_S: f64 = 8.0 / 6e10;
/// One point of the far-field mean quadrature (measured on `default.toml`, transmission, and
/// `backscatter.toml`, where the faces the wave enters take both legs at about the same cost).
const QUADRATURE_S: f64 = 5e-8;
/// The merge of one batch's sums into the moments, per entry of a `J x J` matrix (complex
/// sums and squares of three estimates): memory bound, so counted once whatever the threads
/// (128 batches of `J = 4097` took 16 s on one thread of the reference machine, 10 s on two).
const MERGE_S: f64 = 5e-9;
/// A batch's intensity sums, per pair, whatever the threads: the zeroed sums of two parts,
/// and their merge into the moments (11 s for 128 batches of `J = 2 000 000` on two threads of
/// the reference machine).
const DIAGONAL_MERGE_S: f64 = 4.4e-8;
/// A detector at a vertex of a detector render: the splitting importance (the dipole model's
/// reflectance, two exponentials), the exit test and the next-event check (measured on
/// `tissue_fibre.toml`, one detector, and `head.toml`, four).
const DETECTOR_S: f64 = 6e-8;
/// What a `J x J` render does after its paths, per entry and on one thread whatever the
/// threads: the standard errors, the encoding and synced writes of four arrays, the PNG (3-6 s
/// for `J = 4097`, with the page cache's write-back of the previous files).
const MATRIX_OUTPUT_S: f64 = 3e-7;

/// What a command will cost.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Peak memory, bytes (results, accumulators, staged output files, the medium).
    pub bytes: f64,
    /// The field that drives the memory (named when it is refused).
    pub memory_field: String,
    /// Rough wall time on the given threads, seconds.
    pub seconds: f64,
    /// The field that drives the time.
    pub time_field: String,
    /// Expected vertices per path (0 for commands that trace none).
    pub vertices_per_path: f64,
}

/// `n` bytes in a unit a reader takes in at a glance.
pub fn human_bytes(n: f64) -> String {
    let mut v = n;
    for unit in ["B", "KiB", "MiB", "GiB"] {
        if v < 1024.0 {
            return format!("{v:.0} {unit}");
        }
        v /= 1024.0;
    }
    format!("{v:.1} TiB")
}

/// `t` seconds in a unit a reader takes in at a glance.
pub fn human_seconds(t: f64) -> String {
    match t {
        t if t < 1.0 => "under a second".to_string(),
        t if t < 120.0 => format!("{t:.0} s"),
        t if t < 7200.0 => format!("{:.0} min", t / 60.0),
        t if t < 172_800.0 => format!("{:.1} h", t / 3600.0),
        t if t < 3.2e9 => format!("{:.0} days", t / 86_400.0),
        _ => "more than a century".to_string(),
    }
}

impl Estimate {
    /// The estimate of one of `count` shards of this run: its share of the time, and the
    /// single run's memory (a shard keeps the whole run's accumulators).
    pub fn shard_of(mut self, count: usize) -> Self {
        self.seconds /= count.max(1) as f64;
        self
    }

    /// One line: `about X of memory, roughly Y`.
    pub fn describe(&self) -> String {
        format!(
            "about {} of memory, roughly {}",
            human_bytes(self.bytes),
            human_seconds(self.seconds)
        )
    }
}

/// The machine's memory in bytes (`MemTotal` of `/proc/meminfo`), when known.
pub fn machine_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// The peak resident memory of this process so far in bytes (`VmHWM` of
/// `/proc/self/status`), when known: the sidecars record it beside the estimate.
pub fn peak_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// Refuses `e` when it exceeds the machine: memory above `memory` bytes (the machine's, when
/// known) or a time above [`MAX_SECONDS`], unless `force`. The error names the field that
/// drives the cost and says how to go ahead.
pub fn guard(e: &Estimate, memory: Option<f64>, force: bool) -> Result<(), SceneError> {
    if force {
        return Ok(());
    }
    if let Some(m) = memory
        && e.bytes > m
    {
        return Err(invalid(
            &e.memory_field,
            format!(
                "this needs about {} of memory, more than this machine's {}; reduce it, or pass \
                 --force to try anyway",
                human_bytes(e.bytes),
                human_bytes(m)
            ),
        ));
    }
    if e.seconds > MAX_SECONDS {
        return Err(invalid(
            &e.time_field,
            format!(
                "this would take roughly {} ({}); reduce it, or pass --force to run anyway",
                human_seconds(e.seconds),
                e.describe()
            ),
        ));
    }
    Ok(())
}

/// Expected vertices of a sub-path in a box of optical extents `taus` (one per axis), albedo
/// and mean cosine `g`: a diffusion estimate of the steps before the walk leaves the box (the
/// mean exit time `tau^2 (1 - g) / 4` of a slab of optical thickness `tau` from a uniform
/// start, `/ 6` in flatland, but no less than the ballistic `tau / 2`, which a forward phase
/// function approaches; the axes combined as parallel exits), cut by absorption
/// (`1 / (1 - albedo)`) and by `max_vertices`.
pub fn expected_vertices(
    taus: &[f64],
    albedo: f64,
    g: f64,
    dim: Dimension,
    max_vertices: u32,
) -> f64 {
    let g = g.clamp(-1.0, 0.999);
    let per_axis = match dim {
        Dimension::Three => 4.0,
        Dimension::Two => 6.0,
    };
    let exit_rate: f64 = taus
        .iter()
        .map(|t| 1.0 / (t * t * (1.0 - g) / per_axis).max(0.5 * t).max(1e-300))
        .sum();
    let absorb = (1.0 - albedo).max(0.0);
    let steps = 1.0 + 1.0 / (exit_rate + absorb);
    steps.min(f64::from(max_vertices))
}

/// Rough seconds of `paths` paths of `vertices` vertices each connected to `legs` endpoints
/// and `pairs` pairs, accumulating a `pairs x pairs` covariance, on one thread of the reference
/// machine.
pub fn covariance_seconds(paths: f64, vertices: f64, legs: f64, pairs: f64) -> f64 {
    paths * vertices * (VERTEX_S + legs * LEG_S + pairs * PAIR_S + 0.5 * pairs * pairs * MAC_S)
}

/// Rough seconds of `paths` sampled field paths (Alg. 2) of `vertices` vertices each, connected
/// to `legs` endpoints and updating `pairs` fields, on one thread of the reference machine.
pub fn field_seconds(paths: f64, vertices: f64, legs: f64, pairs: f64) -> f64 {
    paths * vertices * (VERTEX_S + legs * LEG_S + pairs * PAIR_S)
}

/// Bytes and rough seconds per vertex of a correlation render of `j` entries at `lags` lags
/// with `legs` endpoints: per lag, three estimates of every entry and the batches in flight;
/// with drift both copies of every lag connect to every endpoint at both end vertices
/// (`Copies::Displaced`); with Gaussian beams and no drift every lag takes two damped beam
/// integrals per endpoint at the vertex itself (`Copies::Damped`: about a sixth of a connection
/// per lag, measured: 6.3 times the static covariance at 64 lags).
fn g1_cost(j: f64, lags: f64, copies: Copies, legs: f64, threads: f64) -> (f64, f64) {
    let bytes = 16.0 * j * lags * (8.0 + 4.0 * threads);
    let connects = match copies {
        Copies::Displaced => 1.0 + 2.0 * lags,
        Copies::Damped => 2.0 + lags / 6.0,
        Copies::Shared => 2.0,
    };
    let per_vertex_connect = legs * LEG_S + j * PAIR_S;
    (
        bytes,
        VERTEX_S + connects * per_vertex_connect + j * lags * PAIR_S,
    )
}

/// How a correlation render connects the two copies of a path's end vertices ([`g1_cost`]):
/// where the static connector does, with damped beam integrals per lag, at displaced points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Copies {
    Shared,
    Damped,
    Displaced,
}

/// The commands whose cost [`Problem::estimate`] knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// `speckle covariance`.
    Covariance,
    /// `speckle intensity`.
    Intensity,
    /// `speckle single`.
    Single,
    /// `speckle fields`.
    Fields,
    /// `speckle mean`.
    Mean,
    /// `speckle g1` (temporal correlations of moving scatterers at `motion.lags`).
    G1,
    /// `speckle tracking` (Bar et al. 2023, Fig. 9): the `g1` render of the scene's pair, the
    /// same with the drift removed, and one render per lag of the pair against itself shifted
    /// with the flow (two pairs and three times the endpoints, one lag each).
    Tracking,
}

/// Parts of the medium whose paths [`expected_vertices`] estimates, as optical extents along
/// each axis and an albedo: the whole medium (a voxel grid at its mean extinction and albedo),
/// and for a grid each set of voxels of about the same extinction (within a quarter octave,
/// at the set's largest extinction and albedo) that fills at least half of its bounding box,
/// such as a layer: a thin layer far denser than the rest (a scalp of 4e9 /cm over a
/// strongly absorbing CSF, a fuzz finding of issue 27) keeps paths in it that the mean
/// hides.
fn regions(m: &AnyMedium) -> Vec<(Vec<f64>, f64)> {
    let size = m.bounds().size();
    let dims = m.dimension().count() as usize;
    let extents = |sigma_t: f64, size: DVec3| (0..dims).map(|i| sigma_t * size[i]).collect();
    match m {
        AnyMedium::Box(b) => vec![(
            extents(b.extinction(), size),
            b.scattering() / b.extinction(),
        )],
        AnyMedium::Grid(g) => {
            let (t, s) = (g.voxel_sigma_t(), g.voxel_sigma_s());
            let n = t.len().max(1) as f64;
            let (st, ss) = (t.iter().sum::<f64>(), s.iter().sum::<f64>());
            let mean_albedo = if st > 0.0 { ss / st } else { 0.0 };
            let mut out = vec![(extents(st / n, size), mean_albedo)];
            // Per quarter-octave bucket of extinction: voxel count, bounding box of voxel
            // indices, largest extinction and albedo.
            struct Bucket {
                count: usize,
                lo: [usize; 3],
                hi: [usize; 3],
                sigma_t: f64,
                albedo: f64,
            }
            let [_, ny, nz] = g.dims();
            let mut buckets: std::collections::BTreeMap<i64, Bucket> = Default::default();
            for (i, (&vt, &vs)) in t.iter().zip(s).enumerate() {
                if !(vt > 0.0 && vt.is_finite()) {
                    continue;
                }
                let idx = [i / (ny * nz), (i / nz) % ny, i % nz];
                let key = (4.0 * vt.log2()).floor() as i64;
                let b = buckets.entry(key).or_insert(Bucket {
                    count: 0,
                    lo: idx,
                    hi: idx,
                    sigma_t: 0.0,
                    albedo: 0.0,
                });
                b.count += 1;
                for (a, &i) in idx.iter().enumerate() {
                    b.lo[a] = b.lo[a].min(i);
                    b.hi[a] = b.hi[a].max(i);
                }
                b.sigma_t = b.sigma_t.max(vt);
                b.albedo = b.albedo.max(vs / vt);
            }
            let cell = g.voxel_size();
            for b in buckets.values() {
                let span: [usize; 3] = std::array::from_fn(|a| b.hi[a] - b.lo[a] + 1);
                if 2 * b.count < span.iter().product::<usize>() {
                    continue;
                }
                let extent = DVec3::new(
                    span[0] as f64 * cell.x,
                    span[1] as f64 * cell.y,
                    span[2] as f64 * cell.z,
                );
                out.push((extents(b.sigma_t, extent), b.albedo));
            }
            out
        }
    }
}

impl Problem {
    /// Expected vertices of a sub-path in this scene ([`expected_vertices`]): the most of any
    /// of its [`regions`], with the optical extents of that region.
    fn path_length(&self) -> (f64, Vec<f64>) {
        let m = self.scene.medium();
        let g = self
            .scene
            .phases()
            .iter()
            .map(|p| p.mean_cosine())
            .fold(-1.0, f64::max);
        regions(m)
            .into_iter()
            .map(|(taus, albedo)| {
                let v = expected_vertices(
                    &taus,
                    albedo,
                    g,
                    m.dimension(),
                    self.render.sampling.max_vertices,
                );
                (v, taus)
            })
            .fold((0.0, Vec::new()), |a, b| if b.0 > a.0 { b } else { a })
    }

    /// Expected vertices of a sub-path in this scene ([`expected_vertices`]).
    pub fn vertices_per_path(&self) -> f64 {
        self.path_length().0
    }

    /// The field that sets the medium's extinction, as the scene file gives it.
    fn extinction_field(&self) -> &'static str {
        let m = &self.file.medium;
        if m.grid.is_some() {
            "medium.grid"
        } else if m.particles.is_some() {
            "medium.particles"
        } else if m.mean_free_path.is_some() {
            "medium.mean_free_path"
        } else {
            "medium.sigma_s"
        }
    }

    /// Refuses paths that are effectively endless ([`MAX_VERTICES_PER_PATH`]) unless
    /// `render.max_vertices` bounds them; names the field that sets the extinction.
    pub fn check_path_length(&self) -> Result<f64, SceneError> {
        let (v, taus) = self.path_length();
        if v > MAX_VERTICES_PER_PATH {
            return Err(invalid(
                self.extinction_field(),
                format!(
                    "the medium is so optically thick (optical extents {:?}) that a path would \
                     scatter about {v:.1e} times before it leaves: it would never end; use a \
                     thinner medium, or bound the paths with render.max_vertices (biased)",
                    taus.iter().map(|t| format!("{t:.3e}")).collect::<Vec<_>>()
                ),
            ));
        }
        Ok(v)
    }

    /// The pixel replication of a PNG of `width x height` values: `output.png_scale`, or the
    /// smallest integer that makes the larger side at least 256 pixels (at most 16); refuses
    /// images above [`MAX_PNG_PIXELS`], naming `output.png_scale` (or `output.png` when even
    /// one pixel per value is too many).
    pub fn png_scale(&self, width: usize, height: usize) -> Result<usize, SceneError> {
        let scale = match self.output.png_scale {
            Some(s) => s as usize,
            None => 256usize.div_ceil(width.max(height).max(1)).clamp(1, 16),
        };
        let pixels = |s: usize| (width * s) as f64 * (height * s) as f64;
        if pixels(scale) > MAX_PNG_PIXELS {
            let (field, hint) = if scale > 1 && pixels(1) <= MAX_PNG_PIXELS {
                ("output.png_scale", "use a smaller scale")
            } else {
                ("output.png", "set output.png = false (or --no-png)")
            };
            return Err(invalid(
                field,
                format!(
                    "a {width} x {height} image at scale {scale} has {:.2e} pixels, more than \
                     the limit of {MAX_PNG_PIXELS:.2e}; {hint}",
                    pixels(scale)
                ),
            ));
        }
        Ok(scale)
    }

    /// The PNG files `command` would write (field images of `rows` realizations or
    /// configurations): `(count, pixels in all)`; refuses too large images and too many files
    /// (naming `output.png_scale`, `output.png_realizations`).
    pub fn pngs(&self, command: Command, rows: usize) -> Result<(usize, f64), SceneError> {
        if !self.output.png {
            return Ok((0, 0.0));
        }
        let j = self.pairs();
        match command {
            Command::Covariance | Command::Single => {
                let s = self.png_scale(j, j)?;
                Ok((1, (j * s) as f64 * (j * s) as f64))
            }
            Command::Mean | Command::G1 | Command::Tracking => Ok((0, 0.0)),
            Command::Intensity | Command::Fields => {
                let Some(g) = self.png_grid() else {
                    return Ok((0, 0.0));
                };
                let s = self.png_scale(g.nx, g.ny)?;
                let images = if command == Command::Fields {
                    rows.min(self.output.png_realizations)
                        .saturating_mul(self.n_sources())
                } else {
                    self.n_sources()
                };
                if images > MAX_PNG_FILES {
                    let field = if command == Command::Fields {
                        "output.png_realizations"
                    } else {
                        "output.png"
                    };
                    return Err(invalid(
                        field,
                        format!(
                            "this would write {images} PNG images, more than the limit of \
                             {MAX_PNG_FILES}"
                        ),
                    ));
                }
                let each = (g.nx * s) as f64 * (g.ny * s) as f64;
                Ok((images, images as f64 * each))
            }
        }
    }

    /// The number of endpoints in units of a plain leg's cost: a Gaussian beam's connection
    /// costs about [`GAUSSIAN_LEG`] legs per vMF lobe of the costliest phase.
    fn leg_cost(&self) -> f64 {
        let (src, sen) = (self.scene.sources(), self.scene.sensors());
        let gaussian = src
            .iter()
            .filter(|s| matches!(s, speckle_endpoints::Source::GaussianBeam(_)))
            .count()
            + sen
                .iter()
                .filter(|s| matches!(s, speckle_endpoints::Sensor::GaussianBeam(_)))
                .count();
        let lobes = self
            .scene
            .phases()
            .iter()
            .map(|p| p.amplitude_lobes().map_or(1, <[_]>::len))
            .max()
            .unwrap_or(1);
        let plain = src.len() + sen.len() - gaussian;
        plain as f64 + gaussian_legs(gaussian as f64, lobes)
    }

    /// Bytes of the medium's own data (a voxel grid's arrays).
    fn medium_bytes(&self) -> f64 {
        match self.scene.medium() {
            AnyMedium::Box(_) => 0.0,
            AnyMedium::Grid(g) => 28.0 * g.dims().iter().map(|&d| d as f64).product::<f64>(),
        }
    }

    /// Bytes of the endpoint lists and pair list (the scene, and their `.npy` tables).
    fn endpoint_bytes(&self) -> f64 {
        let n = (self.n_sources() + self.n_sensors()) as f64;
        n * (200.0 + 64.0) + self.pairs() as f64 * (16.0 + 16.0)
    }

    /// The cost of `command` on `threads` threads: checks the output sizes and the length of
    /// the paths first (errors name the field), then estimates memory and time. The guard
    /// ([`guard`]) decides whether to go ahead.
    pub fn estimate(&self, command: Command, threads: usize) -> Result<Estimate, SceneError> {
        self.estimate_with(command, threads, None)
    }

    /// [`Problem::estimate`] with the vertices per path measured by a pilot where the
    /// expected ones are not known (detectors' weight windows multiply the paths:
    /// `speckle_estimators::detector_vertices_per_path`); `None`: the expected ones.
    pub fn estimate_with(
        &self,
        command: Command,
        threads: usize,
        measured_vertices: Option<f64>,
    ) -> Result<Estimate, SceneError> {
        // Every command here is a Monte Carlo render (or the mean field): refuse what the
        // estimators would refuse, naming the endpoint. They all connect Gaussian beams (near
        // field) whose amplitudes are vMF lobes; the mean has its own closed form.
        if !matches!(command, Command::Intensity | Command::G1) {
            self.scene.check_field_sensors()?;
        }
        let (sources, sensors) = (self.scene.sources(), self.scene.sensors());
        match command {
            Command::Mean => Ok(()),
            _ => speckle_endpoints::check_near_field(sources, sensors, self.scene.phases()),
        }
        .map_err(|e| {
            let speckle_endpoints::EndpointError::InvalidInput { field, reason } = e;
            invalid(field, reason)
        })?;
        let threads = threads.max(1) as f64;
        let j = self.pairs() as f64;
        let r = &self.render;
        let rows = r.realizations;
        let (_, png_pixels) = self.pngs(command, rows)?;
        let legs = self.leg_cost();
        let fixed = self.medium_bytes() + self.endpoint_bytes() + 2.0 * png_pixels;
        let traced = matches!(
            command,
            Command::Covariance
                | Command::Intensity
                | Command::Fields
                | Command::G1
                | Command::Tracking
        );
        let vertices = if traced {
            let expected = self.check_path_length()?;
            measured_vertices.unwrap_or(expected)
        } else {
            0.0
        };
        let per_vertex_connect = legs * LEG_S + j * PAIR_S;
        let (bytes, memory_field, seconds, time_field) = match command {
            Command::Covariance => {
                // Accumulators of three estimates and the batches in flight, and five staged
                // J x J arrays.
                let square = 16.0 * j * j;
                let bytes = square * (12.0 + 4.0 * threads) + 5.0 * square;
                let per_path = vertices * (VERTEX_S + per_vertex_connect + 0.5 * j * j * MAC_S);
                (bytes, "sensors", per_path * r.paths as f64, "render.paths")
            }
            Command::Single => {
                let square = 16.0 * j * j;
                let bytes = square * (4.0 + 2.0 * threads) + 2.0 * square;
                let per_path = VERTEX_S + per_vertex_connect + 0.5 * j * j * MAC_S;
                (bytes, "sensors", per_path * r.paths as f64, "render.paths")
            }
            Command::Intensity => {
                // The moments of three estimates (sums and squares), the batch sums of two
                // parts held by the 4 batches per thread in flight, a connector per thread
                // (four legs per endpoint), and three staged arrays of J doubles.
                let endpoints = (self.n_sources() + self.n_sensors()) as f64;
                let bytes = 96.0 * j
                    + 4.0 * threads * 2.0 * 16.0 * j
                    + threads * 64.0 * endpoints
                    + 24.0 * j;
                // Per vertex, beyond the connections, the two parts' products added into
                // the batch's sums (a random walk over `J` doubles, memory bound at large J).
                let per_path = vertices
                    * (VERTEX_S + per_vertex_connect + 5.0 * j * PAIR_S + self.detector_seconds());
                (bytes, "sensors", per_path * r.paths as f64, "render.paths")
            }
            Command::G1 => {
                let beams = self.scene.has_beams();
                let (lags, drift) = self
                    .motion
                    .as_ref()
                    .map_or((1.0, false), |m| (m.lags.len() as f64, m.model.has_drift()));
                let copies = match (drift, beams) {
                    (true, _) => Copies::Displaced,
                    (false, true) => Copies::Damped,
                    (false, false) => Copies::Shared,
                };
                let (bytes, per_vertex) = g1_cost(j, lags, copies, legs, threads);
                (
                    bytes,
                    "motion.lags",
                    vertices * (per_vertex + self.detector_seconds()) * r.paths as f64,
                    "render.paths",
                )
            }
            Command::Tracking => {
                // The pair's g1 with and without drift (all lags), and per lag a render of two
                // pairs (the pair and its shifted copy) at that lag alone.
                let lags = self.motion.as_ref().map_or(1.0, |m| m.lags.len() as f64);
                let (b1, drifting) = g1_cost(j, lags, Copies::Displaced, legs, threads);
                let (_, rest) = g1_cost(j, lags, Copies::Shared, legs, threads);
                let (b2, shifted) = g1_cost(2.0 * j, 1.0, Copies::Displaced, 3.0 * legs, threads);
                let per_path = vertices * (drifting + rest + lags * shifted);
                (
                    b1.max(b2),
                    "motion.lags",
                    per_path * r.paths as f64,
                    "render.paths",
                )
            }
            Command::Fields => {
                // The fields, their intensities and the staged array.
                let bytes = rows as f64 * j * (16.0 + 8.0 + 16.0) + 16.0 * j * threads;
                let per_path = vertices * (VERTEX_S + per_vertex_connect);
                let paths = rows as f64 * r.paths_per_realization as f64;
                (
                    bytes,
                    "render.realizations",
                    per_path * paths,
                    "render.paths_per_realization",
                )
            }
            Command::Mean => (32.0 * j, "sensors", self.mean_seconds(), self.mean_field()),
        };
        // The closed-form means that the covariance and the fields (when they add them)
        // compute besides the paths: part of the command's time, which they can dominate (a
        // far grid of a million pixels; issue 27, item 8).
        let means = match command {
            Command::Covariance => self.mean_seconds(),
            Command::Fields if r.add_mean => self.mean_seconds(),
            _ => 0.0,
        };
        // Whatever the threads: the merges of the batches' matrices, and after the paths their
        // standard errors and files.
        let serial = match command {
            Command::Covariance | Command::Single => {
                self.merged_entries(j * j) * MERGE_S + j * j * MATRIX_OUTPUT_S
            }
            Command::Intensity => self.merged_entries(j) * DIAGONAL_MERGE_S,
            _ => 0.0,
        };
        let time_field = if means > seconds {
            self.mean_field()
        } else if serial > seconds / threads {
            "sensors"
        } else {
            time_field
        };
        Ok(Estimate {
            bytes: bytes + fixed,
            memory_field: memory_field.to_string(),
            seconds: (seconds + means) / threads + serial,
            time_field: time_field.to_string(),
            vertices_per_path: vertices,
        })
    }

    /// Seconds per vertex that detectors add (each: the weight window's importance, the exit
    /// test and the next-event check).
    fn detector_seconds(&self) -> f64 {
        if self.scene.has_detectors() {
            self.n_sensors() as f64 * DETECTOR_S
        } else {
            0.0
        }
    }

    /// Entries merged into the moments, `entries` per batch: the render is cut into about
    /// [`speckle_stats::TARGET_BATCHES`] batches whatever its paths, so for large `J` the
    /// merges, not the paths, set the time.
    /// The cost of a band of `entries` kept entries of the covariance (`speckle covariance
    /// --band`): the intensity render's connections, plus per vertex the two parts' products
    /// at the kept entries, the moments and batch sums of `entries` values (as the intensity's
    /// of `J`), their merges, and two staged arrays of the band.
    pub fn band_estimate(&self, entries: usize, threads: usize) -> Result<Estimate, SceneError> {
        let mut e = self.estimate_with(Command::Intensity, threads, None)?;
        let (n, t) = (entries as f64, threads.max(1) as f64);
        e.bytes += 96.0 * n + 4.0 * t * 2.0 * 16.0 * n + 32.0 * n;
        let products = e.vertices_per_path * 5.0 * n * PAIR_S * self.render.paths as f64;
        e.seconds += products / t + self.merged_entries(n) * DIAGONAL_MERGE_S;
        if products / t > e.seconds / 2.0 {
            e.time_field = "band".into();
        }
        e.memory_field = "band".into();
        Ok(e)
    }

    fn merged_entries(&self, entries: f64) -> f64 {
        let batches =
            speckle_stats::Batches::about(self.render.paths, speckle_stats::TARGET_BATCHES);
        batches.count() as f64 * entries
    }

    /// The field that drives the means' time: the sensors, or with one the medium's size.
    fn mean_field(&self) -> &'static str {
        if self.n_sensors() > 1 {
            "sensors"
        } else {
            "medium.size"
        }
    }

    /// Seconds of the closed-form means on one thread. A plane-wave source and a far-field
    /// sensor integrate over the faces where paths leave towards the sensor, with the rule of
    /// `speckle_endpoints::mean` (4 points per panel, `ceil(extent (k |i - v| + sigma_t))`
    /// panels clamped to 48..512 per axis). Every other pair is a closed form.
    fn mean_seconds(&self) -> f64 {
        use speckle_endpoints::{Sensor, Source};
        let m = self.scene.medium();
        let size = m.bounds().size();
        let k = self.scene.wavenumber();
        let sigma_t = m.uniform_sigma_t().unwrap_or(0.0);
        let (sources, sensors) = (self.scene.sources(), self.scene.sensors());
        let points = |ext: f64, rate: f64| {
            if ext == 0.0 {
                1.0
            } else {
                4.0 * (ext * rate).ceil().clamp(48.0, 512.0)
            }
        };
        let quadrature: f64 = self
            .scene
            .pairs()
            .iter()
            .map(|p| match (sources[p.source], sensors[p.sensor]) {
                (Source::PlaneWave { direction: i }, Sensor::FarField { direction: v }) => {
                    let rate = k * (i - v).length() + sigma_t;
                    (0..3)
                        .filter(|&axis| v[axis] != 0.0)
                        .map(|axis| {
                            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                            points(size[a1], rate) * points(size[a2], rate)
                        })
                        .sum::<f64>()
                }
                _ => 0.0,
            })
            .sum();
        quadrature * QUADRATURE_S + self.pairs() as f64 * 1e-6
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn human_units() {
        assert_eq!(human_bytes(512.0), "512 B");
        assert_eq!(human_bytes(3.0 * 1024.0 * 1024.0 * 1024.0), "3 GiB");
        assert_eq!(human_seconds(0.5), "under a second");
        assert_eq!(human_seconds(90.0), "90 s");
        assert_eq!(human_seconds(3.0 * 86_400.0), "3 days");
    }

    #[test]
    fn the_guard_refuses_what_exceeds_the_machine() {
        let e = Estimate {
            bytes: 2e9,
            memory_field: "sensors".into(),
            seconds: 10.0,
            time_field: "render.paths".into(),
            vertices_per_path: 5.0,
        };
        assert!(guard(&e, Some(4e9), false).is_ok());
        let m = guard(&e, Some(1e9), false).unwrap_err().to_string();
        assert!(m.starts_with("sensors: this needs about 2 GiB"), "{m}");
        assert!(guard(&e, Some(1e9), true).is_ok());
        let slow = Estimate { seconds: 1e7, ..e };
        let m = guard(&slow, None, false).unwrap_err().to_string();
        assert!(
            m.starts_with("render.paths: this would take roughly 116 days"),
            "{m}"
        );
    }
}
