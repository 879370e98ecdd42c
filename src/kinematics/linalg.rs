//! The one dense solve the flight code needs: 6x6, Gaussian elimination with partial
//! pivoting, fixed-size arrays, no allocation.

use super::real::Real;

/// Dimension of the pose space.
pub const N: usize = 6;

/// Solves `a x = b`. Returns `None` when a pivot is smaller than
/// `pivot_ratio * max|a_ij|` (numerically singular for the purpose at hand).
pub fn solve6<T: Real>(mut a: [[T; N]; N], mut b: [T; N], pivot_ratio: T) -> Option<[T; N]> {
    let mut scale = T::ZERO;
    for row in a.iter() {
        for v in row.iter() {
            scale = scale.max(v.abs());
        }
    }
    if !(scale > T::ZERO) {
        return None;
    }
    let threshold = pivot_ratio * scale;
    for k in 0..N {
        // Partial pivoting: the largest remaining entry of column k.
        let mut p = k;
        let mut best = a[k][k].abs();
        for (i, row) in a.iter().enumerate().skip(k + 1) {
            let m = row[k].abs();
            if m > best {
                best = m;
                p = i;
            }
        }
        if !(best > threshold) {
            return None;
        }
        // k, p < N always; the explicit test lets the compiler drop the bounds checks
        // of `swap` (no panic path in the flight image).
        if k < N && p < N {
            a.swap(k, p);
            b.swap(k, p);
        }
        let pivot_row = a[k];
        let pivot_b = b[k];
        let inv = T::ONE / pivot_row[k];
        for i in (k + 1)..N {
            let f = a[i][k] * inv;
            if f != T::ZERO {
                for j in (k + 1)..N {
                    a[i][j] -= f * pivot_row[j];
                }
                b[i] -= f * pivot_b;
            }
        }
    }
    let mut x = [T::ZERO; N];
    for k in (0..N).rev() {
        let mut s = b[k];
        for j in (k + 1)..N {
            s -= a[k][j] * x[j];
        }
        x[k] = s / a[k][k];
    }
    Some(x)
}
