//! A rough estimate of what a wave render will cost, to tell a user before it starts.

use crate::{WaveError, WaveScene, expected_scatterers};
use speckle_medium::{Dimension, Medium};
use speckle_scene::cost::Estimate;

/// Rough single-thread speeds of the solver (measured on a 2-core x86-64 machine with AVX-512;
/// the assembly dominates up to `N` of a few thousand): real flops per second of the dense
/// complex LU, and seconds per entry of the Foldy-Lax matrix in 3D (`e^{ikr} / r`) and in
/// flatland (a Hankel function).
const LU_FLOPS: f64 = 5e10;
const GREEN_S_3D: f64 = 1.2e-7;
const GREEN_S_2D: f64 = 2e-7;

/// The estimated cost of a wave render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveCost {
    /// Expected scatterers per configuration, `N = sigma_s |V| / c_s`.
    pub scatterers: f64,
    /// Configurations solved at once (one per thread, at most the number of configurations).
    pub in_flight: f64,
    /// Bytes of the Foldy-Lax matrices being solved at once.
    pub matrix_bytes: f64,
    /// Bytes of the results: the fields, their centred copy and the covariance.
    pub result_bytes: f64,
    /// Wall time, seconds (rough: from the speeds of one machine).
    pub seconds: f64,
}

impl WaveCost {
    /// As a [`speckle_scene::cost::Estimate`], with `staged` bytes of output files added: the
    /// memory is named after `medium` (the number of scatterers) when the matrices dominate, after
    /// `render.configurations` otherwise; the time after `medium`, whose size and density set
    /// `N^3`, unless the configurations are many.
    pub fn estimate(&self, staged: f64) -> Estimate {
        let matrices = self.matrix_bytes > self.result_bytes + staged;
        Estimate {
            bytes: self.matrix_bytes + self.result_bytes + staged,
            memory_field: if matrices {
                "medium"
            } else {
                "render.configurations"
            }
            .into(),
            seconds: self.seconds,
            time_field: "medium".into(),
            vertices_per_path: 0.0,
        }
    }
}

/// The cost of `configurations` configurations of `scene` on `threads` threads: per
/// configuration `N^2 / 2` Green's functions, `(8/3) N^3` flops of LU and `8 N^2` per source.
/// Errors as [`expected_scatterers`].
pub fn estimate_cost(
    scene: &WaveScene,
    configurations: usize,
    threads: usize,
) -> Result<WaveCost, WaveError> {
    let n = expected_scatterers(scene)?;
    let (rr, j) = (configurations as f64, scene.len() as f64);
    let green = match scene.medium().dimension() {
        Dimension::Three => GREEN_S_3D,
        Dimension::Two => GREEN_S_2D,
    };
    let sources = scene.sources().len() as f64;
    let per = 0.5 * n * n * green + (8.0 / 3.0 * n.powi(3) + 8.0 * n * n * sources) / LU_FLOPS;
    let in_flight = (threads as f64).min(rr);
    Ok(WaveCost {
        scatterers: n,
        in_flight,
        matrix_bytes: in_flight * 16.0 * n * n,
        result_bytes: 16.0 * (2.0 * rr * j + 3.0 * j * j),
        seconds: per * rr / in_flight,
    })
}
