//! Axis-aligned boxes and ray/segment clipping against them.

use crate::MediumError;
use glam::{DVec2, DVec3};
use speckle_phase::Dimension;

/// An axis-aligned box `[min, max]`; a slab is a laterally wide box. A flatland box
/// ([`Aabb::flat`]) is a rectangle in the plane `z = 0`: its `z` extent is zero.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    min: DVec3,
    max: DVec3,
}

impl Aabb {
    /// A box from its two corners; every component of `max - min` must be finite and positive.
    pub fn new(min: DVec3, max: DVec3) -> Result<Self, MediumError> {
        if !min.is_finite() || !max.is_finite() {
            return Err(MediumError::InvalidBox {
                field: "corners",
                reason: format!("corners must be finite (min {min}, max {max})"),
            });
        }
        let size = max - min;
        if size.min_element() <= 0.0 {
            return Err(MediumError::InvalidBox {
                field: "size",
                reason: format!("every extent must be > 0 (got {size})"),
            });
        }
        Ok(Self { min, max })
    }

    /// A flatland rectangle `[min, max]` in the plane `z = 0`; both extents must be finite and
    /// positive.
    ///
    /// ```
    /// use speckle_medium::{Aabb, DVec3};
    /// use glam::DVec2;
    /// let r = Aabb::flat(DVec2::new(-50.0, -50.0), DVec2::new(50.0, 50.0)).unwrap();
    /// assert_eq!(r.measure(), 1e4);
    /// assert!(r.contains(DVec3::new(1.0, 2.0, 0.0)) && !r.contains(DVec3::new(1.0, 2.0, 0.1)));
    /// ```
    pub fn flat(min: DVec2, max: DVec2) -> Result<Self, MediumError> {
        // Validate the rectangle as a unit-thick box, then flatten it.
        let b = Self::new(min.extend(0.0), max.extend(1.0))?;
        Ok(Self {
            min: b.min,
            max: b.max.with_z(0.0),
        })
    }

    /// Flatland (zero `z` extent) or 3D.
    pub fn dimension(&self) -> Dimension {
        if self.max.z == self.min.z {
            Dimension::Two
        } else {
            Dimension::Three
        }
    }

    /// The volume of a 3D box, the area of a flatland rectangle.
    pub fn measure(&self) -> f64 {
        let s = self.size();
        match self.dimension() {
            Dimension::Three => s.x * s.y * s.z,
            Dimension::Two => s.x * s.y,
        }
    }

    /// A box of the given size centred on `center`.
    pub fn centered(center: DVec3, size: DVec3) -> Result<Self, MediumError> {
        if !size.is_finite() || size.min_element() <= 0.0 {
            return Err(MediumError::InvalidBox {
                field: "size",
                reason: format!("every extent must be finite and > 0 (got {size})"),
            });
        }
        Self::new(center - 0.5 * size, center + 0.5 * size)
    }

    /// Lower corner.
    pub fn min(&self) -> DVec3 {
        self.min
    }

    /// Upper corner.
    pub fn max(&self) -> DVec3 {
        self.max
    }

    /// Edge lengths.
    pub fn size(&self) -> DVec3 {
        self.max - self.min
    }

    /// Volume (zero for a flatland rectangle; see [`Aabb::measure`]).
    pub fn volume(&self) -> f64 {
        let s = self.size();
        s.x * s.y * s.z
    }

    /// Whether `x` lies in the closed box.
    pub fn contains(&self, x: DVec3) -> bool {
        x.cmpge(self.min).all() && x.cmple(self.max).all()
    }

    /// The parameter interval `[t0, t1]` (clipped to `[lo, hi]`) over which `o + t d` lies in the
    /// box, or `None` if it misses. Slab method; zero direction components are handled exactly.
    pub fn clip(&self, o: DVec3, d: DVec3, lo: f64, hi: f64) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (lo, hi);
        for a in 0..3 {
            let (oa, da, mn, mx) = (o[a], d[a], self.min[a], self.max[a]);
            if da == 0.0 {
                if oa < mn || oa > mx {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / da;
            let (mut ta, mut tb) = ((mn - oa) * inv, (mx - oa) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 > t1 {
                return None;
            }
        }
        Some((t0, t1))
    }

    /// Length of the part of the segment `a -> b` inside the box.
    pub fn segment_length_inside(&self, a: DVec3, b: DVec3) -> f64 {
        let d = b - a;
        match self.clip(a, d, 0.0, 1.0) {
            Some((t0, t1)) => (t1 - t0) * d.length(),
            None => 0.0,
        }
    }

    /// Length of the part of the ray `x + t dir`, `t >= 0`, inside the box (`dir` a unit vector).
    pub fn ray_length_inside(&self, x: DVec3, dir: DVec3) -> f64 {
        match self.clip(x, dir, 0.0, f64::INFINITY) {
            Some((t0, t1)) => t1 - t0,
            None => 0.0,
        }
    }

    /// Distance from a point inside the box to its boundary along the unit direction `dir`.
    pub fn exit_distance(&self, x: DVec3, dir: DVec3) -> f64 {
        let mut t = f64::INFINITY;
        for a in 0..3 {
            if dir[a] > 0.0 {
                t = t.min((self.max[a] - x[a]) / dir[a]);
            } else if dir[a] < 0.0 {
                t = t.min((self.min[a] - x[a]) / dir[a]);
            }
        }
        t.max(0.0)
    }

    /// The outward normal of the face through which the ray from `x` (inside the box) along
    /// the unit direction `dir` leaves it: the face of [`Aabb::exit_distance`].
    pub fn exit_normal(&self, x: DVec3, dir: DVec3) -> DVec3 {
        let (mut t, mut normal) = (f64::INFINITY, DVec3::ZERO);
        for a in 0..3 {
            let (ta, side) = if dir[a] > 0.0 {
                ((self.max[a] - x[a]) / dir[a], 1.0)
            } else if dir[a] < 0.0 {
                ((self.min[a] - x[a]) / dir[a], -1.0)
            } else {
                continue;
            };
            if ta < t {
                t = ta;
                normal = DVec3::ZERO;
                normal[a] = side;
            }
        }
        normal
    }

    /// The outward normal of the face through which the ray from `o` (outside the box) along
    /// `dir` enters it (the face of the entry distance of [`Aabb::clip`]).
    pub fn entry_normal(&self, o: DVec3, dir: DVec3) -> DVec3 {
        let (mut t, mut normal) = (f64::NEG_INFINITY, DVec3::ZERO);
        for a in 0..3 {
            let (ta, side) = if dir[a] > 0.0 {
                ((self.min[a] - o[a]) / dir[a], -1.0)
            } else if dir[a] < 0.0 {
                ((self.max[a] - o[a]) / dir[a], 1.0)
            } else {
                continue;
            };
            if ta > t {
                t = ta;
                normal = DVec3::ZERO;
                normal[a] = side;
            }
        }
        normal
    }

    /// The point with coordinates `u` in `[0, 1)^3` relative to the box.
    pub fn lerp(&self, u: [f64; 3]) -> DVec3 {
        self.min + DVec3::from_array(u) * self.size()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn unit() -> Aabb {
        Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap()
    }

    #[test]
    fn rejects_degenerate_boxes() {
        assert!(Aabb::new(DVec3::ZERO, DVec3::new(1.0, 0.0, 1.0)).is_err());
        assert!(Aabb::new(DVec3::ZERO, DVec3::new(1.0, f64::NAN, 1.0)).is_err());
        assert!(Aabb::centered(DVec3::ZERO, DVec3::new(-1.0, 1.0, 1.0)).is_err());
    }

    #[test]
    fn segment_and_ray_lengths() {
        let b = unit();
        let a = DVec3::new(-1.0, 0.5, 0.5);
        let c = DVec3::new(2.0, 0.5, 0.5);
        assert_relative_eq!(b.segment_length_inside(a, c), 1.0, epsilon = 1e-15);
        assert_relative_eq!(b.segment_length_inside(a, DVec3::new(0.25, 0.5, 0.5)), 0.25);
        assert_eq!(b.segment_length_inside(a, DVec3::new(-0.5, 0.5, 0.5)), 0.0);
        let x = DVec3::new(0.5, 0.5, 0.5);
        let d = DVec3::new(1.0, 1.0, 0.0).normalize();
        assert_relative_eq!(
            b.ray_length_inside(x, d),
            0.5 * 2f64.sqrt(),
            epsilon = 1e-15
        );
        assert_relative_eq!(b.exit_distance(x, d), 0.5 * 2f64.sqrt(), epsilon = 1e-15);
        assert_relative_eq!(b.exit_distance(x, DVec3::Z), 0.5);
        // A ray along a face plane that starts outside misses.
        assert_eq!(
            b.ray_length_inside(DVec3::new(0.5, 2.0, 0.5), DVec3::X),
            0.0
        );
    }

    proptest::proptest! {
        #[test]
        fn exit_distance_agrees_with_clipping(
            u in proptest::array::uniform3(0.0f64..1.0),
            th in 0.0f64..std::f64::consts::PI,
            ph in 0.0f64..std::f64::consts::TAU,
        ) {
            let b = Aabb::new(DVec3::new(-1.0, -2.0, 0.0), DVec3::new(3.0, 1.0, 0.5)).unwrap();
            let x = b.lerp(u);
            let d = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            let e = b.exit_distance(x, d);
            proptest::prop_assert!((e - b.ray_length_inside(x, d)).abs() < 1e-9);
            proptest::prop_assert!(b.contains(x + (e * (1.0 - 1e-9)) * d));
        }
    }
}
