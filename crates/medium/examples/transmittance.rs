//! Sampled free flights against the closed-form transmittance of a slab, and a voxel grid's
//! exact optical depth.
//!
//! `cargo run -p speckle-medium --example transmittance`

use speckle_medium::{Aabb, DVec3, HomogeneousBox, Material, Medium, VoxelGrid};

fn main() {
    // A slab 1 unit thick of extinction 2.5: the unscattered transmittance is exp(-2.5).
    let slab = Aabb::new(DVec3::new(-5.0, -5.0, 0.0), DVec3::new(5.0, 5.0, 1.0)).unwrap();
    let m = HomogeneousBox::new(slab, 2.0, 0.5).unwrap();
    let n = 200_000;
    let mut u = 0.0f64;
    let mut uniform = || {
        // A low-discrepancy sequence: any source of uniforms in [0, 1) drives the medium.
        u = (u + 0.618_033_988_749_894_9) % 1.0;
        u
    };
    let escaped = (0..n)
        .filter(|_| {
            m.sample_flight(DVec3::ZERO, DVec3::Z, &mut uniform)
                .is_none()
        })
        .count();
    println!(
        "slab: transmitted {:.5} of {n} flights, exp(-2.5) = {:.5}; optical depth across {}",
        escaped as f64 / n as f64,
        (-2.5f64).exp(),
        m.optical_depth(DVec3::ZERO, DVec3::Z)
    );
    // Two voxels of different materials along x: the optical depth adds their parts.
    let b = Aabb::new(DVec3::ZERO, DVec3::new(2.0, 1.0, 1.0)).unwrap();
    let mats = vec![Material::single(1.0, 0.0), Material::single(3.0, 0.0)];
    let g = VoxelGrid::from_materials(b, [2, 1, 1], vec![0, 1], mats).unwrap();
    let od = g.optical_depth(DVec3::new(0.5, 0.5, 0.5), DVec3::new(1.5, 0.5, 0.5));
    println!("grid: optical depth across two voxels {od} (0.5 x 1 + 0.5 x 3 = 2)");
}
