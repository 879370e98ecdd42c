//! The one dense solve the flight code needs: the 6x6 Newton system of the forward
//! kinematics, fixed-size arrays, no allocation.
//!
//! The system has structure: every leg's stroke depends on the z translation with
//! derivative exactly 1 (the sliders move along B's z, `n_z = 1`), so the z column of
//! the Jacobian is all ones. Gaussian elimination with partial pivoting on that column
//! may pick any row (all candidates are equal), every multiplier is exactly 1, and the
//! first elimination step is six subtractions per row: no pivot search, no
//! multiplication. What remains is a 5x5 system in `[x, y, alpha, beta, gamma]`, solved
//! by Gaussian elimination with partial pivoting; z follows from the first row.

// Index loops with constant bounds are deliberate here: with the elimination step a
// constant they unroll into straight-line code (the iterator forms with `skip` did not,
// and cost twice the instructions on the target). Every index is such a loop counter,
// below the constant dimension of the fixed-size array it indexes.
#![allow(clippy::needless_range_loop, clippy::indexing_slicing)]

use super::real::Real;

/// Dimension of the pose space.
pub const N: usize = 6;
/// Columns of the Jacobian stored explicitly: `[x, y, alpha, beta, gamma]` (the z
/// column, all ones, is implicit).
pub const NC: usize = N - 1;

/// Components of a 3x3 matrix product with a 3-vector, `m v` (each row summed left to
/// right). Written out on arrays: the flight image is built for size, and there
/// nalgebra's generic `Mul`/`Add` were out-of-line calls in the innermost kinematics
/// loop (this form has no call and no bounds check at any opt-level).
#[inline(always)]
pub fn mat_vec3<T: Real>(m: &nalgebra::Matrix3<T>, v: &[T; 3]) -> [T; 3] {
    // Column-major storage: `c[j][i]` is row i, column j.
    let c = &m.data.0;
    let [x, y, z] = *v;
    [
        c[0][0] * x + c[1][0] * y + c[2][0] * z,
        c[0][1] * x + c[1][1] * y + c[2][1] * z,
        c[0][2] * x + c[1][2] * y + c[2][2] * z,
    ]
}

/// The product `a b` of two 3x3 matrices (each entry summed over k = 0, 1, 2 in order),
/// written out like [`mat_vec3`]: nalgebra's generic product has an index check (a
/// panic branch) that the size-built flight image does not optimise away. Not forced
/// inline: the frames use it four times, outside the innermost loop.
#[inline]
pub fn mat_mul3<T: Real>(
    a: &nalgebra::Matrix3<T>,
    b: &nalgebra::Matrix3<T>,
) -> nalgebra::Matrix3<T> {
    let (a, b) = (&a.data.0, &b.data.0);
    let mut c = [[T::ZERO; 3]; 3];
    for (cj, bj) in c.iter_mut().zip(b.iter()) {
        for (i, cij) in cj.iter_mut().enumerate() {
            *cij = a[0][i] * bj[0] + a[1][i] * bj[1] + a[2][i] * bj[2];
        }
    }
    nalgebra::Matrix3::from_array_storage(nalgebra::ArrayStorage(c))
}

/// The transpose of a 3x3 matrix.
#[inline(always)]
pub fn transpose3<T: Real>(a: &nalgebra::Matrix3<T>) -> nalgebra::Matrix3<T> {
    let a = &a.data.0;
    let c = [
        [a[0][0], a[1][0], a[2][0]],
        [a[0][1], a[1][1], a[2][1]],
        [a[0][2], a[1][2], a[2][2]],
    ];
    nalgebra::Matrix3::from_array_storage(nalgebra::ArrayStorage(c))
}

/// `a - b` by component.
#[inline(always)]
pub fn sub3<T: Real>(a: &[T; 3], b: &[T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a + b` by component.
#[inline(always)]
pub fn add3<T: Real>(a: &[T; 3], b: &[T; 3]) -> [T; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a x b`.
#[inline(always)]
pub fn cross3<T: Real>(a: &[T; 3], b: &[T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a . b`, summed left to right.
#[inline(always)]
pub fn dot3<T: Real>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// A 6x6 Jacobian whose z column (index 2 of `[x, y, z, alpha, beta, gamma]`) is all
/// ones. Row i is leg i; the columns held are `[x, y, alpha, beta, gamma]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UnitZJacobian<T> {
    /// `d stroke_i / d [x, y, alpha, beta, gamma]` (mm/mm, mm/rad).
    pub rows: [[T; NC]; N],
}

impl<T: Real> UnitZJacobian<T> {
    /// The full matrix, columns `[x, y, z, alpha, beta, gamma]`.
    pub fn to_matrix(&self) -> [[T; N]; N] {
        self.rows.map(|[x, y, a, b, g]| [x, y, T::ONE, a, b, g])
    }

    /// Factors the matrix for [`UnitZLu::solve`]. Returns `None` when a pivot is not
    /// above `pivot_ratio * max|J_ij|` (numerically singular for the purpose at hand;
    /// NaN entries also give `None`).
    pub fn factor(&self, pivot_ratio: T) -> Option<UnitZLu<T>> {
        let mut lu = UnitZLu::blank();
        lu.refactor(self, pivot_ratio).then_some(lu)
    }
}

/// Step `k` of Gaussian elimination with partial pivoting on the 5x5 matrix `lu`:
/// pivot search in column `k`, row exchange, multipliers stored below the diagonal.
/// False when the pivot is not above `threshold` (or is NaN).
#[inline(always)]
fn eliminate<T: Real>(
    lu: &mut [[T; NC]; NC],
    inv_pivot: &mut [T; NC],
    swaps: &mut [u8; NC],
    threshold: T,
    k: usize,
) -> bool {
    // Partial pivoting: the largest remaining entry of column k.
    let mut p = k;
    let mut best = lu[k][k].abs();
    for i in (k + 1)..NC {
        let m = lu[i][k].abs();
        if m > best {
            best = m;
            p = i;
        }
    }
    // `!(x > t)` also catches NaN.
    if !(best > threshold) {
        return false;
    }
    if p != k {
        // Entry by entry: `<[_]>::swap` of two rows links a general `memmove` (1.6 KB
        // of flash) because it cannot see that the rows are distinct.
        let p = p.min(NC - 1);
        for j in 0..NC {
            let t = lu[k][j];
            lu[k][j] = lu[p][j];
            lu[p][j] = t;
        }
    }
    swaps[k] = p as u8;
    let inv = T::ONE / lu[k][k];
    inv_pivot[k] = inv;
    for i in (k + 1)..NC {
        let f = lu[i][k] * inv;
        lu[i][k] = f;
        for j in (k + 1)..NC {
            lu[i][j] -= f * lu[k][j];
        }
    }
    true
}

/// The factored Newton matrix: `P (J' ) = L U` for the 5x5 system left after the z
/// column is eliminated, and the first row that gives z back. Solving with it costs
/// about a sixth of factoring, so a later right-hand side (the residual at the next
/// iterate) can be solved with it cheaply.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnitZLu<T> {
    /// Unit lower triangle (the multipliers, below the diagonal) and upper triangle.
    lu: [[T; NC]; NC],
    /// `1 / U_kk`.
    inv_pivot: [T; NC],
    /// Row exchanged with row k at step k (k <= swaps[k] < NC).
    swaps: [u8; NC],
    /// Row 0 of J without its z entry (which is 1).
    row0: [T; NC],
}

impl<T: Real> UnitZLu<T> {
    /// A factorization holding nothing yet (all zero), to be filled by
    /// [`UnitZLu::refactor`].
    pub fn blank() -> Self {
        Self {
            lu: [[T::ZERO; NC]; NC],
            inv_pivot: [T::ZERO; NC],
            swaps: [0; NC],
            row0: [T::ZERO; NC],
        }
    }

    /// Factors `jac` into `self` (in place: no copy of the factors). Returns false when
    /// a pivot is not above `pivot_ratio * max|J_ij|` (numerically singular for the
    /// purpose at hand; NaN entries also give false); `self` must then not be used.
    pub fn refactor(&mut self, jac: &UnitZJacobian<T>, pivot_ratio: T) -> bool {
        let [j0, j1, j2, j3, j4, j5] = &jac.rows;
        // The largest entry is at least the z column's 1.
        let mut scale = T::ONE;
        for row in jac.rows.iter() {
            for v in row.iter() {
                scale = scale.max(v.abs());
            }
        }
        let threshold = pivot_ratio * scale;
        // Eliminate z with row 0 (multiplier 1): rows 1..5 minus row 0.
        let sub = |row: &[T; NC]| -> [T; NC] {
            [
                row[0] - j0[0],
                row[1] - j0[1],
                row[2] - j0[2],
                row[3] - j0[3],
                row[4] - j0[4],
            ]
        };
        self.lu = [sub(j1), sub(j2), sub(j3), sub(j4), sub(j5)];
        self.row0 = *j0;
        let (lu, inv, sw) = (&mut self.lu, &mut self.inv_pivot, &mut self.swaps);
        // The steps in a loop, the step a variable: one copy of the elimination in the
        // code. (With the step a constant, five unrolled copies: 524 more bytes of the
        // flight image for 72 fewer instructions in an FK of the size-built image.)
        (0..NC).all(|k| eliminate(lu, inv, sw, threshold, k))
    }

    /// Solves `J d = r` for `d = [x, y, z, alpha, beta, gamma]`.
    pub fn solve(&self, r: &[T; N]) -> [T; N] {
        let [r0, r1, r2, r3, r4, r5] = *r;
        let mut b = [r1 - r0, r2 - r0, r3 - r0, r4 - r0, r5 - r0];
        for (k, p) in self.swaps.iter().enumerate() {
            // `min` keeps the index provably in range (it always is).
            b.swap(k, usize::from(*p).min(NC - 1));
        }
        for k in 0..NC {
            let bk = b[k];
            for i in (k + 1)..NC {
                b[i] -= self.lu[i][k] * bk;
            }
        }
        let mut d = [T::ZERO; NC];
        for k in (0..NC).rev() {
            let mut s = b[k];
            for j in (k + 1)..NC {
                s -= self.lu[k][j] * d[j];
            }
            d[k] = s * self.inv_pivot[k];
        }
        let j0 = &self.row0;
        // z from row 0: r0 = j0 . d + z.
        let z = r0 - (j0[0] * d[0] + j0[1] * d[1] + j0[2] * d[2] + j0[3] * d[3] + j0[4] * d[4]);
        [d[0], d[1], z, d[2], d[3], d[4]]
    }
}
