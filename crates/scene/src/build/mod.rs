//! The builders: from the parts of a [`crate::schema::SceneFile`] to the library's values,
//! validating every value once and naming the offending field on error.
//!
//! - [`medium`]: coefficients (`sigma_s`/`sigma_a` or mean free path and albedo), the host
//!   index, Mie particle types, voxel grids of densities or of materials;
//! - [`phase`]: phase functions, with the CSV amplitude-table reader (and its writer) and the
//!   tables embedded in the binary (`embedded:NAME`);
//! - [`endpoints`]: sources and the sensor generators (`plane_tilts`, `far_grid`, `far_arc`,
//!   `point_grid`), expanded in order;
//! - [`motion`]: moving scatterers (one motion, or one per material) and time lags;
//! - [`render`]: render and output settings (path counts, seed, coherence, sampling strategies,
//!   realizations, configurations, PNGs).
//!
//! Each builder is usable alone, so that a front end that does not read TOML (a binding) builds
//! the same values with the same checks.

pub mod endpoints;
pub mod fit;
pub mod medium;
pub mod motion;
pub mod phase;
pub mod render;

/// At most this many sensors (or sources) after expanding grids and generators.
pub const MAX_ENDPOINTS: usize = 1 << 20;
