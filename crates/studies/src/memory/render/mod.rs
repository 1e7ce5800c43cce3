//! The bands (Mie spheres and slab coefficients per wavelength), the render of each band in
//! independent groups, and the result as plain data.

mod band;
mod groups;
mod output;
mod scene;
mod study;
#[cfg(test)]
mod tests;

pub use band::{Band, DENSE_VOLUME_FRACTION, MAX_OPTICAL_DEPTH, MILNE_ZE, eq39};
pub use groups::Curve;
pub(crate) use groups::render_groups;
pub use output::{Array, LAYOUT, MemorySpectrum, Wavelength, check_finite};
pub(crate) use scene::{slab_tracer, slab_tracer_json, tilt_scene};
