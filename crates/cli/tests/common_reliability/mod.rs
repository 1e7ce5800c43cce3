//! What `reliability.rs` and `input_guards.rs` share: the tiny scene their cases start from.

/// A tiny scene: 2 plane waves, 6 far-field sensors (J = 12), PNGs.
pub const TINY: &str = r#"
name = "tiny"
wavelength = 1.0
[medium]
size = [8.0, 8.0, 3.0]
mean_free_path = 4.0
[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 3.0]
[[sensors]]
type = "far_grid"
theta_x_deg = [-5.0, 5.0]
theta_y_deg = [-2.0, 2.0]
nx = 3
ny = 2
[render]
paths = 2000
[output]
dir = "res"
"#;
