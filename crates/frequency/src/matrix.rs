//! Small dense matrices on plain arrays: products, transposes, inverses by Gauss-Jordan
//! elimination with partial pivoting, and the absolute value of a symmetric 2 x 2 matrix.

/// A dense row-major `N x N` matrix.
pub type Mat<const N: usize> = [[f64; N]; N];

/// The identity.
pub fn identity<const N: usize>() -> Mat<N> {
    let mut m = [[0.0; N]; N];
    for (i, row) in m.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    m
}

/// `a b`.
pub fn mul<const N: usize>(a: &Mat<N>, b: &Mat<N>) -> Mat<N> {
    let mut c = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            c[i][j] = (0..N).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// `a^T`.
pub fn transpose<const N: usize>(a: &Mat<N>) -> Mat<N> {
    let mut t = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            t[j][i] = a[i][j];
        }
    }
    t
}

/// `a^T s a`.
pub fn congruence<const N: usize>(a: &Mat<N>, s: &Mat<N>) -> Mat<N> {
    mul(&transpose(a), &mul(s, a))
}

/// The inverse, or `None` when a pivot is below `1e-300` or not finite (singular).
pub fn inverse<const N: usize>(a: &Mat<N>) -> Option<Mat<N>> {
    let mut m = *a;
    let mut inv = identity::<N>();
    for col in 0..N {
        let pivot = (col..N).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        let p = m[pivot][col];
        if !(p.abs() > 1e-300 && p.is_finite()) {
            return None;
        }
        m.swap(col, pivot);
        inv.swap(col, pivot);
        for k in 0..N {
            m[col][k] /= p;
            inv[col][k] /= p;
        }
        for row in 0..N {
            if row != col {
                let f = m[row][col];
                if f != 0.0 {
                    for k in 0..N {
                        m[row][k] -= f * m[col][k];
                        inv[row][k] -= f * inv[col][k];
                    }
                }
            }
        }
    }
    Some(inv)
}

/// The determinant (Gaussian elimination with partial pivoting).
pub fn determinant<const N: usize>(a: &Mat<N>) -> f64 {
    let mut m = *a;
    let mut det = 1.0;
    for col in 0..N {
        let pivot = (col..N)
            .max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))
            .expect("a column");
        if m[pivot][col] == 0.0 {
            return 0.0;
        }
        if pivot != col {
            m.swap(col, pivot);
            det = -det;
        }
        det *= m[col][col];
        for row in col + 1..N {
            let f = m[row][col] / m[col][col];
            for k in col..N {
                m[row][k] -= f * m[col][k];
            }
        }
    }
    det
}

/// `|h|` of a symmetric 2 x 2 matrix: `R^T |D| R` for `h = R^T D R` (its eigenvalues made
/// non-negative, the eigenvectors kept).
pub fn abs_symmetric(h: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
    let (a, b, d) = (h[0][0], 0.5 * (h[0][1] + h[1][0]), h[1][1]);
    let mean = 0.5 * (a + d);
    let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (l1, l2) = (mean + r, mean - r);
    if r == 0.0 {
        return [[l1.abs(), 0.0], [0.0, l2.abs()]];
    }
    // Unit eigenvector of l1: (l1 - d, b) or (b, l1 - a), whichever is longer (better
    // conditioned).
    let (x, y) = if (l1 - d).hypot(b) >= (l1 - a).hypot(b) {
        (l1 - d, b)
    } else {
        (b, l1 - a)
    };
    let n = x.hypot(y);
    let (c, s) = (x / n, y / n);
    let (p1, p2) = (l1.abs(), l2.abs());
    // p1 e1 e1^T + p2 e2 e2^T, e1 = (c, s), e2 = (-s, c).
    [
        [p1 * c * c + p2 * s * s, (p1 - p2) * c * s],
        [(p1 - p2) * c * s, p1 * s * s + p2 * c * c],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_of_a_product_and_singular_refused() {
        let a = [
            [2.0, 1.0, 0.0, 0.5],
            [1.0, 3.0, 0.2, 0.0],
            [0.0, 0.2, 1.0, 0.1],
            [0.5, 0.0, 0.1, 4.0],
        ];
        let i = mul(&a, &inverse(&a).unwrap());
        for (r, row) in i.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                assert!((v - if r == c { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
        }
        let mut s = a;
        s[3] = s[2];
        assert!(inverse(&s).is_none());
    }

    #[test]
    fn absolute_value_keeps_eigenvectors() {
        // Eigenvalues 3 and -1 along (1, 1) / sqrt 2 and (1, -1) / sqrt 2.
        let h = [[1.0, 2.0], [2.0, 1.0]];
        let a = abs_symmetric(h);
        // |h| has eigenvalues 3 and 1 on the same vectors: [[2, 1], [1, 2]].
        for (got, want) in a.iter().flatten().zip([2.0, 1.0, 1.0, 2.0]) {
            assert!((got - want).abs() < 1e-14, "{a:?}");
        }
        assert_eq!(
            abs_symmetric([[-2.0, 0.0], [0.0, 5.0]]),
            [[2.0, 0.0], [0.0, 5.0]]
        );
    }
}
