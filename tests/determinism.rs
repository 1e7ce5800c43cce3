//! Determinism: the same seed gives bitwise the same numbers for 1, 2 and 7 threads, for the
//! covariance render (total, single and multiple parts, values and standard errors), the
//! single-scattering render and the field render (fields and mean); a different seed gives
//! different numbers.
//!
//! Path counts are chosen so that the work split is uneven: 10 007 covariance paths are 126
//! batches of 79 and one of 53 (not a multiple of the 128-batch target), and 5 003 paths per
//! field realization are one work item of 4 096 and one of 907, so a realization is summed from
//! items that may run on different threads.
//!
//! Run time (release, 2 cores): about 1 s.

use num_complex::Complex64;
use speckle::estimators::{
    CMatrix, Coherence, CovarianceEstimate, CovarianceOptions, FieldEstimate, FieldOptions,
    MatrixEstimate, NoProgress, Pair, Scene, Sensor, Source, render_covariance, render_fields,
    render_single_scattering,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle::phase::Phase;

/// A slab with HG scattering and absorption, a plane wave and a point source, a far-field
/// sensor in transmission, one in reflection and a point sensor: `J = 6` pairs with all four
/// endpoint combinations; first directions from the phase function (a non-default sampler).
fn scene() -> Scene<HomogeneousBox, Phase> {
    let slab = Aabb::centered(DVec3::new(0.1, -0.2, 0.0), DVec3::new(6.0, 5.0, 2.0)).unwrap();
    let medium = HomogeneousBox::from_mean_free_path(slab, 0.8, 0.95).unwrap();
    Scene::new(
        medium,
        Phase::hg(0.6).unwrap(),
        0.3,
        vec![
            Source::plane_wave(DVec3::new(0.1, 0.05, 1.0)).unwrap(),
            Source::Point {
                position: DVec3::new(-1.0, 0.5, -2.5),
            },
        ],
        vec![
            Sensor::far_field(DVec3::new(0.2, 0.0, 1.0)).unwrap(),
            Sensor::far_field(DVec3::new(-0.3, 0.1, -1.0)).unwrap(),
            Sensor::Point {
                position: DVec3::new(0.5, 0.0, 3.0),
            },
        ],
        Pair::all(2, 3),
    )
    .unwrap()
}

/// The sampling of every render here: first directions from the phase function about +z.
const SAMPLING: TracerConfig = TracerConfig {
    first_vertex: FirstVertex::Uniform,
    first_direction: FirstDirection::Phase { axis: DVec3::Z },
    beams: speckle::paths::BeamStrategy::PositionAndDirection,
    max_vertices: u32::MAX,
};

/// Covariance paths: not a multiple of the 128 batches.
const PATHS: u64 = 10_007;

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

fn covariance(
    s: &Scene<HomogeneousBox, Phase>,
    seed: u64,
    coherence: Coherence,
) -> CovarianceEstimate {
    let opts = CovarianceOptions {
        paths: PATHS,
        seed,
        coherence,
        sampling: SAMPLING,
    };
    render_covariance(s, &opts, &NoProgress).unwrap()
}

fn single(s: &Scene<HomogeneousBox, Phase>, seed: u64) -> MatrixEstimate {
    let opts = CovarianceOptions {
        paths: PATHS,
        seed,
        coherence: Coherence::ForwardAndReversed,
        sampling: SAMPLING,
    };
    render_single_scattering(s, &opts, &NoProgress).unwrap()
}

fn fields(s: &Scene<HomogeneousBox, Phase>, seed: u64) -> FieldEstimate {
    let opts = FieldOptions {
        realizations: 7,
        paths_per_realization: 5_003,
        seed,
        coherence: Coherence::ForwardAndReversed,
        add_mean: true,
        sampling: SAMPLING,
    };
    render_fields(s, &opts, &NoProgress).unwrap()
}

fn bits(z: &[Complex64]) -> Vec<(u64, u64)> {
    z.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
}

fn matrix_bits(m: &MatrixEstimate) -> Vec<(u64, u64)> {
    let mut b = bits(m.value.as_slice());
    b.extend(bits(m.std_error.as_slice()));
    b
}

fn covariance_bits(c: &CovarianceEstimate) -> Vec<(u64, u64)> {
    let mut b = matrix_bits(&c.total);
    b.extend(matrix_bits(&c.single));
    b.extend(matrix_bits(&c.multiple));
    b
}

fn field_bits(f: &FieldEstimate) -> Vec<(u64, u64)> {
    let mut b = bits(f.fields.as_slice());
    b.extend(bits(&f.mean));
    b
}

/// Every entry of `a` differs from the corresponding entry of `b` (a different seed must change
/// every estimate, not just some).
fn all_differ(a: &CMatrix, b: &CMatrix) -> bool {
    a.as_slice()
        .iter()
        .zip(b.as_slice())
        .all(|(x, y)| x.re != y.re)
}

/// The covariance render (both coherence modes) with 1, 2 and 7 threads: bitwise equal values
/// and standard errors of the total, single and multiple parts. Also checks that the render is
/// not trivially constant: seed 2 changes the real part of every entry of every part.
#[test]
fn covariance_is_bitwise_identical_for_any_thread_count() {
    let s = scene();
    for coherence in [Coherence::ForwardAndReversed, Coherence::ForwardOnly] {
        let reference = in_pool(1, || covariance(&s, 1, coherence));
        assert_eq!(reference.paths, PATHS);
        for threads in [2, 7] {
            let other = in_pool(threads, || covariance(&s, 1, coherence));
            assert_eq!(
                covariance_bits(&reference),
                covariance_bits(&other),
                "{coherence:?}: {threads} threads differ from 1 thread"
            );
        }
        let reseeded = in_pool(2, || covariance(&s, 2, coherence));
        for (name, a, b) in [
            ("total", &reference.total, &reseeded.total),
            ("single", &reference.single, &reseeded.single),
            ("multiple", &reference.multiple, &reseeded.multiple),
        ] {
            assert!(
                all_differ(&a.value, &b.value),
                "{coherence:?} {name}: seed 2 left an entry unchanged"
            );
        }
        eprintln!(
            "{coherence:?}: C[0,0] = {:.6e} (seed 1, 1/2/7 threads, bitwise equal), {:.6e} (seed 2)",
            reference.total.value.get(0, 0).re,
            reseeded.total.value.get(0, 0).re
        );
    }
}

/// The single-scattering render with 1, 2 and 7 threads: bitwise equal; seed 2 differs.
#[test]
fn single_scattering_is_bitwise_identical_for_any_thread_count() {
    let s = scene();
    let reference = in_pool(1, || single(&s, 1));
    for threads in [2, 7] {
        let other = in_pool(threads, || single(&s, 1));
        assert_eq!(
            matrix_bits(&reference),
            matrix_bits(&other),
            "{threads} threads"
        );
    }
    let reseeded = in_pool(7, || single(&s, 2));
    assert!(all_differ(&reference.value, &reseeded.value));
    eprintln!(
        "single scattering: C[0,0] = {:.6e} (seed 1), {:.6e} (seed 2)",
        reference.value.get(0, 0).re,
        reseeded.value.get(0, 0).re
    );
}

/// The field render (with the mean added) with 1, 2 and 7 threads: bitwise equal fields and
/// mean; seed 2 changes every field value (the mean, which does not depend on the seed, stays).
#[test]
fn fields_are_bitwise_identical_for_any_thread_count() {
    let s = scene();
    let reference = in_pool(1, || fields(&s, 1));
    for threads in [2, 7] {
        let other = in_pool(threads, || fields(&s, 1));
        assert_eq!(
            field_bits(&reference),
            field_bits(&other),
            "{threads} threads"
        );
    }
    let reseeded = in_pool(2, || fields(&s, 2));
    assert!(all_differ(&reference.fields, &reseeded.fields));
    assert_eq!(bits(&reference.mean), bits(&reseeded.mean));
    eprintln!(
        "fields: u[0,0] = {:.6e} (seed 1), {:.6e} (seed 2)",
        reference.fields.get(0, 0),
        reseeded.fields.get(0, 0)
    );
}
