//! Quadrature shared by the tests that integrate over apertures (`nearfield_reflection`; the
//! brute-force comparison's is the same function, in `speckle::studies::nearfield`).

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on the three-term recurrence).
pub use speckle::studies::nearfield::gauss_legendre;
