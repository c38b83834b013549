//! A 6x6 LDL^T (square-root-free Cholesky) factorisation on plain arrays. nalgebra's generic
//! `Cholesky` is correct but its loops are written for any size and took a third of a 4-point
//! solve; this one has fixed bounds the compiler unrolls, and needs no square roots (whose
//! latency dominated a first hand-written `L L^T` version): one division per column.
#![allow(clippy::needless_range_loop)] // index loops mirror the textbook recurrences

use nalgebra::{Matrix6, Vector6};

/// `A = L D L^T` with unit lower-triangular `L` and positive diagonal `D`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Chol6 {
    l: [[f64; 6]; 6],
    inv_d: [f64; 6],
}

impl Chol6 {
    /// Factorises the symmetric matrix `a` (only its lower triangle is read); `None` when `a`
    /// is not (numerically) positive definite.
    #[inline]
    pub(crate) fn new(a: &Matrix6<f64>) -> Option<Self> {
        let mut l = [[0.0f64; 6]; 6];
        let mut d = [0.0f64; 6];
        let mut inv_d = [0.0f64; 6];
        for j in 0..6 {
            // ld[k] = L_jk d_k
            let mut ld = [0.0f64; 6];
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
            for i in j + 1..6 {
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
    pub(crate) fn solve(&self, b: &Vector6<f64>) -> Vector6<f64> {
        let l = &self.l;
        let mut y = [0.0f64; 6];
        for i in 0..6 {
            let mut s = b[i];
            for k in 0..i {
                s -= l[i][k] * y[k];
            }
            y[i] = s;
        }
        for i in 0..6 {
            y[i] *= self.inv_d[i];
        }
        let mut x = [0.0f64; 6];
        for i in (0..6).rev() {
            let mut s = y[i];
            for k in i + 1..6 {
                s -= l[k][i] * x[k];
            }
            x[i] = s;
        }
        Vector6::from(x)
    }

    /// `A^-1 = L^-T D^-1 L^-1`, exactly symmetric.
    pub(crate) fn inverse(&self) -> Matrix6<f64> {
        let l = &self.l;
        // m = L^-1 (unit lower triangular), column by column.
        let mut m = [[0.0f64; 6]; 6];
        for c in 0..6 {
            m[c][c] = 1.0;
            for i in c + 1..6 {
                let mut s = 0.0;
                for k in c..i {
                    s -= l[i][k] * m[k][c];
                }
                m[i][c] = s;
            }
        }
        let mut inv = Matrix6::zeros();
        for i in 0..6 {
            for j in 0..=i {
                let mut s = 0.0;
                for k in i..6 {
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

    #[test]
    fn matches_nalgebra() {
        let m = Matrix6::from_fn(|i, j| {
            ((i * 7 + j * 3) % 5) as f64 - 2.0 + if i == j { 3.0 } else { 0.0 }
        });
        let a = m * m.transpose() + Matrix6::identity();
        let b = Vector6::new(1.0, -2.0, 0.5, 3.0, 0.0, -1.0);
        let x = Chol6::new(&a).expect("positive definite").solve(&b);
        assert!((a * x - b).amax() < 1e-10);
        let inv = Chol6::new(&a).expect("positive definite").inverse();
        assert!((a * inv - Matrix6::identity()).amax() < 1e-10);
        assert!(Chol6::new(&Matrix6::zeros()).is_none());
        let mut nan = a;
        nan[(2, 2)] = f64::NAN;
        assert!(Chol6::new(&nan).is_none());
    }
}
