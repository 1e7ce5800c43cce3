//! Speckle field sampling (Alg. 2, Sec. 5.2).

use crate::connect::{Connector, Cvec, Tile, tiles};
use crate::field_sequences::{Frames, Trajectory};
use crate::{CMatrix, Coherence, EstimatorError, Scene};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_paths::{PathRng, TracerConfig, Vertex, VertexSink};
use speckle_phase::PhaseFunction;
use speckle_stats::{
    Batches, PairShare, PartialRows, Poll, Progress, Shard, ShardError, assemble_rows,
    for_each_path, run_ordered_range,
};
use std::f64::consts::TAU;
use std::ops::Range;

/// Options of a field render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldOptions {
    /// Number `R` of independent field realizations.
    pub realizations: usize,
    /// Number `N` of sub-paths summed into each realization (more gives more Gaussian fields).
    pub paths_per_realization: u64,
    /// Seed; path `n` of realization `r` draws from stream `r N + n`.
    pub seed: u64,
    /// Forward and reversed paths, or forward only.
    pub coherence: Coherence,
    /// Add the speckle mean (Eq. 20 and its far-field form) to every realization.
    pub add_mean: bool,
    /// How sub-paths are sampled (first-vertex and first-direction strategies).
    pub sampling: TracerConfig,
}

impl Default for FieldOptions {
    /// 8 realizations of 20 000 paths, seed 1, forward and reversed paths, the mean added,
    /// uniform first vertex and direction.
    fn default() -> Self {
        Self {
            realizations: 8,
            paths_per_realization: 20_000,
            seed: 1,
            coherence: Coherence::default(),
            add_mean: true,
            sampling: TracerConfig::default(),
        }
    }
}

/// `R` realizations of the `J`-vector of fields of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldEstimate {
    /// Fields, one realization per row (`R x J`).
    pub fields: CMatrix,
    /// The speckle mean that was added to every row (zeros when `add_mean` was off).
    pub mean: Vec<Complex64>,
    /// Sub-paths per realization.
    pub paths_per_realization: u64,
}

/// Most pairs per work item of a field render: a large render is cut into tiles of pairs
/// (see [`crate::connect::Tile`]) so that a work item holds 512 KiB of fields and its
/// per-vertex loops run in the core's cache.
const FIELD_TILE: usize = 1 << 15;

/// Work per item, in units of a pair update per vertex (a leg counts as [`LEG_COST`]).
const ITEM_WORK: u64 = 1 << 22;

/// The cost of one leg (an exponential, a sine and cosine, an amplitude) in pair updates.
const LEG_COST: u64 = 8;

/// Paths per work item: about [`ITEM_WORK`] per vertex over the item, 16 to 1024 paths, and
/// the same for all items of a realization. Depends only on the scene and `n`, never on the
/// number of threads, so results stay bitwise identical for any thread count.
fn paths_per_item(n: u64, tile: &Tile) -> u64 {
    let cost = tile.len() as u64 + LEG_COST * tile.endpoints() as u64;
    let size = (ITEM_WORK / cost.max(1)).clamp(16, 1024);
    // Even batches: ceil(n / size) of them, of (nearly) equal length.
    n.div_ceil(n.div_ceil(size))
}

/// Adds the sub-paths of a realization to its fields: one connector and one field vector per
/// frame (one for a static render; one per time for a sequence, whose `motion` displaces the
/// vertices and carries the per-path time factor of each frame).
struct FieldSink<'c, 's, 'p, 'f, M, P> {
    scene: &'s Scene<M, P>,
    conns: &'c mut [Connector<'s, M, P>],
    u: &'c mut [Cvec],
    motion: Option<&'c mut Trajectory<'f>>,
    coherence: Coherence,
    poll: &'c mut Poll<'p>,
}

#[inline]
fn random_phase(rng: &mut PathRng) -> Complex64 {
    Complex64::from_polar(1.0, TAU * rng.next_f64())
}

impl<M: Medium, P: PhaseFunction> VertexSink for FieldSink<'_, '_, '_, '_, M, P> {
    fn first(&mut self, x1: DVec3, ty: usize, weight: f64, rng: &mut PathRng) {
        // Single scattering: z sqrt(sigma_s / q_o) F, so that E[u u^H] gains (sigma_s / q_o) F F^H
        // as in Alg. 1. (Alg. 2 prints sqrt(V/2) here, which would halve single scattering.)
        let z = random_phase(rng) * weight.sqrt();
        match self.motion.as_deref_mut() {
            None => self.conns[0].add_first(x1, ty, z, &mut self.u[0]),
            Some(m) => {
                m.first(self.scene.medium(), x1);
                for (l, (conn, u)) in self.conns.iter_mut().zip(self.u.iter_mut()).enumerate() {
                    if m.alive(l) {
                        conn.add_first(m.position(l, x1), ty, z, u);
                    }
                }
            }
        }
    }

    fn vertex(&mut self, v: &Vertex, rng: &mut PathRng) {
        let z = random_phase(rng) * v.weight_for(self.coherence).sqrt();
        match self.motion.as_deref_mut() {
            None => {
                let conn = &mut self.conns[0];
                if v.index == 2 {
                    conn.second(v.w12);
                }
                conn.add_vertex(v.x, v.w_in, v.ty, self.coherence, z, &mut self.u[0]);
            }
            Some(m) => {
                m.vertex(self.scene.medium(), v);
                for (l, (conn, u)) in self.conns.iter_mut().zip(self.u.iter_mut()).enumerate() {
                    if !m.alive(l) {
                        continue;
                    }
                    // The scattering amplitudes keep the undisplaced directions.
                    if v.index == 2 {
                        conn.second(v.w12);
                    }
                    let x = m.position(l, v.x);
                    conn.add_vertex(x, v.w_in, v.ty, self.coherence, m.weighted(l, z), u);
                }
            }
        }
    }

    #[inline]
    fn keep_going(&mut self) -> bool {
        !self.poll.cancelled()
    }
}

/// A [`Progress`] that forwards cancellation but counts nothing.
struct Silent<'a>(&'a dyn Progress);

impl Progress for Silent<'_> {
    fn cancelled(&self) -> bool {
        self.0.cancelled()
    }
}

/// Samples `R` realizations of the fields of all pairs of `scene` (Alg. 2): each is
/// `m + sqrt(1/N) sum_n z_n sqrt(w_n) a_n` with an independent uniform phase `z` per vertex, so
/// that `E[(u - m)(u - m)^H]` equals the covariance of [`crate::render_covariance`] exactly, and
/// the fields tend to circular complex Gaussians as `N` grows.
///
/// The work is split into items of (realization, batch of paths, tile of at most 32768 pairs);
/// an item traces its paths and connects them to its tile only (paths are traced once per
/// tile, a small cost next to the connections of so many pairs).
///
/// Memory, beyond the scene: the result, `16 (R + 1) J` bytes (`R x J` fields and the `J`
/// mean, zeros when `add_mean` is off), plus at most `3 x threads` tiles of fields (512 KiB
/// each; in flight or being filled) and one connector per running item (its endpoint arrays,
/// about 250 bytes per endpoint, and a first-vertex amplitude table of 512 KiB per particle
/// type for far-field tiles): `16 (R + 1) J + O(threads)` bytes, about 2 MiB per thread. For
/// 512 x 512 far-field sensors and 8 plane waves (`J = 2^21`) and `R = 2` that is 96 MiB of
/// result and about 5 MiB of work space on 2 threads.
///
/// Deterministic: the same seed gives bitwise the same fields for any number of threads.
pub fn render_fields<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &FieldOptions,
    progress: &dyn Progress,
) -> Result<FieldEstimate, EstimatorError> {
    render(scene, options, progress, FIELD_TILE, None)
}

/// Renders shard `shard` of [`render_fields`]: its range of realizations, each exactly as the
/// single run computes it before the mean is added, and (with `add_mean`) the speckle means of
/// its share of the pairs (`shard.units(J)`), so that the mean is computed once over all shards;
/// [`FieldShard::merge`] of all shards adds it and is bitwise the single run's fields. A
/// realization is the unit: there is nothing to split further when there are more shards than
/// realizations (those shards are empty).
pub fn render_fields_shard<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &FieldOptions,
    shard: Shard,
    progress: &dyn Progress,
) -> Result<FieldShard, EstimatorError> {
    render_rows(
        scene,
        options,
        progress,
        FIELD_TILE,
        None,
        Some(shard),
        None,
    )
}

/// The fields of every frame of `frames` (see [`crate::render_field_sequence`]): realizations
/// of `T J` values, frame after frame, the mean added to every frame.
pub(crate) fn render_frames<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &FieldOptions,
    frames: &Frames,
    progress: &dyn Progress,
) -> Result<FieldEstimate, EstimatorError> {
    render_with(scene, options, progress, FIELD_TILE, None, Some(frames))
}

/// One shard of a field render: its realizations (rows) without the mean, and the mean of its
/// share of the pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldShard {
    /// Its realizations among the run's, `units.len() x J`, before the mean is added.
    pub rows: PartialRows,
    /// Whether the run adds the speckle mean to every realization.
    pub add_mean: bool,
    /// With `add_mean`, the speckle means of the shard's share of the pairs; empty otherwise.
    pub mean: PairShare,
    /// Sub-paths per realization.
    pub paths_per_realization: u64,
}

impl FieldShard {
    /// Merges the shards of one field render (in any order): bitwise the single run's fields.
    /// An error names missing or overlapping shards by index. The means of pairs that no
    /// shard's share covers (shards of different counts) are computed by `mean_of`.
    pub fn merge(
        shards: &[FieldShard],
        mean_of: impl FnMut(Range<usize>) -> Result<Vec<Complex64>, EstimatorError>,
    ) -> Result<FieldEstimate, EstimatorError> {
        let rows: Vec<PartialRows> = shards.iter().map(|s| s.rows.clone()).collect();
        let (mut fields, order) = assemble_rows(&rows, "realizations")?;
        let first = &shards[order[0]];
        if shards.iter().any(|s| {
            s.add_mean != first.add_mean || s.paths_per_realization != first.paths_per_realization
        }) {
            return Err(ShardError::Mismatch(
                "the shards are of field renders with and without the mean, or with different \
                 paths per realization"
                    .into(),
            )
            .into());
        }
        let j = fields.cols();
        let mean = if first.add_mean {
            let shares: Vec<&PairShare> = shards.iter().map(|s| &s.mean).collect();
            let mean = PairShare::assemble(&shares, j, mean_of)?;
            add_to_rows(&mut fields, &mean);
            mean
        } else {
            vec![Complex64::new(0.0, 0.0); j]
        };
        Ok(FieldEstimate {
            fields,
            mean,
            paths_per_realization: first.paths_per_realization,
        })
    }
}

/// Adds `mean` to every row of `fields` (as the single run does, after its paths), or to every
/// frame of `J` values of every row.
fn add_to_rows(fields: &mut CMatrix, mean: &[Complex64]) {
    let j = mean.len();
    for row in fields.as_mut_slice().chunks_exact_mut(j.max(1)) {
        for (f, m) in row.iter_mut().zip(mean) {
            *f += m;
        }
    }
}

/// [`render_fields`] with tiles of at most about `max_tile` pairs and, if given, `batch` paths
/// per work item.
fn render<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &FieldOptions,
    progress: &dyn Progress,
    max_tile: usize,
    batch: Option<u64>,
) -> Result<FieldEstimate, EstimatorError> {
    render_with(scene, options, progress, max_tile, batch, None)
}

/// [`render`] of the frames of `frames` (one static frame when `None`).
fn render_with<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &FieldOptions,
    progress: &dyn Progress,
    max_tile: usize,
    batch: Option<u64>,
    frames: Option<&Frames>,
) -> Result<FieldEstimate, EstimatorError> {
    let s = render_rows(scene, options, progress, max_tile, batch, None, frames)?;
    let mut fields = s.rows.rows;
    let mean = if options.add_mean {
        add_to_rows(&mut fields, &s.mean.values);
        s.mean.values
    } else {
        vec![Complex64::new(0.0, 0.0); scene.len()]
    };
    Ok(FieldEstimate {
        fields,
        mean,
        paths_per_realization: s.paths_per_realization,
    })
}

/// [`render`] of the realizations of `shard` (all of them when `None`), without the mean, and
/// with `add_mean` the means of the shard's share of the pairs (all of them when `None`).
///
/// With `frames`, a row holds `T` frames of `J` fields (a field sequence, unsharded): each work
/// item connects its paths to a tile of at most `max_tile / T` pairs at every time, with the
/// same batches of paths as the static render, so that a frame at time 0 is bitwise the static
/// fields.
#[allow(clippy::too_many_arguments)]
fn render_rows<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &FieldOptions,
    progress: &dyn Progress,
    max_tile: usize,
    batch: Option<u64>,
    shard: Option<Shard>,
    frames: Option<&Frames>,
) -> Result<FieldShard, EstimatorError> {
    // Gaussian beams connect through the covariance's closed forms (Bar et al. 2020, Sec. 7,
    // Eqs. 43-45): the same vMF-lobe amplitudes are needed.
    speckle_endpoints::check_near_field(scene.sources(), scene.sensors(), scene.phases())?;
    if options.realizations == 0 {
        return Err(EstimatorError::InvalidInput {
            field: "realizations".into(),
            reason: "at least one realization is needed".into(),
        });
    }
    let n = options.paths_per_realization;
    if n == 0 {
        return Err(EstimatorError::InvalidInput {
            field: "paths_per_realization".into(),
            reason: "at least one path per realization is needed".into(),
        });
    }
    let tracer = scene.tracer(options.sampling, options.coherence)?;
    let j = scene.len();
    let share = shard.map_or(0..j, |s| s.units(j));
    let mean = PairShare {
        values: if options.add_mean {
            scene
                .means_of(share.clone(), &|| progress.cancelled())?
                .ok_or(EstimatorError::Cancelled)?
        } else {
            Vec::new()
        },
        pairs: if options.add_mean { share } else { 0..0 },
    };
    let nf = frames.map_or(1, Frames::len);
    // The batches of the static render (whose tiles are `max_tile` pairs), whatever the frames.
    let per = Batches::of_size(
        n,
        batch.unwrap_or_else(|| paths_per_item(n, &tiles(scene, max_tile)[0])),
    );
    let tiles = tiles(scene, (max_tile / nf).max(1));
    let nt = tiles.len();
    let whole = Shard::new(0, 1)?;
    let shard = shard.unwrap_or(whole);
    let units = shard.units(options.realizations);
    let per_realization = per.count() * nt;
    let items = units.start * per_realization..units.end * per_realization;
    // Item (r, b, t) = ((r * batches) + b) * tiles + t: a realization's batches of one tile
    // are merged in batch order.
    let split = |item: usize| {
        let (rb, t) = (item / nt, item % nt);
        (rb / per.count(), rb % per.count(), t)
    };
    let work = |item: usize| {
        let (r, b, t) = split(item);
        let mut conns: Vec<_> = (0..nf)
            .map(|_| Connector::for_tile(scene, &tiles[t]))
            .collect();
        let mut u = vec![Cvec::zeros(tiles[t].len()); nf];
        let mut trajectory = frames.map(Frames::trajectory);
        let range = per.range(b);
        // Progress counts a realization's paths once, with its last tile.
        let counted: &dyn Progress = if t + 1 == nt {
            progress
        } else {
            &Silent(progress)
        };
        for_each_path(range, counted, |path, poll| {
            let stream = r as u64 * n + path;
            if let Some(m) = trajectory.as_mut() {
                m.start(stream);
            }
            let mut sink = FieldSink {
                scene,
                conns: &mut conns,
                u: &mut u,
                motion: trajectory.as_mut(),
                coherence: options.coherence,
                poll,
            };
            tracer.trace(&mut PathRng::new(options.seed, stream), &mut sink);
        })?;
        Some(u)
    };
    let mut fields = CMatrix::zeros(units.len(), nf * j);
    let scale = 1.0 / (n as f64).sqrt();
    let bytes = tiles.iter().map(Tile::len).max().unwrap_or(0) * 16 * nf;
    let nv = scene.sensors().len();
    let done = run_ordered_range(items, bytes, work, |item, frames_u| {
        let (r, _, t) = split(item);
        let r = r - units.start;
        let row = &mut fields.as_mut_slice()[r * nf * j..(r + 1) * nf * j];
        for (row, u) in row.chunks_exact_mut(j.max(1)).zip(&frames_u) {
            let add = |dst: &mut [Complex64], from: Range<usize>| {
                for (f, (re, im)) in dst
                    .iter_mut()
                    .zip(u.re[from.clone()].iter().zip(&u.im[from]))
                {
                    *f += Complex64::new(*re, *im) * scale;
                }
            };
            match &tiles[t] {
                Tile::Grid { sources, sensors } => {
                    let w = sensors.len();
                    for (l, s) in sources.clone().enumerate() {
                        let start = s * nv + sensors.start;
                        add(&mut row[start..start + w], l * w..(l + 1) * w);
                    }
                }
                Tile::List { pairs } => add(&mut row[pairs.clone()], 0..pairs.len()),
            }
        }
    });
    if !done {
        return Err(EstimatorError::Cancelled);
    }
    Ok(FieldShard {
        rows: PartialRows {
            shard,
            units,
            total: options.realizations,
            rows: fields,
        },
        add_mean: options.add_mean,
        mean,
        paths_per_realization: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NoProgress, Pair, Sensor, Source};
    use speckle_medium::{Aabb, HomogeneousBox};
    use speckle_phase::Phase;

    /// Two particle types (HG lobes), plane-wave and point sources, far-field and point
    /// sensors in mixed runs: `J = 3 x 7`.
    fn mixed_scene(pairs: Option<Vec<Pair>>) -> Scene<HomogeneousBox, Phase> {
        let b = Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 3.0, 2.0)).unwrap();
        let m = HomogeneousBox::with_types(b, 0.8, 0.1, vec![0.3, 0.7]).unwrap();
        let sources = vec![
            Source::plane_wave(DVec3::Z).unwrap(),
            Source::plane_wave(DVec3::new(0.1, 0.0, 1.0)).unwrap(),
            Source::Point {
                position: DVec3::new(0.5, -0.5, -4.0),
            },
        ];
        let far = |x: f64| Sensor::far_field(DVec3::new(x, 0.05, 1.0)).unwrap();
        let point = |x: f64| Sensor::Point {
            position: DVec3::new(x, 0.0, 5.0),
        };
        let sensors = vec![
            far(0.0),
            far(0.1),
            far(-0.2),
            far(0.3),
            point(0.0),
            point(1.0),
            far(-0.5),
        ];
        Scene::with_types(
            m,
            vec![Phase::hg(0.5).unwrap(), Phase::hg(-0.3).unwrap()],
            0.5,
            sources,
            sensors,
            pairs.unwrap_or_else(|| Pair::all(3, 7)),
        )
        .unwrap()
    }

    fn bits(f: &FieldEstimate) -> Vec<(u64, u64)> {
        let z = f.fields.as_slice();
        z.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
    }

    #[test]
    fn tiles_do_not_change_the_fields() {
        // One tile, or 8 grid tiles (2 source blocks x 4 sensor blocks) / 6 list tiles, with
        // the same batches: bitwise the same fields, both coherence modes.
        let reversed: Vec<Pair> = Pair::all(3, 7).into_iter().rev().skip(3).collect();
        for coherence in [Coherence::ForwardAndReversed, Coherence::ForwardOnly] {
            let opts = FieldOptions {
                realizations: 3,
                paths_per_realization: 300,
                seed: 4,
                coherence,
                add_mean: false,
                ..Default::default()
            };
            let grid = mixed_scene(None);
            let one = render(&grid, &opts, &NoProgress, 1 << 15, Some(70)).unwrap();
            let many = render(&grid, &opts, &NoProgress, 4, Some(70)).unwrap();
            assert_eq!(tiles(&grid, 4).len(), 8);
            assert_eq!(bits(&one), bits(&many), "{coherence:?} grid");
            let list = mixed_scene(Some(reversed.clone()));
            let one_l = render(&list, &opts, &NoProgress, 1 << 15, Some(70)).unwrap();
            let many_l = render(&list, &opts, &NoProgress, 3, Some(70)).unwrap();
            assert_eq!(tiles(&list, 3).len(), 6);
            assert_eq!(bits(&one_l), bits(&many_l), "{coherence:?} list");
            // The listed pairs are the grid's entries in another order (up to rounding: the
            // list loop multiplies in another order).
            for r in 0..3 {
                for (jl, p) in reversed.iter().enumerate() {
                    let a = one_l.fields.get(r, jl);
                    let b = one.fields.get(r, p.source * 7 + p.sensor);
                    assert!((a - b).norm() <= 1e-13 * b.norm(), "{a} {b}");
                }
            }
        }
    }

    /// Peak resident memory of this process in bytes (`VmHWM`), where Linux reports it.
    fn peak_rss() -> Option<u64> {
        let s = std::fs::read_to_string("/proc/self/status").ok()?;
        let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib * 1024)
    }

    /// A 512 x 512 far-field image for 8 plane-wave tilts (`J = 2^21`), 2 realizations of 64
    /// paths: prints the peak RSS and the run time. Run with
    /// `cargo test --release -p speckle-estimators --lib -- --ignored --nocapture field_memory`.
    #[test]
    #[ignore = "memory measurement of a large render (a few seconds, about 100 MiB)"]
    fn field_memory_512x512x8() {
        let slab = Aabb::centered(DVec3::ZERO, DVec3::new(40.0, 40.0, 10.0)).unwrap();
        let medium = HomogeneousBox::from_mean_free_path(slab, 10.0, 0.95).unwrap();
        let sources: Vec<Source> = (0..8)
            .map(|m| {
                let t = (0.5 * f64::from(m)).to_radians();
                Source::plane_wave(DVec3::new(t.sin(), 0.0, t.cos())).unwrap()
            })
            .collect();
        let n = 512;
        let tan = |i: usize| (-8.0 + 16.0 * i as f64 / (n - 1) as f64).to_radians().tan();
        let sensors: Vec<Sensor> = (0..n * n)
            .map(|i| Sensor::far_field(DVec3::new(tan(i % n), tan(i / n), 1.0)).unwrap())
            .collect();
        let scene = Scene::new(
            medium,
            Phase::hg(0.7).unwrap(),
            1.0,
            sources,
            sensors,
            Pair::all(8, n * n),
        )
        .unwrap();
        let before = peak_rss();
        let opts = FieldOptions {
            realizations: 2,
            paths_per_realization: 64,
            seed: 1,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let f = render_fields(&scene, &opts, &NoProgress).unwrap();
        let wall = t.elapsed().as_secs_f64();
        let after = peak_rss();
        let mib = |b: u64| b as f64 / (1 << 20) as f64;
        let output = ((f.fields.as_slice().len() + f.mean.len()) * 16) as u64;
        assert!(f.fields.as_slice().iter().all(|z| z.is_finite()));
        let (Some(before), Some(after)) = (before, after) else {
            eprintln!("no VmHWM in /proc/self/status: peak memory not measured ({wall:.2} s)");
            return;
        };
        let work = after.saturating_sub(before + output);
        eprintln!(
            "fields J = {} x R = 2, N = 64, {} threads: {wall:.2} s, peak RSS {:.0} MiB: {:.0} \
             MiB before the render, {:.0} MiB of result (R x J fields and J mean), {:.1} MiB \
             beyond it",
            scene.len(),
            rayon::current_num_threads(),
            mib(after),
            mib(before),
            mib(output),
            mib(work),
        );
        // The bound of `render_fields`, about 2 MiB per thread beyond the result, with room
        // for the allocator and the thread stacks.
        let bound = (8 + 4 * rayon::current_num_threads() as u64) << 20;
        assert!(work < bound, "{} MiB beyond the result", mib(work));
    }
}
