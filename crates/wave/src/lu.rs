//! A blocked LU factorisation with partial pivoting that can be cancelled between its steps,
//! and the solve with it.
//!
//! faer's LU is one call: at `N = 19 000` it runs for minutes and cannot be interrupted. This is
//! the right-looking blocked algorithm (LAPACK's `getrf`) built from faer's kernels: for each
//! panel of `PANEL` (128) columns, faer's recursive LU of the tall panel, its row interchanges
//! applied to the other columns, the triangular solve for the panel's block row of `U`, and the
//! update of the trailing matrix by GEMM in chunks of `CHUNK` (512) columns. The cancellation test
//! runs before every panel and every chunk, a few hundred milliseconds of work apart at the
//! largest sizes. The flops are those of any LU, `(8/3) N^3` real, almost all in the GEMMs.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::factor;
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_unit_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::reborrow::{IntoConst, ReborrowMut};
use faer::{Accum, Mat, MatMut, Par};
use num_complex::Complex64;

/// Columns of a panel.
const PANEL: usize = 128;

/// Columns of the trailing matrix updated between two cancellation tests.
const CHUNK: usize = 512;

/// Factorises `a` in place (`P a = L U`, `L` unit lower and `U` upper in `a`) and returns the row
/// interchanges (`swaps[j]`: row `j` was exchanged with row `swaps[j] >= j`, in order), or
/// `None` once `cancelled()` says so (then `a` is garbage).
pub fn factorise(a: &mut Mat<Complex64>, cancelled: &dyn Fn() -> bool) -> Option<Vec<usize>> {
    let n = a.nrows();
    assert_eq!(n, a.ncols(), "factorise: a square matrix");
    let par = Par::Seq;
    let mut swaps = vec![0usize; n];
    let mut perm = vec![0usize; n];
    let mut perm_inv = vec![0usize; n];
    let mut buffer = MemBuffer::new(factor::lu_in_place_scratch::<usize, Complex64>(
        n,
        PANEL.min(n),
        par,
        Default::default(),
    ));
    let mut k0 = 0;
    while k0 < n {
        if cancelled() {
            return None;
        }
        let kb = PANEL.min(n - k0);
        let m = n - k0;
        // 1. The tall panel (rows k0.., columns k0..k0 + kb) by faer's recursive LU.
        {
            let panel = a.as_mut().submatrix_mut(k0, k0, m, kb);
            let stack = MemStack::new(&mut buffer);
            factor::lu_in_place(
                panel,
                &mut perm[..m],
                &mut perm_inv[..m],
                par,
                stack,
                Default::default(),
            );
        }
        // 2. Its row permutation as interchanges (it is a product of kb of them, position idx
        //    with a later one, in order), applied to the columns left and right of the panel.
        let local = interchanges(&perm[..m], kb);
        for (idx, &p) in local.iter().enumerate() {
            swaps[k0 + idx] = k0 + p;
            if p != idx {
                swap_rows_outside(a.as_mut(), k0 + idx, k0 + p, k0, k0 + kb);
            }
        }
        let rest = k0 + kb;
        if rest < n {
            // 3. U12 = L11^{-1} A12.
            let (l11, a12) = {
                let (top, _) = a.as_mut().split_at_row_mut(rest);
                let (left, right) = top.split_at_col_mut(rest);
                (
                    left.into_const().submatrix(k0, k0, kb, kb),
                    right.submatrix_mut(k0, 0, kb, n - rest),
                )
            };
            solve_unit_lower_triangular_in_place(l11, a12, par);
            // 4. A22 -= L21 U12, in chunks of columns.
            let mut c0 = rest;
            while c0 < n {
                if cancelled() {
                    return None;
                }
                let cb = CHUNK.min(n - c0);
                let (top, bottom) = a.as_mut().split_at_row_mut(rest);
                let u12 = top.into_const().submatrix(k0, c0, kb, cb);
                let (left, right) = bottom.split_at_col_mut(c0);
                let l21 = left.into_const().submatrix(0, k0, n - rest, kb);
                let a22 = right.submatrix_mut(0, 0, n - rest, cb);
                matmul(a22, Accum::Add, l21, u12, Complex64::new(-1.0, 0.0), par);
                c0 += cb;
            }
        }
        k0 += kb;
    }
    Some(swaps)
}

/// The first `kb` interchanges that turn the identity into the row permutation `perm` (row `i`
/// of the result is row `perm[i]` of the input) when `perm` is such a product: at step `idx`
/// the row that ends at position `idx` is brought there from where it is.
fn interchanges(perm: &[usize], kb: usize) -> Vec<usize> {
    let m = perm.len();
    let mut at: Vec<usize> = (0..m).collect(); // at[position] = original row
    let mut pos: Vec<usize> = (0..m).collect(); // pos[original row] = position
    let mut out = Vec::with_capacity(kb);
    for idx in 0..kb.min(m) {
        let p = pos[perm[idx]];
        out.push(p);
        if p != idx {
            let (r_idx, r_p) = (at[idx], at[p]);
            at.swap(idx, p);
            pos[r_idx] = p;
            pos[r_p] = idx;
        }
    }
    debug_assert!(at.iter().zip(perm).all(|(a, b)| a == b));
    out
}

/// Exchanges rows `i` and `j` of `a` in every column outside `from..to`.
fn swap_rows_outside(mut a: MatMut<'_, Complex64>, i: usize, j: usize, from: usize, to: usize) {
    for c in (0..from).chain(to..a.ncols()) {
        let t = a[(i, c)];
        a[(i, c)] = a[(j, c)];
        a[(j, c)] = t;
    }
}

/// Solves `A X = B` in place of `B` with the factors of [`factorise`].
pub fn solve(lu: &Mat<Complex64>, swaps: &[usize], mut b: MatMut<'_, Complex64>) {
    for (j, &p) in swaps.iter().enumerate() {
        if p != j {
            for c in 0..b.ncols() {
                let t = b[(j, c)];
                b[(j, c)] = b[(p, c)];
                b[(p, c)] = t;
            }
        }
    }
    solve_unit_lower_triangular_in_place(lu.as_ref(), b.rb_mut(), Par::Seq);
    solve_upper_triangular_in_place(lu.as_ref(), b, Par::Seq);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random complex matrix (xorshift), with a zero leading entry so
    /// that pivoting is needed.
    fn matrix(n: usize, seed: u64) -> Mat<Complex64> {
        let mut x = seed | 1;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut m = Mat::from_fn(n, n, |_, _| Complex64::new(next(), next()));
        m[(0, 0)] = Complex64::new(0.0, 0.0);
        m
    }

    /// `max |A X - B| / max |B|` for `X` solved by the blocked LU, several sizes around the
    /// panel and chunk widths (one panel, several, a ragged last one).
    #[test]
    fn blocked_lu_solves_systems() {
        for n in [1, 7, 128, 129, 300, 700] {
            let a = matrix(n, n as u64 + 3);
            let x = Mat::<Complex64>::from_fn(n, 3, |i, s| {
                Complex64::new(1.0 + i as f64 * 0.01, s as f64 - 0.5)
            });
            let b = &a * &x;
            let mut lu = a.clone();
            let swaps = factorise(&mut lu, &|| false).unwrap();
            let mut got = b.clone();
            solve(&lu, &swaps, got.as_mut());
            let err = (0..n)
                .flat_map(|i| (0..3).map(move |s| (i, s)))
                .map(|(i, s)| (got[(i, s)] - x[(i, s)]).norm())
                .fold(0.0f64, f64::max);
            // A random complex matrix of this size is well conditioned (condition numbers of a
            // few hundred): the error is a few hundred times the rounding of the solution.
            assert!(err < 1e-10, "N = {n}: error {err:e}");
        }
    }

    #[test]
    fn interchanges_reproduce_the_permutation() {
        let perm = [3, 0, 4, 1, 2, 5];
        let swaps = interchanges(&perm, 6);
        let mut rows: Vec<usize> = (0..6).collect();
        for (i, &p) in swaps.iter().enumerate() {
            rows.swap(i, p);
        }
        assert_eq!(rows, perm);
    }

    #[test]
    fn a_cancelled_factorisation_stops() {
        let mut a = matrix(600, 5);
        let calls = std::cell::Cell::new(0);
        let cancelled = || {
            calls.set(calls.get() + 1);
            calls.get() > 2
        };
        assert!(factorise(&mut a, &cancelled).is_none());
        assert_eq!(calls.get(), 3, "stopped at the first test that said so");
    }
}
