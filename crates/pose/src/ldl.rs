//! An N x N LDL^T (square-root-free Cholesky) factorisation on plain arrays, for the normal
//! equations of the 6-DOF pose (N = 6) and of the pose on a plane (N = 3). nalgebra's generic
//! `Cholesky` is correct but its loops are written for any size and took a third of a 4-point
//! solve; this one has constant bounds the compiler unrolls for each N, and needs no square
//! roots (whose latency dominated a first hand-written `L L^T` version): one division per
//! column.
#![allow(clippy::needless_range_loop)] // index loops mirror the textbook recurrences

use nalgebra::{SMatrix, SVector};

/// `A = L D L^T` with unit lower-triangular `L` and positive diagonal `D`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ldl<const N: usize> {
    l: [[f64; N]; N],
    inv_d: [f64; N],
}

impl<const N: usize> Ldl<N> {
    /// Factorises the symmetric matrix `a` (only its lower triangle is read); `None` when `a`
    /// is not (numerically) positive definite.
    #[inline]
    pub(crate) fn new(a: &SMatrix<f64, N, N>) -> Option<Self> {
        let mut l = [[0.0f64; N]; N];
        let mut d = [0.0f64; N];
        let mut inv_d = [0.0f64; N];
        for j in 0..N {
            // ld[k] = L_jk d_k
            let mut ld = [0.0f64; N];
            let mut djj = a[(j, j)];
            for k in 0..j {
                ld[k] = l[j][k] * d[k];
                djj -= l[j][k] * ld[k];
            }
            if djj.is_nan() || djj <= 0.0 {
                return None;
            }
            d[j] = djj;
            let inv = 1.0 / djj;
            inv_d[j] = inv;
            l[j][j] = 1.0;
            for i in j + 1..N {
                let mut s = a[(i, j)];
                for k in 0..j {
                    s -= l[i][k] * ld[k];
                }
                l[i][j] = s * inv;
            }
        }
        Some(Self { l, inv_d })
    }

    /// Solves `A x = b`.
    #[inline]
    pub(crate) fn solve(&self, b: &SVector<f64, N>) -> SVector<f64, N> {
        let l = &self.l;
        let mut y = [0.0f64; N];
        for i in 0..N {
            let mut s = b[i];
            for k in 0..i {
                s -= l[i][k] * y[k];
            }
            y[i] = s;
        }
        for i in 0..N {
            y[i] *= self.inv_d[i];
        }
        let mut x = [0.0f64; N];
        for i in (0..N).rev() {
            let mut s = y[i];
            for k in i + 1..N {
                s -= l[k][i] * x[k];
            }
            x[i] = s;
        }
        SVector::from(x)
    }

    /// `A^-1 = L^-T D^-1 L^-1`, exactly symmetric.
    pub(crate) fn inverse(&self) -> SMatrix<f64, N, N> {
        let l = &self.l;
        // m = L^-1 (unit lower triangular), column by column.
        let mut m = [[0.0f64; N]; N];
        for c in 0..N {
            m[c][c] = 1.0;
            for i in c + 1..N {
                let mut s = 0.0;
                for k in c..i {
                    s -= l[i][k] * m[k][c];
                }
                m[i][c] = s;
            }
        }
        let mut inv = SMatrix::<f64, N, N>::zeros();
        for i in 0..N {
            for j in 0..=i {
                let mut s = 0.0;
                for k in i..N {
                    s += m[k][i] * m[k][j] * self.inv_d[k];
                }
                inv[(i, j)] = s;
                inv[(j, i)] = s;
            }
        }
        inv
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

    #[test]
    fn matches_nalgebra() {
        let m = Matrix6::from_fn(|i, j| {
            ((i * 7 + j * 3) % 5) as f64 - 2.0 + if i == j { 3.0 } else { 0.0 }
        });
        let a = m * m.transpose() + Matrix6::identity();
        let b = Vector6::new(1.0, -2.0, 0.5, 3.0, 0.0, -1.0);
        let x = Ldl::new(&a).expect("positive definite").solve(&b);
        assert!((a * x - b).amax() < 1e-10);
        let inv = Ldl::new(&a).expect("positive definite").inverse();
        assert!((a * inv - Matrix6::identity()).amax() < 1e-10);
        assert!(Ldl::new(&Matrix6::zeros()).is_none());
        let mut nan = a;
        nan[(2, 2)] = f64::NAN;
        assert!(Ldl::new(&nan).is_none());
    }

    #[test]
    fn three_by_three_matches_nalgebra() {
        let a = Matrix3::new(4.0, 1.0, -0.5, 1.0, 3.0, 0.25, -0.5, 0.25, 2.0);
        let b = Vector3::new(1.0, -2.0, 0.5);
        let ldl = Ldl::new(&a).expect("positive definite");
        let want = a.cholesky().expect("positive definite").solve(&b);
        assert!((ldl.solve(&b) - want).amax() < 1e-14);
        assert!((a * ldl.inverse() - Matrix3::identity()).amax() < 1e-14);
        assert!(Ldl::new(&Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 1.0))).is_none());
    }
}
