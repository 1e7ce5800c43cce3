//! The stand-alone tools of the phase-function builders (`speckle mie`, `speckle fit-phase`):
//! they compute what a scene's `[[medium.particles]]` or `[phase]` would, report it, and write it
//! in the forms a scene reads back (a CSV amplitude table, a `[phase]` TOML table).
//!
//! Errors name the option by its field name (`radius`, `host_index`, `index/index_imag`: one of
//! these); a front end maps those names to its own (`--radius`, `--host-index`).

pub mod fit;
pub mod mie;
